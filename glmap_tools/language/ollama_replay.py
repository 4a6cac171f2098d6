"""Record and replay Ollama HTTP exchanges: a small Ollama-compatible server on 127.0.0.1.

Replay mode answers each request with the response recorded for it, so the real `ollama`
client (and everything above it) runs in tests without a model. Record mode forwards every
request to a live Ollama and writes what came back. A request missing from a recording is
answered with an error that names the closest recorded request, where the two differ, and
the command that re-records the file.

Cassette file (JSON Lines): a header line
    {"format": "glmap-ollama-cassette", "version": 1, "source": ..., "record": ...}
then one line per exchange: {"key", "request": {"method", "path", "body"}, "response":
{"status", "body"}}. Request bodies are stored canonically: sorted keys, `keep_alive`
dropped, images replaced by their SHA-256 (so cassettes stay small and diffable). Keys
ignore image content (only how many images a message carries), since renders can differ
in their last bits from one CPU to another.
`source` says whether a file was recorded from a model or written by hand.
"""

from __future__ import annotations

import difflib
import hashlib
import json
import os
import sys
import threading
import time
import urllib.error
import urllib.request
from collections import defaultdict
from dataclasses import dataclass, field
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any

from glmap_tools.atomic import write_atomic
from glmap_tools.errors import InvalidInputError, StoreError
from glmap_tools.language.llm import REPLAY_MARK
from glmap_tools.language.transcript import scrub

FORMAT = "glmap-ollama-cassette"
VERSION = 1
RECORD_ENV = "GLMAP_OLLAMA_RECORD"
VOLATILE = ("keep_alive",)
MAX_BODY = 64 * 1024 * 1024


def canonical(body: Any) -> Any:
    """The request body as stored and matched: images hashed, volatile fields dropped."""
    if isinstance(body, dict):
        body = {k: v for k, v in body.items() if k not in VOLATILE}
    return scrub(body)


def _mask_images(value: Any) -> Any:
    """Images replaced by a placeholder: renders may differ in their last bits across CPUs,
    so a request matches on its text and on how many images it carries."""
    if isinstance(value, dict):
        return {
            k: (["image"] * len(v) if k == "images" and isinstance(v, list) else _mask_images(v))
            for k, v in value.items()
        }
    if isinstance(value, list):
        return [_mask_images(v) for v in value]
    return value


def request_key(method: str, path: str, body: Any) -> str:
    """The matching key of a request: method, path and canonical body, images masked."""
    masked = _mask_images(canonical(body))
    text = json.dumps([method, path, masked], sort_keys=True, ensure_ascii=False)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def _summary(body: Any) -> str:
    """A short human description of a request body (model, last message)."""
    if not isinstance(body, dict):
        return json.dumps(body)[:120]
    last = ""
    messages = body.get("messages") or []
    messages = messages if isinstance(messages, list) else []
    if messages and isinstance(messages[-1], dict):
        last = str(messages[-1].get("content", ""))[:100]
    return f"model {body.get('model')!r}, {len(messages)} messages, last: {last!r}"


