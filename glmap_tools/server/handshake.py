"""Answer the stdio handshake from prepared answers while the MCP SDK is still importing.

Importing the MCP SDK takes 0.7-1.6 s on two cores (it builds pydantic models for every
protocol version), and clients time out their handshake in seconds. So `glmap-mcp` over
stdio starts a `StdioRelay` before that import: a thread reads the client's lines and
answers the session's opening request (`initialize`, or `server/discover` for stateless
2026-07-28 clients) and its first `tools/list` itself, from answers the real server gave
before (kept in `~/.glmap/cache/handshake.json`, or `$GLMAP_CACHE_DIR`). Every line still
reaches the SDK in order once it is loaded, so its session state is the client's; its
answers to the requests already answered are held back and compared with what was sent.
A difference (or no prepared answer) updates the file for the next launch, and is logged.

The prepared answers are keyed by a stamp of the installed sources (glmap_tools, mcp,
mcp_types), so an upgrade or an edit is never answered from an old file. `glmap-mcp
--prepare` fills the file for every protocol version.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import logging
import os
import queue
import socket
import sys
import threading
import time
from collections.abc import AsyncIterator, Callable
from importlib.util import find_spec
from pathlib import Path
from typing import Any, BinaryIO, cast

from glmap_tools.checks import is_real

# Imports inside functions stay there: anyio, mcp load on first use: `glmap-mcp` answers the
# handshake before they load (the launch path); `bench tokens` and `bench startup` stay light; an
# import that may fail is caught where it is used.

logger = logging.getLogger(__name__)

FORMAT = 2
KEPT = 8  # installations whose answers one file keeps
INITIALIZE = "initialize"
TOOLS_LIST = "tools/list"
DISCOVER = "server/discover"
OPENINGS = (INITIALIZE, DISCOVER)  # a session opens with one of them, then lists tools
META_VERSION = "io.modelcontextprotocol/protocolVersion"
# mcp_types' HANDSHAKE_PROTOCOL_VERSIONS (opened by `initialize`) and MODERN_PROTOCOL_VERSIONS
# (stateless requests, opened by `server/discover`); listed here because importing
# mcp_types is the slow part.
HANDSHAKE_VERSIONS = ("2024-11-05", "2025-03-26", "2025-06-18", "2025-11-25")
MODERN_VERSIONS = ("2026-07-28",)
LOOK_AFTER_HANDOVER = 8  # lines still looked at once the SDK reads, to record its answers


def is_complete(answers: Any) -> bool:
    """Whether `answers` (method -> result) hold an opening and tools/list."""
    return (
        isinstance(answers, dict)
        and isinstance(answers.get(TOOLS_LIST), dict)
        and any(isinstance(answers.get(m), dict) for m in OPENINGS)
    )


def cache_dir() -> Path:
    """`$GLMAP_CACHE_DIR`, else `~/.glmap/cache`."""
    env = os.environ.get("GLMAP_CACHE_DIR")
    return Path(env).expanduser() if env else Path.home() / ".glmap" / "cache"


def answers_path() -> Path:
    return cache_dir() / "handshake.json"


def source_stamp() -> str:
    """A hash of the path, size and mtime of every source file the answers depend on."""
    digest = hashlib.sha256(sys.version.encode())
    roots = [Path(__file__).resolve().parents[1]]  # glmap_tools
    for package in ("mcp", "mcp_types"):
        spec = find_spec(package)
        if spec is not None and spec.origin is not None:
            roots.append(Path(spec.origin).parent)
    for root in roots:
        for folder, dirs, files in os.walk(root):
            dirs[:] = sorted(d for d in dirs if d != "__pycache__")
            for name in sorted(files):
                if name.endswith(".py"):
                    st = os.stat(os.path.join(folder, name))
                    digest.update(f"{folder}/{name}:{st.st_size}:{st.st_mtime_ns}\n".encode())
    return digest.hexdigest()[:32]


class PreparedAnswers:
    """The prepared results of `initialize` and `tools/list`, per protocol version.

    The file keeps the answers of the last `KEPT` installations (checkouts, virtual
    environments), each under its source stamp, so they do not overwrite each other.

    Args:
        path: the JSON file; a missing or unreadable file is empty.
        stamp: `source_stamp()` of this installation.
    """

    def __init__(self, path: Path, stamp: str) -> None:
        self.path = path
        self.stamp = stamp
        self.answers: dict[str, dict[str, Any]] = {}
        self._lock = threading.Lock()
        mine = self._read().get(stamp, {}).get("answers")
        if isinstance(mine, dict):
            self.answers = {v: a for v, a in mine.items() if is_complete(a)}

    def _read(self) -> dict[str, Any]:
        """The file's installations (stamp -> {"answers", "written"}), or {}."""
        try:
            data = json.loads(self.path.read_text())
        except (OSError, ValueError):
            return {}
        if not isinstance(data, dict) or data.get("format") != FORMAT:
            return {}
        kept = data.get("installations")
        return (
            {k: v for k, v in kept.items() if isinstance(v, dict)} if isinstance(kept, dict) else {}
        )

    def get(self, version: str, method: str) -> dict[str, Any] | None:
        return self.answers.get(version, {}).get(method)

    def put(self, version: str, method: str, result: dict[str, Any]) -> None:
        """Record the real server's `result`; the file is rewritten once a version has both."""
        with self._lock:
            entry = self.answers.setdefault(version, {})
            if entry.get(method) == result:
                return
            entry[method] = result
            if not is_complete(entry):
                return
            installations = self._read()
            installations.pop(self.stamp, None)
            installations[self.stamp] = {"answers": self.complete(), "written": time.time()}
            newest = sorted(installations, key=lambda k: installations[k].get("written", 0))
            kept = {k: installations[k] for k in newest[-KEPT:]}
            data = {"format": FORMAT, "installations": kept}
            try:
                from glmap_tools.atomic import write_atomic

                self.path.parent.mkdir(parents=True, exist_ok=True)
                write_atomic(self.path, [json.dumps(data, ensure_ascii=False).encode()])
            except Exception as exc:  # a read-only home: answer through the SDK next time
                logger.info("glmap-mcp: cannot keep the handshake answers: %s", exc)

    def complete(self) -> dict[str, dict[str, Any]]:
        return {v: a for v, a in self.answers.items() if is_complete(a)}


