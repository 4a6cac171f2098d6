"""Language-model clients: the `LLMClient` Protocol and `OllamaClient` on the `ollama` package.

The paper uses models in three places (an MLLM describes frames, an LLM scores units for a
goal, an LLM rewrites text buffers), and agents use them to call tools. All of it goes
through `LLMClient.chat`: messages with optional images, optional tools, optional JSON
schema for structured output. `chat_structured` adds what weak local models need: JSON
pulled out of prose or code fences, validation against a pydantic model, and one retry that
tells the model what was wrong.

Tests replay recorded HTTP exchanges through `glmap_tools.language.ollama_replay`, so the
real `ollama` client code runs in CI without a model.
"""

from __future__ import annotations

import json
import os
import re
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol, TypeVar, runtime_checkable

from pydantic import BaseModel, ValidationError

from glmap_tools.errors import (
    InvalidInputError,
    LLMError,
    LLMOutputError,
    LLMUnavailableError,
    ReplayMissError,
)
from glmap_tools.language.prompts import Prompt
from glmap_tools.language.transcript import Transcript

# Imports inside functions stay there: httpx load on first use: build_server stays light
# (test_server_startup): the server loads them in the background or on first use; `glmap` imports
# every command module to build its parser; optional: ollama.

M = TypeVar("M", bound=BaseModel)
DEFAULT_HOST = "http://127.0.0.1:11434"
REPLAY_MARK = "glmap replay:"


@dataclass(frozen=True)
class ToolCall:
    """A tool the model asked to call."""

    name: str
    arguments: dict[str, Any]


@dataclass(frozen=True)
class LLMReply:
    """One chat response.

    Attributes:
        content: the text (may be empty when the model only calls tools).
        tool_calls: tools the model asked to call, in order.
        prompt_tokens, output_tokens: as the server counted them (0 when unknown).
        seconds: wall time of the call, retries included.
    """

    content: str
    tool_calls: tuple[ToolCall, ...] = ()
    prompt_tokens: int = 0
    output_tokens: int = 0
    seconds: float = 0.0
    model: str = ""


@runtime_checkable
class LLMClient(Protocol):
    """A chat model: text and images in, text or tool calls out."""

    model: str
    vision: bool

    def chat(
        self,
        messages: Sequence[Mapping[str, Any]],
        *,
        tools: Sequence[Mapping[str, Any]] | None = None,
        format: Mapping[str, Any] | None = None,
        prompt: Prompt | None = None,
    ) -> LLMReply:
        """One chat call.

        Args:
            messages: {"role": "system"|"user"|"assistant"|"tool", "content": str,
                "images": [PNG/JPEG bytes] (optional), "tool_calls"/"tool_name" (optional)}.
            tools: Ollama function-tool schemas ({"type": "function", "function": {...}}).
            format: a JSON schema the reply must follow (structured output).
            prompt: the prompt template the messages came from (for the transcript).
        """
        ...


_FENCE = re.compile(r"```(?:json|JSON)?\s*(.*?)```", re.DOTALL)


def extract_json(text: str) -> Any:
    """The JSON value in a model's reply: bare, inside a code fence, or inside prose.

    Raises:
        LLMOutputError: no JSON object or array can be found.
    """
    text = text.strip()
    shown = text if len(text) <= 200 else text[:200] + "..."
    candidates = [text] + [m.group(1).strip() for m in _FENCE.finditer(text)]
    decoder = json.JSONDecoder()
    try:
        for candidate in candidates:
            try:
                return json.loads(candidate)
            except json.JSONDecodeError:
                pass
        for i, ch in enumerate(text):
            if ch in "{[":
                try:
                    value, _ = decoder.raw_decode(text, i)
                    return value
                except json.JSONDecodeError:
                    continue
    except RecursionError:  # a reply stuck repeating brackets
        raise LLMOutputError(
            f"the model's reply nests brackets deeper than JSON is read: {shown!r}"
        ) from None
    raise LLMOutputError(f"the model's reply holds no JSON: {shown!r}")