@dataclass
class Cassette:
    """Recorded exchanges, by request key (several per key are served in order)."""

    path: Path
    header: dict[str, Any]
    exchanges: list[dict[str, Any]] = field(default_factory=list)

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Cassette:
        """Read a cassette file.

        Raises:
            StoreError: missing, not a cassette, or a newer version.
        """
        p = Path(path)
        try:
            lines = [ln for ln in p.read_text(encoding="utf-8").splitlines() if ln.strip()]
            records = [json.loads(ln) for ln in lines]
        except FileNotFoundError:
            raise StoreError(
                f"no recording at {p}; record one against a live Ollama with "
                f"{RECORD_ENV}=http://127.0.0.1:11434 (see docs/own_model.md)."
            ) from None
        except (UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise StoreError(f"{p} is not a JSON Lines cassette: {exc}.") from None
        if not records or not isinstance(records[0], dict) or records[0].get("format") != FORMAT:
            raise StoreError(f"{p} is not a {FORMAT} file (its first line is the header).")
        version = records[0].get("version", 0)
        if isinstance(version, bool) or not isinstance(version, int) or version > VERSION:
            raise StoreError(f"{p} has cassette version {version!r}; this reads 1..{VERSION}.")
        for line, ex in enumerate(records[1:], start=2):
            if not _is_exchange(ex):
                raise StoreError(
                    f"{p} line {line} is not a recorded exchange ({{key, request: {{method, "
                    "path, body}, response: {status, body}}}); re-record the cassette."
                )
        return cls(p, records[0], records[1:])

    def save(self) -> None:
        lines = [self.header, *self.exchanges]
        text = "".join(json.dumps(r, sort_keys=True, ensure_ascii=False) + "\n" for r in lines)
        write_atomic(self.path, [text.encode("utf-8")])

    def closest(self, method: str, path: str, body: Any) -> tuple[int, float, str]:
        """(index, similarity in [0, 1], where they differ) of the nearest recorded request."""
        want = json.dumps(canonical(body), sort_keys=True, indent=0)
        best = (-1, 0.0, "")
        for i, ex in enumerate(self.exchanges):
            req = ex["request"]
            if req["method"] != method or req["path"] != path:
                continue
            have = json.dumps(req["body"], sort_keys=True, indent=0)
            matcher = difflib.SequenceMatcher(None, have, want, autojunk=False)
            if matcher.real_quick_ratio() <= best[1] or matcher.quick_ratio() <= best[1]:
                continue
            ratio = matcher.ratio()
            if ratio > best[1]:
                diff = next(
                    (
                        f"recorded {have[a1:a2][:80]!r} vs requested {want[b1:b2][:80]!r}"
                        for tag, a1, a2, b1, b2 in matcher.get_opcodes()
                        if tag != "equal"
                    ),
                    "",
                )
                best = (i, ratio, diff)
        return best


def _is_exchange(ex: Any) -> bool:
    """Whether a cassette line holds what replaying it reads."""
    if not isinstance(ex, dict) or not isinstance(ex.get("key"), str):
        return False
    req, resp = ex.get("request"), ex.get("response")
    return (
        isinstance(req, dict)
        and isinstance(req.get("method"), str)
        and isinstance(req.get("path"), str)
        and "body" in req
        and isinstance(resp, dict)
        and isinstance(resp.get("status"), int)
        and not isinstance(resp.get("status"), bool)
        and "body" in resp
    )


class _Handler(BaseHTTPRequestHandler):
    server: _ReplayHTTPServer
    protocol_version = "HTTP/1.1"

    def log_message(self, format: str, *args: Any) -> None:  # quiet in tests
        pass

    def _send(self, status: int, body: Any) -> None:
        data = json.dumps(body).encode("utf-8")
        self.send_response(status)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(data)))
        self.end_headers()
        self.wfile.write(data)

    def _body(self) -> Any:
        n = int(self.headers.get("Content-Length") or 0)
        if n > MAX_BODY:
            raise ValueError(f"request body of {n} bytes")
        raw = self.rfile.read(n) if n else b""
        return json.loads(raw) if raw else None

    def do_GET(self) -> None:
        self._handle("GET")

    def do_POST(self) -> None:
        self._handle("POST")

    def _handle(self, method: str) -> None:
        try:
            body = self._body()
        except (ValueError, json.JSONDecodeError) as exc:
            self._send(400, {"error": f"bad request body: {exc}"})
            return
        status, reply = self.server.owner.answer(method, self.path, body)
        self._send(status, reply)


class _ReplayHTTPServer(ThreadingHTTPServer):
    daemon_threads = True
    owner: OllamaReplayServer

    def handle_error(self, request: Any, client_address: Any) -> None:
        """A client that hung up before its answer (a timeout test) is not an error."""

        if isinstance(sys.exc_info()[1], ConnectionError):
            return
        super().handle_error(request, client_address)