def _claim(fd: int, mode: str, diversion: int) -> tuple[BinaryIO, int | None]:
    """A private file on standard stream `fd`, which then points at `diversion`, so stray
    reads and prints of libraries miss the wire (as the SDK's own stdio transport does)."""
    try:
        private = os.dup(fd)
        os.dup2(diversion, fd)
    except OSError:
        stream = sys.stdin if fd == 0 else sys.stdout
        return stream.buffer, None
    return cast(BinaryIO, os.fdopen(private, mode, closefd=False)), private


def _request_id(value: Any) -> bool:
    """Whether `value` is a JSON-RPC request id (a string or a number)."""
    return isinstance(value, str) or is_real(value)


class StdioRelay:
    """The process's stdio between the client and the MCP SDK (see the module docstring).

    Start it before importing the SDK; then `serve(server)` runs the server on it.

    Args:
        prepared: the prepared answers (answers the handshake early if it has them).
        source: the client's lines; default the process's stdin (claimed).
        sink: where answers go; default the process's stdout (claimed).
    """

    def __init__(
        self,
        prepared: PreparedAnswers,
        source: BinaryIO | None = None,
        sink: BinaryIO | None = None,
    ) -> None:
        self.prepared = prepared
        self._restore: list[tuple[int, int]] = []
        if source is None:
            null = os.open(os.devnull, os.O_RDONLY)
            source, fd = _claim(0, "rb", null)
            os.close(null)
            if fd is not None:
                self._restore.append((0, fd))
        if sink is None:
            sink, fd = _claim(1, "wb", 2)
            if fd is not None:
                self._restore.append((1, fd))
        self.source = source
        self.sink = sink
        self.lines: queue.Queue[bytes | None] = queue.Queue()
        self.early: dict[Any, dict[str, Any]] = {}  # request id -> the result sent early
        self.watched: dict[Any, tuple[str, str]] = {}  # request id -> (version, method)
        self.answered_early: list[str] = []  # methods answered before the SDK was loaded
        self._looked: set[str] = set()  # the methods whose first request is watched
        self._after_handover = 0
        self._version: str | None = None  # asked for in the first initialize
        self._handed_over = threading.Event()
        self._write_lock = threading.Lock()
        self._watch_lock = threading.Lock()
        threading.Thread(target=self._read, name="glmap-stdio", daemon=True).start()

    # The client's side: read every line; answer the handshake early when prepared.
    def _read(self) -> None:
        try:
            for line in iter(self.source.readline, b""):
                if self._looking():
                    try:
                        self._look_at(line)
                    except Exception:  # the early answer is a shortcut: the SDK answers instead
                        logger.exception("glmap-mcp: cannot look at a client line; SDK reads it")
                self.lines.put(line)
        except (OSError, ValueError) as exc:
            logger.info("glmap-mcp: stdin closed: %s", exc)
        self.lines.put(None)

    def _looking(self) -> bool:
        if TOOLS_LIST in self._looked:
            return False
        if self._handed_over.is_set():
            self._after_handover += 1
            return self._after_handover <= LOOK_AFTER_HANDOVER
        return True

    def _look_at(self, line: bytes) -> None:
        """Answer (or watch for the SDK's answer to) the opening request and tools/list."""
        try:
            message = json.loads(line)
        except (ValueError, RecursionError):  # the SDK answers a line it cannot parse
            return
        if not isinstance(message, dict) or not _request_id(message.get("id")):
            return
        method = message.get("method")
        params = message.get("params") or {}
        if not isinstance(params, dict):
            return
        meta = params.get("_meta")
        version = meta.get(META_VERSION) if isinstance(meta, dict) else None
        if method == INITIALIZE and self._version is None:
            version = self._version = str(params.get("protocolVersion"))
        elif method == DISCOVER and isinstance(version, str):
            pass
        elif method == TOOLS_LIST and not params.get("cursor"):
            version = version or self._version
        else:
            return
        if not isinstance(version, str):
            return
        with self._watch_lock:
            if method in self._looked:
                return  # the first of each is watched
            self._looked.add(method)
            self.watched[message["id"]] = (version, method)
            result = None if self._handed_over.is_set() else self.prepared.get(version, method)
            if result is not None:
                self.early[message["id"]] = result
                self.answered_early.append(method)
        if result is not None:
            self._send({"jsonrpc": "2.0", "id": message["id"], "result": result})

    def _send(self, message: dict[str, Any]) -> None:
        data = json.dumps(message, ensure_ascii=False, separators=(",", ":")).encode() + b"\n"
        self._write(data)

    def _write(self, data: bytes) -> None:
        with self._write_lock:
            self.sink.write(data)
            self.sink.flush()

    # The SDK's side.
    def _sdk_line(self, text: str) -> None:
        """One answer line from the SDK: held back if it was answered early, else sent."""
        if self.watched:
            try:
                message = json.loads(text)
            except ValueError:
                message = None
            if isinstance(message, dict) and "id" in message and "method" not in message:
                with self._watch_lock:
                    watched = self.watched.pop(message["id"], None)
                    sent = self.early.pop(message["id"], None)
                if watched is not None:
                    self._check(watched, sent, message.get("result"))
                if sent is not None:
                    return
        self._write(text.encode())

    def _check(self, watched: tuple[str, str], sent: Any, result: Any) -> None:
        version, method = watched
        if not isinstance(result, dict):
            return  # an error: nothing to prepare
        if sent is not None and sent != result:
            logger.warning(
                "glmap-mcp: the prepared %s answer was out of date; it is refreshed for the "
                "next start",
                method,
            )
        self.prepared.put(version, method, result)

    def serve(self, server: Any) -> None:
        """Run `server` (an MCPServer) on this relay until the client closes stdin."""
        import anyio
        from mcp.server.stdio import stdio_server

        relay = self

        class Stdin:
            def __aiter__(self) -> AsyncIterator[str]:
                return self._lines()

            async def _lines(self) -> AsyncIterator[str]:
                relay._handed_over.set()
                while True:
                    line = await anyio.to_thread.run_sync(relay.lines.get, abandon_on_cancel=True)
                    if line is None:
                        return
                    yield line.decode("utf-8", errors="replace")

        class Stdout:
            async def write(self, text: str) -> None:
                await anyio.to_thread.run_sync(relay._sdk_line, text)

            async def flush(self) -> None:
                return None

        lowlevel = server._lowlevel_server

        async def run() -> None:
            async with stdio_server(stdin=Stdin(), stdout=Stdout()) as (read, write):  # type: ignore[arg-type]
                await lowlevel.run(read, write, lowlevel.create_initialization_options())

        try:
            anyio.run(run)
        finally:
            self.close()

    def forward(self, sock: socket.socket, first_line: Callable[[], None]) -> None:
        """Pass the client's lines to a server behind `sock` (`glmap-mcp --linger`) and its
        lines back, until it closes; `first_line()` runs when its first line (or its end)
        arrives."""

        def pump() -> None:
            try:
                while (line := self.lines.get()) is not None:
                    sock.sendall(line)
            except OSError:
                pass
            finally:
                with contextlib.suppress(OSError):
                    sock.shutdown(socket.SHUT_WR)  # the client is done: so is its session

        self._handed_over.set()
        threading.Thread(target=pump, name="glmap-linger", daemon=True).start()
        told = False
        try:
            with sock, sock.makefile("rb") as answers:
                for line in iter(answers.readline, b""):
                    if not told:
                        told = True
                        first_line()
                    self._sdk_line(line.decode("utf-8", errors="replace"))
        finally:
            if not told:
                first_line()
            self.close()

    def close(self) -> None:
        """Point the standard streams back at the wire."""
        for fd, private in self._restore:
            with contextlib.suppress(OSError):
                os.dup2(private, fd)
        self._restore.clear()


