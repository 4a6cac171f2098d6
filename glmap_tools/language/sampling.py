"""The calling client's model as GLMap's LLM: MCP sampling behind `LLMClient`, with fallbacks.

When an MCP client declares the sampling capability, the server may ask the client's model
for a completion (`sampling/createMessage`). This module knows no MCP: a `Sampler` is any
async function from chat messages to an `LLMReply`; `glmap_tools.server.context` makes one
from the request's session, `glmap_tools.toolset` may take one from its user.

The map and the planner call their models synchronously on worker threads (the scorer from
the value map, the text merger from fusion). `SamplingClient.chat` therefore hands the
request to the event loop that serves the tool call (`asyncio.run_coroutine_threadsafe`) and
waits for it with a timeout. Which sampler and loop a thread uses is bound per tool call
(`bind`, in a context variable, which anyio copies into the worker threads), so a scorer
made at sim_reset asks the client of the call that is running when it scores.

`FallbackScorer` and `FallbackMerger` put the sampling-backed `LLMScorer` / `LLMTextMerger`
in front of an offline (or Ollama) one: a request that fails, is refused or times out is
answered by the fallback, logged, and counted in `SamplingUsage`, which the tools report.
The same prompt files as the Ollama path are used (`glmap_tools/prompts`).
"""

from __future__ import annotations

import asyncio
import contextvars
import logging
import math
import threading
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from glmap_tools.errors import LLMError, LLMUnavailableError
from glmap_tools.language.llm import LLMReply
from glmap_tools.language.prompts import Prompt
from glmap_tools.language.transcript import Transcript

logger = logging.getLogger("glmap_tools.sampling")

CHARS_PER_TOKEN = 4  # sampling results carry no token counts: estimated from characters
DEFAULT_TIMEOUT_S = 60.0
DEFAULT_MAX_TOKENS = 2048
SAMPLING_MODEL = "client (MCP sampling)"


class Sampler(Protocol):
    """Asks the calling client's model for one completion (MCP `sampling/createMessage`)."""

    async def __call__(
        self,
        messages: Sequence[Mapping[str, Any]],
        *,
        system: str | None = None,
        max_tokens: int = DEFAULT_MAX_TOKENS,
        timeout: float = DEFAULT_TIMEOUT_S,
    ) -> LLMReply:
        """One completion.

        Args:
            messages: {"role": "user"|"assistant", "content": str, "images": [PNG/JPEG
                bytes] (optional)}, as `LLMClient.chat` takes them.
            system: a system prompt, or None.
            max_tokens: the most tokens the client's model may write.
            timeout: seconds to wait for the client's answer.

        Raises:
            LLMError: the client refused, failed or did not answer in time.
        """
        ...


@dataclass
class SamplingUsage:
    """What sampling cost one session: calls, estimated tokens, time, fallbacks.

    Tokens are estimated (`CHARS_PER_TOKEN` characters a token): an MCP sampling result
    does not say how many tokens the client's model used.
    """

    calls: int = 0
    failed: int = 0
    prompt_chars: int = 0
    reply_chars: int = 0
    seconds: float = 0.0
    fallbacks: int = 0
    last_fallback: str = ""
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False, compare=False)

    def add(self, prompt_chars: int, reply_chars: int, seconds: float, ok: bool) -> None:
        with self._lock:
            self.calls += 1
            self.failed += 0 if ok else 1
            self.prompt_chars += prompt_chars
            self.reply_chars += reply_chars
            self.seconds += seconds

    def fell_back(self, message: str) -> None:
        with self._lock:
            self.fallbacks += 1
            self.last_fallback = message

    @property
    def prompt_tokens(self) -> int:
        return math.ceil(self.prompt_chars / CHARS_PER_TOKEN)

    @property
    def output_tokens(self) -> int:
        return math.ceil(self.reply_chars / CHARS_PER_TOKEN)

    def report(self) -> dict[str, Any]:
        """A result field: calls, failures, estimated tokens, seconds, fallbacks."""
        out: dict[str, Any] = {
            "sampling_calls": self.calls,
            "sampling_failed": self.failed,
            "est_prompt_tokens": self.prompt_tokens,
            "est_output_tokens": self.output_tokens,
            "sampling_s": round(self.seconds, 2),
            "fallbacks": self.fallbacks,
        }
        if self.last_fallback:
            out["last_fallback"] = self.last_fallback
        return out