class OllamaReplayServer:
    """An Ollama-compatible HTTP server on 127.0.0.1 that replays or records a cassette.

    Args:
        cassette: the cassette file.
        upstream: a live Ollama URL to record from; None replays. Defaults to
            $GLMAP_OLLAMA_RECORD when `record_from_env` is set.
        record_command: the command that re-records this cassette (quoted in misses and
            written into recorded headers).
        port: 0 picks a free port.

    Use as a context manager; `host` is the URL to give `OllamaClient`.
    """

    def __init__(
        self,
        cassette: str | os.PathLike[str],
        *,
        upstream: str | None = None,
        record_from_env: bool = False,
        record_command: str = "",
        port: int = 0,
    ) -> None:
        if record_from_env and upstream is None:
            upstream = os.environ.get(RECORD_ENV) or None
        self.upstream = upstream.rstrip("/") if upstream else None
        self.record_command = record_command or (
            f"{RECORD_ENV}=http://127.0.0.1:11434 <the command that made this recording>"
        )
        path = Path(cassette)
        if self.upstream is None:
            self.cassette = Cassette.load(path)
        else:
            self.cassette = Cassette(
                path,
                {
                    "format": FORMAT,
                    "version": VERSION,
                    "source": f"recorded from the Ollama at {self.upstream} on "
                    f"{time.strftime('%Y-%m-%d')}",
                    "record": self.record_command,
                },
            )
        self._served: dict[str, int] = defaultdict(int)
        self._by_key: dict[str, list[int]] = defaultdict(list)
        for i, ex in enumerate(self.cassette.exchanges):
            self._by_key[ex["key"]].append(i)
        self._lock = threading.Lock()
        self.misses: list[str] = []
        self._httpd = _ReplayHTTPServer(("127.0.0.1", port), _Handler)
        self._httpd.owner = self
        self._thread: threading.Thread | None = None

    @property
    def host(self) -> str:
        return f"http://127.0.0.1:{self._httpd.server_address[1]}"

    @property
    def recording(self) -> bool:
        return self.upstream is not None

    def __enter__(self) -> OllamaReplayServer:
        self._thread = threading.Thread(target=self._httpd.serve_forever, daemon=True)
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        self._httpd.shutdown()
        self._httpd.server_close()
        if self.recording:
            self.cassette.save()

    def answer(self, method: str, path: str, body: Any) -> tuple[int, Any]:
        """The (status, JSON body) for one request."""
        if self.recording:
            return self._forward(method, path, body)
        if method == "GET" and path == "/api/version":
            return 200, {"version": "0.0.0-glmap-replay"}
        key = request_key(method, path, body)
        with self._lock:
            indices = self._by_key.get(key)
            if indices:
                n = self._served[key]
                self._served[key] = n + 1
                ex = self.cassette.exchanges[indices[min(n, len(indices) - 1)]]
                return int(ex["response"]["status"]), ex["response"]["body"]
        index, ratio, diff = self.cassette.closest(method, path, body)
        if index >= 0:
            nearest = _summary(self.cassette.exchanges[index]["request"]["body"])
            closest = (
                f"closest recorded request: #{index + 1} ({nearest}), similarity {ratio:.2f}, "
                f"first difference: {diff}"
            )
        else:
            closest = f"the recording holds no {method} {path} request"

        message = (
            f"{REPLAY_MARK} no recorded response in {self.cassette.path.name} for {method} "
            f"{path} ({_summary(canonical(body))}); {closest}. The request changed (prompt, "
            f"model, options or inputs): re-record against a live Ollama with: "
            f"{self.record_command}"
        )
        self.misses.append(message)
        return 501, {"error": message}

    def _forward(self, method: str, path: str, body: Any) -> tuple[int, Any]:
        assert self.upstream is not None
        data = json.dumps(body).encode("utf-8") if body is not None else None
        req = urllib.request.Request(
            self.upstream + path,
            data=data,
            method=method,
            headers={"Content-Type": "application/json"},
        )
        try:
            with urllib.request.urlopen(req, timeout=600) as resp:
                status, reply = resp.status, json.loads(resp.read() or b"null")
        except urllib.error.HTTPError as exc:
            status = exc.code
            try:
                reply = json.loads(exc.read() or b"null")
            except json.JSONDecodeError:
                reply = {"error": str(exc)}
        except urllib.error.URLError as exc:
            return 502, {"error": f"record mode: upstream {self.upstream} unreachable: {exc}"}
        if isinstance(reply, dict):
            # Timings differ run to run; keep the counts that token tables use.
            for k in ("total_duration", "load_duration", "prompt_eval_duration", "eval_duration"):
                reply.pop(k, None)
        with self._lock:
            self.cassette.exchanges.append(
                {
                    "key": request_key(method, path, body),
                    "request": {"method": method, "path": path, "body": canonical(body)},
                    "response": {"status": status, "body": reply},
                }
            )
        return status, reply