def chat_structured(
    client: LLMClient,
    messages: Sequence[Mapping[str, Any]],
    schema: type[M],
    *,
    prompt: Prompt | None = None,
    check: Callable[[M], None] | None = None,
    retries: int = 1,
) -> tuple[M, LLMReply]:
    """Ask for JSON that validates as `schema`; retry with the reason when it does not.

    Args:
        check: extra validation of the parsed reply; raise ValueError with a reason the
            model can act on (e.g. "ids 3, 7 are missing").
        retries: corrective retries after the first answer.

    Returns:
        (the validated model, the last reply).

    Raises:
        LLMOutputError: still invalid after the retries (the message quotes the reply).
    """
    history = [dict(m) for m in messages]
    fmt = schema.model_json_schema()
    reason = ""
    reply = LLMReply("")
    for attempt in range(retries + 1):
        reply = client.chat(history, format=fmt, prompt=prompt)
        try:
            value = schema.model_validate(extract_json(reply.content))
            if check is not None:
                check(value)
            return value, reply
        except LLMOutputError as exc:
            reason = str(exc)
        except ValidationError as exc:
            reason = "; ".join(
                f"{'.'.join(str(p) for p in e['loc']) or 'reply'}: {e['msg']}"
                for e in exc.errors()[:5]
            )
        except ValueError as exc:
            reason = str(exc)
        if attempt < retries:
            history += [
                {"role": "assistant", "content": reply.content},
                {
                    "role": "user",
                    "content": f"That reply is not usable: {reason}. Answer again with JSON "
                    "only, following the requested format exactly.",
                },
            ]
    name = prompt.ref if prompt else schema.__name__
    shown = reply.content if len(reply.content) <= 300 else reply.content[:300] + "..."
    raise LLMOutputError(
        f"model {reply.model or client.model!r} gave no valid {schema.__name__} for {name} "
        f"after {retries + 1} tries: {reason}. Last reply: {shown!r}. Try a larger model or "
        "edit the prompt (--prompts DIR)."
    )