@dataclass(frozen=True)
class Binding:
    """The sampler a tool call offers, the event loop serving it, and its session's usage."""

    sampler: Sampler | None
    loop: asyncio.AbstractEventLoop | None
    usage: SamplingUsage


_ACTIVE: contextvars.ContextVar[Binding | None] = contextvars.ContextVar(
    "glmap_sampling", default=None
)


def bind(sampler: Sampler | None, usage: SamplingUsage) -> None:
    """Offer `sampler` to the model calls of the running tool call (and its worker threads).

    Call on the event loop, in the tool call's task, before its work goes to a thread.
    """
    try:
        loop: asyncio.AbstractEventLoop | None = asyncio.get_running_loop()
    except RuntimeError:
        loop = None
    _ACTIVE.set(Binding(sampler, loop, usage))


def active() -> Binding | None:
    """The binding of the running tool call, or None (outside any tool call)."""
    return _ACTIVE.get()


def usage_report() -> dict[str, Any]:
    """The running tool call's session's sampling figures, or {} when nothing was sampled."""
    binding = _ACTIVE.get()
    if binding is None or (binding.usage.calls == 0 and binding.usage.fallbacks == 0):
        return {}
    return binding.usage.report()


def _callable_binding() -> tuple[Sampler, asyncio.AbstractEventLoop, SamplingUsage]:
    """(sampler, event loop, usage) of the call's binding, checked: a client that samples,
    asked from off the event loop's thread.

    Raises:
        LLMUnavailableError: no client with the sampling capability on this call.
        LLMError: asked for on the event loop's own thread.
    """
    binding = _ACTIVE.get()
    if binding is None or binding.sampler is None or binding.loop is None:
        raise LLMUnavailableError(
            "no MCP client with the sampling capability on this call (the client did not "
            "declare it, or the connection has no back-channel)"
        )
    try:
        running = asyncio.get_running_loop()
    except RuntimeError:
        running = None
    if running is binding.loop:
        raise LLMError("sampling was asked for on the event loop's thread (a bug)")
    return binding.sampler, binding.loop, binding.usage


def _sampling_error(exc: BaseException, timeout: float) -> Exception | None:
    """The `LLMError` a failed sampling call raises for `exc`; None for what is no
    `Exception` (a cancellation, an interrupt), which is raised as it is."""
    if isinstance(exc, TimeoutError):
        return LLMError(f"the client's model gave no answer within {timeout:g} s")
    if isinstance(exc, LLMError):
        return exc
    if isinstance(exc, Exception):
        return LLMError(f"sampling failed: {type(exc).__name__}: {exc}")
    return None


def _chars(messages: Sequence[Mapping[str, Any]], system: str | None) -> int:
    return len(system or "") + sum(len(str(m.get("content") or "")) for m in messages)


@dataclass
class SamplingClient:
    """`LLMClient` on the calling client's model through MCP sampling.

    `chat` blocks its (worker) thread while the event loop asks the client; it must not
    be called on the event loop's own thread.

    Args:
        timeout: seconds to wait for one answer.
        max_tokens: the most tokens one answer may have.
        vision: whether images are sent (MCP sampling carries image content).
        transcript: where every request and answer is recorded.
    """

    timeout: float = DEFAULT_TIMEOUT_S
    max_tokens: int = DEFAULT_MAX_TOKENS
    vision: bool = True
    transcript: Transcript | None = None
    model: str = SAMPLING_MODEL

    def chat(
        self,
        messages: Sequence[Mapping[str, Any]],
        *,
        tools: Sequence[Mapping[str, Any]] | None = None,
        format: Mapping[str, Any] | None = None,
        prompt: Prompt | None = None,
    ) -> LLMReply:
        """See `LLMClient.chat` (tools are not offered to the client's model; `format` is
        asked for in words by the prompts). Raises the `LLMError` family."""
        sampler, loop, usage = _callable_binding()
        if tools:
            raise LLMError("tool calls are not offered to the client's model through sampling")
        msgs = [
            {k: v for k, v in m.items() if v is not None and (self.vision or k != "images")}
            for m in messages
        ]
        system = "\n\n".join(str(m["content"]) for m in msgs if m.get("role") == "system")
        msgs = [m for m in msgs if m.get("role") != "system"]
        ref = prompt.ref if prompt else None
        if self.transcript is not None:
            self.transcript.write(
                "llm_request", model=self.model, prompt=ref, messages=msgs, format=bool(format)
            )
        sent = _chars(msgs, system)
        t0 = time.monotonic()
        future = asyncio.run_coroutine_threadsafe(
            sampler(msgs, system=system or None, max_tokens=self.max_tokens, timeout=self.timeout),
            loop,
        )
        try:
            reply = future.result(timeout=self.timeout + 1.0)
        except BaseException as exc:
            future.cancel()
            seconds = time.monotonic() - t0
            usage.add(sent, 0, seconds, ok=False)
            error = _sampling_error(exc, self.timeout)
            if error is None:
                raise
            if self.transcript is not None:
                self.transcript.write("error", model=self.model, error=str(error))
            raise error from None
        seconds = time.monotonic() - t0
        usage.add(sent, len(reply.content), seconds, ok=True)
        reply = LLMReply(
            content=reply.content,
            prompt_tokens=reply.prompt_tokens or math.ceil(sent / CHARS_PER_TOKEN),
            output_tokens=reply.output_tokens or math.ceil(len(reply.content) / CHARS_PER_TOKEN),
            seconds=round(seconds, 3),
            model=reply.model or self.model,
        )
        if self.transcript is not None:
            self.transcript.write(
                "llm_response",
                model=reply.model,
                prompt=ref,
                content=reply.content,
                prompt_tokens=reply.prompt_tokens,
                output_tokens=reply.output_tokens,
                seconds=reply.seconds,
            )
        return reply