def start_relay() -> StdioRelay:
    """A relay on this process's stdio with this installation's prepared answers."""
    return StdioRelay(PreparedAnswers(answers_path(), source_stamp()))


def opening_requests(version: str, client: str) -> list[dict[str, Any]]:
    """A client's first messages in `version`: the opening request (id 1), then tools/list
    (id 2); `server/discover` with every request's `_meta` envelope for stateless versions,
    else `initialize` and its `notifications/initialized`."""
    info = {"name": client, "version": "1"}
    if version in MODERN_VERSIONS:
        meta = {
            META_VERSION: version,
            "io.modelcontextprotocol/clientInfo": info,
            "io.modelcontextprotocol/clientCapabilities": {},
        }
        return [
            {"jsonrpc": "2.0", "id": i, "method": m, "params": {"_meta": meta}}
            for i, m in ((1, DISCOVER), (2, TOOLS_LIST))
        ]
    opening = {"protocolVersion": version, "capabilities": {}, "clientInfo": info}
    return [
        {"jsonrpc": "2.0", "id": 1, "method": INITIALIZE, "params": opening},
        {"jsonrpc": "2.0", "method": "notifications/initialized"},
        {"jsonrpc": "2.0", "id": 2, "method": TOOLS_LIST, "params": {}},
    ]