def write_cassette(
    path: str | os.PathLike[str],
    exchanges: list[tuple[str, str, Any, int, Any]],
    *,
    source: str,
    record: str,
) -> Cassette:
    """Write a cassette from (method, path, request body, status, response body) tuples.

    Used for recordings written by hand or by a scripted stand-in model; `source` must say
    so, and `record` gives the command that replaces the file with a real recording.
    """
    if not source.strip():
        raise InvalidInputError("source must say where the exchanges came from.")
    cassette = Cassette(
        Path(path), {"format": FORMAT, "version": VERSION, "source": source, "record": record}
    )
    for method, p, body, status, reply in exchanges:
        cassette.exchanges.append(
            {
                "key": request_key(method, p, body),
                "request": {"method": method, "path": p, "body": canonical(body)},
                "response": {"status": status, "body": reply},
            }
        )
    cassette.save()
    return cassette


class ScriptedOllama:
    """An Ollama-compatible server whose answers come from a Python function.

    A stand-in model for writing recordings by hand (record through an
    `OllamaReplayServer` pointed at it, then say so in the cassette's `source`) and for
    fault tests (slow answers, errors). Not a model: `responder` decides every reply.

    Args:
        responder: (method, path, body) -> (status, JSON body).
        delay: seconds to wait before each answer (timeout tests).
    """

    def __init__(self, responder: Any, delay: float = 0.0) -> None:
        self.responder = responder
        self.delay = delay
        self.requests: list[tuple[str, str, Any]] = []
        self._httpd = _ReplayHTTPServer(("127.0.0.1", 0), _Handler)
        self._httpd.owner = self  # type: ignore[assignment]
        self._thread: threading.Thread | None = None

    @property
    def host(self) -> str:
        return f"http://127.0.0.1:{self._httpd.server_address[1]}"

    def answer(self, method: str, path: str, body: Any) -> tuple[int, Any]:
        self.requests.append((method, path, body))
        if self.delay:
            time.sleep(self.delay)
        return self.responder(method, path, body)  # type: ignore[no-any-return]

    def __enter__(self) -> ScriptedOllama:
        self._thread = threading.Thread(target=self._httpd.serve_forever, daemon=True)
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._httpd.shutdown()
        self._httpd.server_close()


def chat_reply(model: str, content: str = "", tool_calls: list[Any] | None = None) -> dict:
    """An /api/chat response body as Ollama writes it (non-streaming)."""
    message: dict[str, Any] = {"role": "assistant", "content": content}
    if tool_calls:
        message["tool_calls"] = [
            {"function": {"name": name, "arguments": args}} for name, args in tool_calls
        ]
    return {
        "model": model,
        "created_at": "2026-01-01T00:00:00Z",
        "message": message,
        "done": True,
        "done_reason": "stop",
        "prompt_eval_count": 0,
        "eval_count": 0,
    }