def fallback_message(what: str, exc: Exception, fallback: str) -> str:
    """'<what> by the client's model failed (<why>); used <fallback> instead'."""
    text = " ".join(str(exc).split())
    if len(text) > 240:
        text = text[:240] + "..."
    return f"{what} by the client's model failed ({text}); used {fallback} instead"


def note_fallback(message: str) -> None:
    """Say that a part fell back: a log line (once per reason in a row) and the usage."""
    global _LAST_UNBOUND
    binding = _ACTIVE.get()
    if binding is None:  # outside a tool call (e.g. an episode replayed at start-up)
        if message != _LAST_UNBOUND:
            logger.warning("glmap: %s", message)
        _LAST_UNBOUND = message
        return
    if binding.usage.last_fallback != message:
        logger.warning("glmap: %s", message)
    binding.usage.fell_back(message)


_LAST_UNBOUND = ""


class _WithFallback:
    """A primary model part and the part that stands in when a request to it fails.

    Args:
        primary: the part that asks the client's model.
        fallback: the stand-in; None: the primary's error is raised.
        fallback_name: how the fallback is named in messages ("embedding", "ollama").
    """

    what = ""  # what the part does, for the fallback message
    kind = ""  # what the fallback is, for the fallback message

    def __init__(self, primary: Any, fallback: Any | None, fallback_name: str = "") -> None:
        self.primary = primary
        self.fallback = fallback
        self.fallback_name = fallback_name or type(fallback).__name__

    @property
    def calls(self) -> int:
        return int(getattr(self.primary, "calls", 0))

    def _either(self, method: str, *args: Any) -> Any:
        try:
            return getattr(self.primary, method)(*args)
        except LLMError as exc:
            if self.fallback is None:
                raise
            note_fallback(fallback_message(self.what, exc, f"the {self.fallback_name} {self.kind}"))
            return getattr(self.fallback, method)(*args)


class FallbackScorer(_WithFallback):
    """f_S from the primary scorer (the client's model); the fallback when it fails.

    Satisfies `glmap_tools.nav.Scorer`. The primary's cache (goal + unit text) makes a
    unit scored once cost no further calls; a failed batch is not cached, so the next
    decision asks again. Primary e.g. `LLMScorer(SamplingClient())`; fallback e.g.
    `EmbeddingScorer(embedder)` or an Ollama `LLMScorer`.
    """

    what, kind = "scoring", "scorer"

    def score(self, goal: str, units: Sequence[Any]) -> np.ndarray:
        """[N] scores in [0, 1] of `units` for `goal` (see `glmap_tools.nav.Scorer`)."""
        return np.asarray(self._either("score", goal, units), dtype=np.float64)


class FallbackMerger(_WithFallback):
    """`TextMerger` from the primary merger (the client's model); the fallback when it fails.

    Primary e.g. `LLMTextMerger(SamplingClient())`; fallback e.g.
    `ExtractiveTextMerger(embedder)`.
    """

    what, kind = "merging a text", "merger"

    def merge(self, texts: Sequence[str], max_words: int) -> str:
        """One description of at most `max_words` words (see `TextMerger.merge`)."""
        return str(self._either("merge", texts, max_words))
