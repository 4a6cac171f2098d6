"""Choosing the language backends from settings: offline defaults, an LLM through Ollama, or
the calling client's model through MCP sampling.

One place turns `LLMSettings` (from config files, `glmap` and `glmap-mcp` flags) into the
parts the map and the planner use:

- text merger (buffers past 300 words): "extractive" (default, offline), "llm" (Ollama) or
  "sampling" (the MCP client's model; `glmap-mcp` only);
- unit scorer f_S (value map, paper Eq. 7): "embedding" (default, offline), "llm" or
  "sampling".

A sampling part falls back (`fallback`: "offline" = embedding scorer / extractive merger,
"ollama" = the Ollama model, "none" = the error) when the client cannot or does not answer;
see glmap_tools.language.sampling. Nothing here loads a model at import; an LLM backend
only talks to Ollama (or the client) when used.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from glmap_tools.errors import InvalidInputError, did_you_mean

# Imports inside functions stay there: gaussians, language.embed, scipy, numba load on first use:
# `glmap-mcp` answers the handshake before they load (the launch path); build_server stays light
# (test_server_startup): the server loads them in the background or on first use.

TEXT_MERGERS = ("extractive", "llm", "sampling")
SCORERS = ("embedding", "llm", "sampling")
FALLBACKS = ("offline", "ollama", "none")
MLLMS = ("ollama", "sampling")
READERS = ("rules", "llm", "sampling")
ANSWERERS = ("map", "llm", "sampling")
# `glmap-mcp --llm`: one word for both parts (the scorer's and the merger's backends).
LLM_CHOICES = {  # (scorer, text_merger, mllm, reader, answerer)
    "embedding": ("embedding", "extractive", "ollama", "rules", "map"),
    "ollama": ("llm", "llm", "ollama", "llm", "llm"),
    "sampling": ("sampling", "sampling", "sampling", "sampling", "sampling"),
}
SAMPLING_BATCH = 40  # units per sampling call: a client's model reads longer lists well


@dataclass(frozen=True)
class LLMSettings:
    """Which backends to use and how to reach the model.

    Attributes:
        text_merger: "extractive", "llm" (Ollama) or "sampling" (the MCP client's model).
        scorer: "embedding", "llm" (Ollama) or "sampling" (the MCP client's model).
        fallback: what a sampling part uses when the client fails, refuses or times out:
            "offline" (embedding scorer, extractive merger), "ollama" (`model` on `host`)
            or "none" (the error reaches the tool call).
        sampling_timeout: seconds to wait for the client's answer to one sampling request.
        mllm: the vision model of the model-backed perception (`--perception
            geometric+mllm`, `mllm`): "ollama" (`model`) or "sampling" (the client's model;
            a frame it cannot name keeps its segments pending for label_segments).
        reader: who reads locate_situation's situation text into the reading form:
            "rules" (the offline reader), "llm" (`model` on Ollama) or "sampling".
        answerer: who answers locate_situation's question beside the map's answer: "map"
            (the map alone), "llm" (`model` on Ollama, a vision model) or "sampling" (the
            client's model), from the four views and the map's notes (prompt sqa_answer).
        model: Ollama model tag for the LLM parts (the paper: Qwen3-8B for text).
        host: Ollama URL (None = $OLLAMA_HOST or http://127.0.0.1:11434).
        timeout: seconds per request.
        prompts: a prompt override folder (`--prompts DIR`), or None.
        transcript: a JSONL file recording every model call, or None.
    """

    text_merger: str = "extractive"
    scorer: str = "embedding"
    fallback: str = "offline"
    sampling_timeout: float = 60.0
    mllm: str = "ollama"
    reader: str = "rules"
    answerer: str = "map"
    model: str = "qwen3:8b"
    host: str | None = None
    timeout: float = 120.0
    prompts: Path | None = None
    transcript: Path | None = None

    def __post_init__(self) -> None:
        for name, value, choices in (
            ("text_merger", self.text_merger, TEXT_MERGERS),
            ("scorer", self.scorer, SCORERS),
            ("fallback", self.fallback, FALLBACKS),
            ("mllm", self.mllm, MLLMS),
            ("reader", self.reader, READERS),
            ("answerer", self.answerer, ANSWERERS),
        ):
            if value not in choices:
                raise InvalidInputError(
                    f"{name}={value!r} is not one of {list(choices)}.{did_you_mean(value, choices)}"
                )
        if not 0 < self.sampling_timeout <= 3600:
            raise InvalidInputError(
                f"sampling_timeout={self.sampling_timeout!r} s must be in (0, 3600]."
            )
        if not 0 < self.timeout <= 3600:
            raise InvalidInputError(
                f"timeout={self.timeout!r} s (--llm-timeout) must be in (0, 3600]; the default "
                "is 120."
            )
        if self.prompts is not None:  # a missing folder or a bad file is refused now
            from glmap_tools.language.prompts import PromptSet

            PromptSet(self.prompts)

    @property
    def uses_llm(self) -> bool:
        """Whether a part talks to Ollama (a sampling part may, as its fallback)."""
        ollama_fallback = self.uses_sampling and self.fallback == "ollama"
        parts = (self.text_merger, self.scorer, self.reader, self.answerer)
        return "llm" in parts or ollama_fallback

    @property
    def uses_sampling(self) -> bool:
        """Whether a part asks the MCP client's model (sampling)."""
        parts = (self.text_merger, self.scorer, self.mllm, self.reader, self.answerer)
        return "sampling" in parts

    def sampling_client(self) -> Any:
        """The `SamplingClient` for these settings (one per part; cheap)."""
        from glmap_tools.language.sampling import SamplingClient
        from glmap_tools.language.transcript import Transcript

        return SamplingClient(
            timeout=self.sampling_timeout,
            transcript=Transcript(self.transcript) if self.transcript else None,
        )

    def client(self) -> Any:
        """The `OllamaClient` for these settings (one per call site; cheap)."""
        from glmap_tools.language.llm import OllamaClient
        from glmap_tools.language.transcript import Transcript

        return OllamaClient(
            self.model,
            host=self.host,
            timeout=self.timeout,
            transcript=Transcript(self.transcript) if self.transcript else None,
        )

    def vision_client(self, backend: str | None = None) -> Any:
        """A vision model: the client's ("sampling") or `model` on Ollama; by default the
        one the model-backed perception uses (`mllm`)."""
        if (backend or self.mllm) == "sampling":
            from glmap_tools.language.sampling import SamplingClient
            from glmap_tools.language.transcript import Transcript

            return SamplingClient(
                timeout=self.sampling_timeout,
                vision=True,
                transcript=Transcript(self.transcript) if self.transcript else None,
            )
        from glmap_tools.language.llm import OllamaClient

        return OllamaClient(self.model, host=self.host, timeout=self.timeout, vision=True)

    def prompt_set(self) -> Any:
        from glmap_tools.language.prompts import PromptSet, default_prompts

        return PromptSet(self.prompts) if self.prompts else default_prompts()


def _fallback_settings(settings: LLMSettings, **part: str) -> LLMSettings:
    """The settings of a sampling part's fallback: `part` (e.g. scorer="embedding") on the
    Ollama model, host, timeout, prompts and transcript of `settings`."""
    return LLMSettings(
        model=settings.model,
        host=settings.host,
        timeout=settings.timeout,
        prompts=settings.prompts,
        transcript=settings.transcript,
        **part,  # type: ignore[arg-type]
    )


def make_text_merger(settings: LLMSettings, embedder: Any) -> Any:
    """The text merger the settings ask for (`TextMerger`)."""
    if settings.text_merger == "sampling":
        from glmap_tools.language.llm_merger import LLMTextMerger
        from glmap_tools.language.sampling import FallbackMerger

        primary = LLMTextMerger(settings.sampling_client(), settings.prompt_set())
        if settings.fallback == "none":
            return FallbackMerger(primary, None)
        ollama = settings.fallback == "ollama"
        fallback = _fallback_settings(settings, text_merger="llm" if ollama else "extractive")
        name = "ollama" if ollama else "extractive"
        return FallbackMerger(primary, make_text_merger(fallback, embedder), name)
    if settings.text_merger == "llm":
        from glmap_tools.language.llm_merger import LLMTextMerger

        return LLMTextMerger(settings.client(), settings.prompt_set())
    from glmap_tools.language.text_merger import ExtractiveTextMerger

    return ExtractiveTextMerger(embedder)


def make_scorer(settings: LLMSettings, embedder: Any) -> Any:
    """The unit scorer f_S the settings ask for (`glmap_tools.nav.Scorer`)."""
    if settings.scorer == "sampling":
        from glmap_tools.language.llm_scorer import LLMScorer
        from glmap_tools.language.sampling import FallbackScorer

        client = settings.sampling_client()
        primary = LLMScorer(client, settings.prompt_set(), batch_size=SAMPLING_BATCH)
        if settings.fallback == "none":
            return FallbackScorer(primary, None)
        ollama = settings.fallback == "ollama"
        fallback = _fallback_settings(settings, scorer="llm" if ollama else "embedding")
        name = "ollama" if ollama else "embedding"
        return FallbackScorer(primary, make_scorer(fallback, embedder), name)
    if settings.scorer == "llm":
        from glmap_tools.language.llm_scorer import LLMScorer

        return LLMScorer(settings.client(), settings.prompt_set())
    from glmap_tools.nav import EmbeddingScorer

    return EmbeddingScorer(embedder)


def add_llm_arguments(
    parser: argparse.ArgumentParser, *, scorer: bool = True, sampling: bool = False
) -> None:
    """Add --text-merger, --scorer, --llm-model, --ollama-host, --llm-timeout, --prompts;
    with `sampling` (an MCP server) also --llm, --llm-fallback and --sampling-timeout."""
    g = parser.add_argument_group("language backends (offline by default)")
    merger_choices = TEXT_MERGERS if sampling else TEXT_MERGERS[:2]
    g.add_argument(
        "--text-merger",
        choices=merger_choices,
        default="extractive",
        help="rewrites text buffers past 300 words: extractive (offline), llm (Ollama)"
        + (" or sampling (the MCP client's model)" if sampling else ""),
    )
    if scorer:
        g.add_argument(
            "--scorer",
            choices=SCORERS if sampling else SCORERS[:2],
            default="embedding",
            help="f_S for the value map: embedding cosine (offline), llm (Ollama)"
            + (" or sampling (the MCP client's model)" if sampling else ""),
        )
    if sampling:
        g.add_argument(
            "--llm",
            choices=list(LLM_CHOICES),
            default=None,
            help="every model part at once (f_S, text merger, the --perception MLLM, the "
            "situation reader and answerer): "
            "embedding (offline), ollama, or sampling (ask the client's model through MCP "
            "sampling, when the client declares it)",
        )
        g.add_argument(
            "--llm-fallback",
            choices=FALLBACKS,
            default="offline",
            help="when a sampling request fails, is refused or times out: offline "
            "(embedding / extractive), ollama, or none (the tool call fails)",
        )
        g.add_argument(
            "--sampling-timeout",
            type=float,
            default=60.0,
            help="seconds to wait for the client's answer to one sampling request",
        )
    g.add_argument("--llm-model", default="qwen3:8b", help="Ollama model for the llm parts")
    g.add_argument("--ollama-host", default=None, help="Ollama URL ($OLLAMA_HOST or local)")
    g.add_argument("--llm-timeout", type=float, default=120.0, help="seconds per model call")
    g.add_argument("--prompts", type=Path, default=None, help="prompt override folder")


def settings_from_args(args: argparse.Namespace) -> LLMSettings:
    """`LLMSettings` from arguments added by `add_llm_arguments`."""
    scorer, merger = getattr(args, "scorer", "embedding"), args.text_merger
    mllm, reader, answerer = "ollama", "rules", "map"
    both = getattr(args, "llm", None)
    if both is not None:
        scorer, merger, mllm, reader, answerer = LLM_CHOICES[both]
    return LLMSettings(
        text_merger=merger,
        scorer=scorer,
        mllm=mllm,
        reader=reader,
        answerer=answerer,
        fallback=getattr(args, "llm_fallback", "offline"),
        sampling_timeout=getattr(args, "sampling_timeout", 60.0),
        model=args.llm_model,
        host=args.ollama_host,
        timeout=args.llm_timeout,
        prompts=args.prompts,
    )