def _exchange(
    command: list[str], text: str, ids: set[int], timeout: float
) -> tuple[set[Any], str, int | None]:
    """Send `text` to a new server, read until `ids` are answered (stdin stays open till
    then: a stateless server drops requests still running when its input ends), close.

    Returns:
        (the ids answered, the server's stderr, its exit status or None if it was killed).
    """
    import subprocess
    import tempfile

    with tempfile.TemporaryFile("w+") as err:
        proc = subprocess.Popen(
            command, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=err, text=True
        )
        timer = threading.Timer(timeout, proc.kill)
        timer.start()
        answered: set[Any] = set()
        try:
            assert proc.stdin is not None and proc.stdout is not None
            proc.stdin.write(text)
            proc.stdin.flush()
            for line in proc.stdout:
                with contextlib.suppress(ValueError, AttributeError):
                    answered.add(json.loads(line).get("id"))
                if ids <= answered:
                    break
            proc.stdin.close()
            code = proc.wait()
        finally:
            timer.cancel()
        err.seek(0)
        return answered, err.read(), code


def prepare_handshake(timeout: float = 60.0) -> list[str]:
    """Start `glmap-mcp` once per protocol version and let it keep its answers.

    Returns:
        The versions whose answers are now prepared for this installation.

    Raises:
        RuntimeError: a server did not answer (its stderr is in the message).
    """
    import tempfile

    for version in (*HANDSHAKE_VERSIONS, *MODERN_VERSIONS):
        with tempfile.TemporaryDirectory() as maps:
            command = [sys.executable, "-m", "glmap_tools.server", "--embedder", "hashing"]
            command += ["--no-warm-up", "--maps-dir", maps]
            requests = opening_requests(version, "glmap-mcp --prepare")
            text = "".join(json.dumps(r) + "\n" for r in requests)
            answered, stderr, code = _exchange(command, text, {1, 2}, timeout)
            if not {1, 2} <= answered:
                raise RuntimeError(
                    f"glmap-mcp did not answer the {version} opening (exit {code}):\n"
                    f"{stderr[-2000:]}"
                )
    return sorted(PreparedAnswers(answers_path(), source_stamp()).complete())