@dataclass
class OllamaClient:
    """`LLMClient` on the real `ollama` package.

    Args:
        model: an Ollama model tag, e.g. "qwen3:8b" or "gemma3:27b".
        host: server URL (default $OLLAMA_HOST or http://127.0.0.1:11434).
        timeout: seconds per HTTP request.
        retries: extra attempts after a connection error, timeout or 5xx, with
            exponential backoff starting at `backoff` seconds.
        keep_alive: how long Ollama keeps the model loaded after a call.
        options: Ollama model options (temperature, seed, num_ctx ...); default
            temperature 0 and seed 0 so runs repeat.
        vision: whether images are sent to the model (an MLLM); text-only models get
            the text of image-bearing messages only.
        transcript: where every request and response is recorded.
    """

    model: str
    host: str | None = None
    timeout: float = 120.0
    retries: int = 2
    backoff: float = 1.0
    keep_alive: str | float = "10m"
    options: dict[str, Any] = field(default_factory=lambda: {"temperature": 0.0, "seed": 0})
    vision: bool = False
    transcript: Transcript | None = None
    _client: Any = field(default=None, init=False, repr=False)

    def __post_init__(self) -> None:

        import ollama

        if not self.model or not isinstance(self.model, str):
            raise InvalidInputError(f"model={self.model!r}; give an Ollama tag like 'qwen3:8b'.")
        if not (0 < self.timeout <= 3600):
            raise InvalidInputError(f"timeout={self.timeout!r} s must be in (0, 3600].")
        self.host = self.host or os.environ.get("OLLAMA_HOST") or DEFAULT_HOST
        self._client = ollama.Client(host=self.host, timeout=self.timeout)

    def _messages(self, messages: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
        out = []
        for m in messages:
            msg = {k: v for k, v in m.items() if v is not None}
            if not self.vision:
                msg.pop("images", None)
            out.append(msg)
        return out

    def _error(self, exc: Exception) -> tuple[LLMError, bool]:
        """Translate an ollama/httpx error; the flag says whether a retry may help."""
        import httpx
        import ollama

        if isinstance(exc, ollama.ResponseError):
            text = str(exc.error)
            if text.startswith(REPLAY_MARK):
                return ReplayMissError(text), False
            if exc.status_code == 404 and "not found" in text.lower():
                return (
                    LLMUnavailableError(
                        f"model {self.model!r} is not installed in Ollama at {self.host}: run "
                        f"`ollama pull {self.model}` (or pick an installed one: `ollama list`)."
                    ),
                    False,
                )
            retry = exc.status_code >= 500 or exc.status_code == 429
            return LLMError(f"Ollama at {self.host} refused the request: {exc}"), retry
        if isinstance(exc, ConnectionError | httpx.ConnectError):
            return (
                LLMUnavailableError(
                    f"Ollama is not reachable at {self.host}: start it with `ollama serve`, or "
                    "point --ollama-host (or $OLLAMA_HOST) at a running server."
                ),
                True,
            )
        if isinstance(exc, httpx.TimeoutException):
            return (
                LLMError(
                    f"Ollama at {self.host} gave no answer within {self.timeout} s for model "
                    f"{self.model!r}; raise the timeout or use a smaller model."
                ),
                True,
            )
        if isinstance(exc, httpx.HTTPError):
            return LLMError(f"HTTP error talking to Ollama at {self.host}: {exc}"), True
        raise exc

    def check(self) -> dict[str, Any]:
        """Whether the server answers and has the model: its details, or a clear error.

        Raises:
            LLMUnavailableError: the server is down or the model is not pulled.
        """
        try:
            shown = self._client.show(self.model)
        except Exception as exc:
            error, _ = self._error(exc)
            raise error from None
        details = getattr(shown, "details", None)
        capabilities = list(getattr(shown, "capabilities", None) or [])
        return {
            "host": self.host,
            "model": self.model,
            "family": getattr(details, "family", None),
            "parameters": getattr(details, "parameter_size", None),
            "capabilities": capabilities,
            "vision": "vision" in capabilities,
            "tools": "tools" in capabilities,
        }

    def chat(
        self,
        messages: Sequence[Mapping[str, Any]],
        *,
        tools: Sequence[Mapping[str, Any]] | None = None,
        format: Mapping[str, Any] | None = None,
        prompt: Prompt | None = None,
    ) -> LLMReply:
        """See `LLMClient.chat`. Raises the `LLMError` family after the retries."""
        msgs = self._messages(messages)
        if self.transcript is not None:
            self.transcript.write(
                "llm_request",
                model=self.model,
                prompt=prompt.ref if prompt else None,
                messages=msgs,
                tools=[t.get("function", {}).get("name") for t in tools or []],
                format=bool(format),
            )
        t0 = time.monotonic()
        error: LLMError | None = None
        for attempt in range(self.retries + 1):
            try:
                r = self._client.chat(
                    model=self.model,
                    messages=msgs,
                    tools=list(tools) if tools else None,
                    format=dict(format) if format is not None else None,
                    options=self.options,
                    keep_alive=self.keep_alive,
                )
                break
            except Exception as exc:
                error, retry = self._error(exc)
                if not retry or attempt == self.retries:
                    if self.transcript is not None:
                        self.transcript.write("error", model=self.model, error=str(error))
                    raise error from None
                time.sleep(self.backoff * 2**attempt)
        calls = tuple(
            ToolCall(c.function.name, dict(c.function.arguments or {}))
            for c in (r.message.tool_calls or [])
        )
        reply = LLMReply(
            content=r.message.content or "",
            tool_calls=calls,
            prompt_tokens=int(r.prompt_eval_count or 0),
            output_tokens=int(r.eval_count or 0),
            seconds=round(time.monotonic() - t0, 3),
            model=str(r.model or self.model),
        )
        if self.transcript is not None:
            self.transcript.write(
                "llm_response",
                model=reply.model,
                prompt=prompt.ref if prompt else None,
                content=reply.content,
                tool_calls=[{"name": c.name, "arguments": c.arguments} for c in calls],
                prompt_tokens=reply.prompt_tokens,
                output_tokens=reply.output_tokens,
                seconds=reply.seconds,
            )
        return reply
