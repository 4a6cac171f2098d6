"""Choosing the language backends from settings: offline defaults, or an LLM through Ollama.

One place turns `LLMSettings` (from config files, `glmap` and `glmap-mcp` flags) into the
parts the map and the planner use:

- text merger (buffers past 300 words): "extractive" (default, offline) or "llm";
- unit scorer f_S (value map, paper Eq. 7): "embedding" (default, offline) or "llm".

Nothing here loads a model at import; an LLM backend only talks to Ollama when used.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from glmap_tools.errors import InvalidInputError, did_you_mean

TEXT_MERGERS = ("extractive", "llm")
SCORERS = ("embedding", "llm")


@dataclass(frozen=True)
class LLMSettings:
    """Which backends to use and how to reach the model.

    Attributes:
        text_merger: "extractive" or "llm".
        scorer: "embedding" or "llm".
        model: Ollama model tag for the LLM parts (the paper: Qwen3-8B for text).
        host: Ollama URL (None = $OLLAMA_HOST or http://127.0.0.1:11434).
        timeout: seconds per request.
        prompts: a prompt override folder (`--prompts DIR`), or None.
        transcript: a JSONL file recording every model call, or None.
    """

    text_merger: str = "extractive"
    scorer: str = "embedding"
    model: str = "qwen3:8b"
    host: str | None = None
    timeout: float = 120.0
    prompts: Path | None = None
    transcript: Path | None = None

    def __post_init__(self) -> None:
        for name, value, choices in (
            ("text_merger", self.text_merger, TEXT_MERGERS),
            ("scorer", self.scorer, SCORERS),
        ):
            if value not in choices:
                raise InvalidInputError(
                    f"{name}={value!r} is not one of {list(choices)}.{did_you_mean(value, choices)}"
                )

    @property
    def uses_llm(self) -> bool:
        return "llm" in (self.text_merger, self.scorer)

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

    def prompt_set(self) -> Any:
        from glmap_tools.language.prompts import PromptSet, default_prompts

        return PromptSet(self.prompts) if self.prompts else default_prompts()


def make_text_merger(settings: LLMSettings, embedder: Any) -> Any:
    """The text merger the settings ask for (`TextMerger`)."""
    if settings.text_merger == "llm":
        from glmap_tools.language.llm_merger import LLMTextMerger

        return LLMTextMerger(settings.client(), settings.prompt_set())
    from glmap_tools.language.text_merger import ExtractiveTextMerger

    return ExtractiveTextMerger(embedder)


def make_scorer(settings: LLMSettings, embedder: Any) -> Any:
    """The unit scorer f_S the settings ask for (`glmap_tools.nav.Scorer`)."""
    if settings.scorer == "llm":
        from glmap_tools.language.llm_scorer import LLMScorer

        return LLMScorer(settings.client(), settings.prompt_set())
    from glmap_tools.nav import EmbeddingScorer

    return EmbeddingScorer(embedder)


def add_llm_arguments(parser: argparse.ArgumentParser, *, scorer: bool = True) -> None:
    """Add --text-merger, --scorer, --llm-model, --ollama-host, --llm-timeout, --prompts."""
    g = parser.add_argument_group("language backends (offline by default)")
    g.add_argument(
        "--text-merger",
        choices=TEXT_MERGERS,
        default="extractive",
        help="rewrites text buffers past 300 words: extractive (offline) or llm (Ollama)",
    )
    if scorer:
        g.add_argument(
            "--scorer",
            choices=SCORERS,
            default="embedding",
            help="f_S for the value map: embedding cosine (offline) or llm (Ollama)",
        )
    g.add_argument("--llm-model", default="qwen3:8b", help="Ollama model for the llm parts")
    g.add_argument("--ollama-host", default=None, help="Ollama URL ($OLLAMA_HOST or local)")
    g.add_argument("--llm-timeout", type=float, default=120.0, help="seconds per model call")
    g.add_argument("--prompts", type=Path, default=None, help="prompt override folder")


def settings_from_args(args: argparse.Namespace) -> LLMSettings:
    """`LLMSettings` from arguments added by `add_llm_arguments`."""
    return LLMSettings(
        text_merger=args.text_merger,
        scorer=getattr(args, "scorer", "embedding"),
        model=args.llm_model,
        host=args.ollama_host,
        timeout=args.llm_timeout,
        prompts=args.prompts,
    )
