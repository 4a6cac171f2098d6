"""Episode transcripts: one JSON object per line for every model call and tool call.

A transcript lets anyone see what a run sent and got back: the prompt's name and hash,
the request (images as their SHA-256 and size, not their bytes), the response, tool calls
and their results, errors. Agents and the LLM-backed map parts write to the same file.
"""

from __future__ import annotations

import base64
import hashlib
import json
import os
import threading
import time
from collections.abc import Mapping
from pathlib import Path
from typing import IO, Any

MAX_STRING = 20_000  # characters of one string field kept in a transcript line


def image_ref(data: bytes | str) -> str:
    """`sha256:<hex16>:<bytes>` for an image given as bytes or base64 text."""
    if isinstance(data, bytes):
        raw = data
    else:
        try:
            raw = base64.b64decode(data, validate=True)
        except ValueError:  # not base64: hash the text itself
            raw = data.encode("utf-8")
    return f"sha256:{hashlib.sha256(raw).hexdigest()[:16]}:{len(raw)}"


def scrub(value: Any) -> Any:
    """A JSON-safe copy with image payloads replaced by `image_ref`s and long strings cut."""
    if isinstance(value, Mapping):
        out: dict[str, Any] = {}
        for k, v in value.items():
            if k == "images" and isinstance(v, list | tuple):
                out[k] = [image_ref(x) if isinstance(x, bytes | str) else scrub(x) for x in v]
            elif k == "data" and isinstance(v, str) and len(v) > 256:
                out[k] = image_ref(v)
            else:
                out[str(k)] = scrub(v)
        return out
    if isinstance(value, list | tuple):
        return [scrub(v) for v in value]
    if isinstance(value, bytes):
        return image_ref(value)
    if isinstance(value, str) and len(value) > MAX_STRING:
        return value[:MAX_STRING] + f"... [{len(value) - MAX_STRING} more characters]"
    if isinstance(value, float | int | bool) or value is None or isinstance(value, str):
        return value
    if hasattr(value, "model_dump"):
        return scrub(value.model_dump())
    return repr(value)


class Transcript:
    """Appends events to a JSONL file (thread-safe; each line flushed when written).

    Args:
        path: the file; its folder is created. None keeps events in memory only.
    """

    def __init__(self, path: str | os.PathLike[str] | None = None) -> None:
        self.path = Path(path) if path is not None else None
        self.events: list[dict[str, Any]] = []
        self._lock = threading.Lock()
        self._file: IO[str] | None = None
        if self.path is not None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._file = self.path.open("a", encoding="utf-8")
        self._t0 = time.monotonic()

    def write(self, kind: str, **fields: Any) -> dict[str, Any]:
        """Record one event; kind: llm_request|llm_response|tool_call|tool_result|error|note."""
        event = {"t": round(time.monotonic() - self._t0, 4), "kind": kind, **scrub(fields)}
        with self._lock:
            self.events.append(event)
            if self._file is not None:
                self._file.write(json.dumps(event, ensure_ascii=False, sort_keys=True) + "\n")
                self._file.flush()
        return event

    def close(self) -> None:
        with self._lock:
            if self._file is not None:
                self._file.close()
                self._file = None

    def __enter__(self) -> Transcript:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
