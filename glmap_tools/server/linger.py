"""`glmap-mcp --map NAME --linger SECONDS`: one warm server behind the processes a client
starts per call.

A client that starts a server for every tool call (LangChain's default `get_tools()`, the
Inspector CLI) makes each call pay the whole start-up: the imports, the kernels, reading the
map and replaying the episode. With `--linger`, the process the client starts is a relay: it
answers the handshake from the prepared answers (`handshake.StdioRelay`) and passes every
line on to a server that runs in the background, keeps the map and the episode in memory,
and exits once no client has been connected for SECONDS. The first call starts it; the next
calls find it.

The server listens on a Unix socket in `runtime_dir()` (this user's, mode 0700), named by a
hash of all that shapes it: the command line, the working folder, the environment variables
it reads, the installed sources and the interpreter. A call with other settings gets a server
of its own. The server's stderr goes to `<hash>.log` beside the socket.

`<hash>.lock` (flock) keeps a server from leaving while a client connects: a relay holds it
shared from its connect until the server's first line reaches it, and exclusive while it
starts a server; the server leaves only when it takes it exclusively with no connection open.
`<hash>.alive` (flock, exclusive) is held by the server for its whole life, from the relay's
launch on: a relay that finds no socket but a server alive (one still starting, whose relay
the client killed meanwhile) waits for that server instead of starting a second.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import json
import logging
import os
import signal
import socket
import stat
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from glmap_tools.errors import GLMapError
from glmap_tools.server.handshake import PreparedAnswers, StdioRelay, answers_path, source_stamp

# Imports inside functions stay there: anyio, mcp load on first use: the relay (the launch
# path of every call) imports neither.

logger = logging.getLogger(__name__)

SERVE_FLAG = "--serve-socket"  # the background server's own flag (hidden from --help)
ENV_PREFIXES = ("GLMAP_", "OLLAMA_", "PYOPENGL_", "HF_", "NUMBA_", "OMP_", "OPENBLAS_", "MKL_")
START_WAIT_S = 120.0  # how long a relay waits for the server it started to listen
POLL_S = 0.02
MAX_SOCKET_PATH = 100  # sun_path holds 104-108 bytes


class LingerError(GLMapError):
    """The background server could not be reached or started; `status` is the exit status."""

    def __init__(self, message: str, status: int = 1) -> None:
        super().__init__(message)
        self.status = status


def runtime_dir() -> Path:
    """`$XDG_RUNTIME_DIR/glmap`, else `<tmp>/glmap-<uid>`: created 0700, checked to be this
    user's alone (a socket there reaches the maps).

    Raises:
        LingerError: the folder is someone else's, open to others, or not a folder.
    """
    base = os.environ.get("XDG_RUNTIME_DIR")
    folder = Path(base) / "glmap" if base else Path(tempfile.gettempdir()) / f"glmap-{os.getuid()}"
    try:
        folder.mkdir(mode=0o700, parents=True, exist_ok=True)
        st = os.lstat(folder)
    except OSError as exc:
        raise LingerError(
            f"cannot create the folder for --linger's socket {str(folder)!r}: "
            f"{exc.strerror or exc}; set XDG_RUNTIME_DIR to a folder of yours."
        ) from None
    if not stat.S_ISDIR(st.st_mode) or st.st_uid != os.getuid() or st.st_mode & 0o077:
        raise LingerError(
            f"{str(folder)!r} is not a folder only you can use (owner uid {st.st_uid}, mode "
            f"{oct(st.st_mode & 0o777)}); remove it, or set XDG_RUNTIME_DIR to a folder of yours."
        )
    return folder


def server_key(argv: list[str], stamp: str, environ: Any = os.environ) -> str:
    """The hash that names the server for this command line, folder, environment and install."""
    shaping = sorted((k, v) for k, v in environ.items() if k.startswith(ENV_PREFIXES))
    blob = json.dumps(
        {
            "argv": argv,
            "cwd": os.getcwd(),
            "env": shaping,
            "python": sys.executable,
            "sources": stamp,
        }
    )
    return hashlib.sha256(blob.encode()).hexdigest()[:24]


class ServerFiles:
    """The socket, lock and log of one lingering server."""

    def __init__(self, folder: Path, key: str) -> None:
        self.socket = folder / f"{key}.sock"
        self.lock = folder / f"{key}.lock"
        self.log = folder / f"{key}.log"
        self.alive = folder / f"{key}.alive"
        if len(os.fsencode(self.socket)) > MAX_SOCKET_PATH:
            raise LingerError(
                f"the socket path {str(self.socket)!r} is too long for a Unix socket; set "
                "XDG_RUNTIME_DIR to a shorter folder of yours."
            )

    def open_lock(self) -> int:
        return os.open(self.lock, os.O_RDWR | os.O_CREAT, 0o600)


def _connect(path: Path) -> socket.socket | None:
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    try:
        sock.connect(os.fspath(path))
    except OSError:  # no such file, or refused: no server listens there
        sock.close()
        return None
    return sock


def _take_alive(files: ServerFiles) -> int | None:
    """The alive lock, taken exclusively, when no server of this key lives; else None."""
    fd = os.open(files.alive, os.O_RDWR | os.O_CREAT, 0o600)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        os.close(fd)
        return None
    return fd


def _start(argv: list[str], files: ServerFiles) -> socket.socket:
    """Start the background server and wait until it listens (the caller holds the lock;
    the server replaces the socket a dead one left). A server of this key that is alive
    but not yet listening is waited for instead."""
    alive = _take_alive(files)
    if alive is None:
        return _wait_for_the_starting_server(argv, files)
    try:
        with open(files.log, "wb") as log:
            child = subprocess.Popen(
                [sys.executable, "-m", "glmap_tools.server", *argv, SERVE_FLAG, str(files.socket)],
                stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL,
                stderr=log,
                start_new_session=True,  # outlives this process and the client's kill of its group
                pass_fds=(alive,),  # the server holds the alive lock from here on, for its life
            )
    finally:
        os.close(alive)
    deadline = time.monotonic() + START_WAIT_S
    while True:
        sock = _connect(files.socket)
        if sock is not None:
            return sock
        status = child.poll()
        if status is not None:
            text = files.log.read_text(errors="replace").strip()
            raise LingerError(text or f"the background server exited with status {status}", status)
        if time.monotonic() > deadline:
            child.kill()
            raise LingerError(
                f"the background server did not listen within {START_WAIT_S:.0f} s; its log: "
                f"{files.log}"
            )
        time.sleep(POLL_S)


def _wait_for_the_starting_server(argv: list[str], files: ServerFiles) -> socket.socket:
    """A connection to the server another relay started (and was killed before it listened);
    a server of our own when that one dies first."""
    deadline = time.monotonic() + START_WAIT_S
    while True:
        sock = _connect(files.socket)
        if sock is not None:
            return sock
        alive = _take_alive(files)
        if alive is not None:  # it died before it listened
            os.close(alive)
            return _start(argv, files)
        if time.monotonic() > deadline:
            raise LingerError(
                f"the background server another call started did not listen within "
                f"{START_WAIT_S:.0f} s; its log: {files.log}"
            )
        time.sleep(POLL_S)


def connect_or_start(argv: list[str], files: ServerFiles) -> tuple[socket.socket, int]:
    """A connection to the server for `argv`, started if none listens; and the lock's file
    descriptor, held shared until the server's first line arrives (then closed)."""
    lock = files.open_lock()
    try:
        fcntl.flock(lock, fcntl.LOCK_SH)
        sock = _connect(files.socket)
        if sock is None:
            fcntl.flock(lock, fcntl.LOCK_EX)
            sock = _connect(files.socket)  # another relay may have started it meanwhile
            if sock is None:
                sock = _start(argv, files)
            fcntl.flock(lock, fcntl.LOCK_SH)
    except BaseException:
        os.close(lock)
        raise
    return sock, lock


def relay_calls(argv: list[str]) -> int:
    """Be the process the client started: relay its stdio to the lingering server.

    Args:
        argv: the command line (without the program name), `--linger` included.

    Returns:
        The exit status: 0, or the server's when it could not start.
    """
    stamp = source_stamp()
    relay = StdioRelay(PreparedAnswers(answers_path(), stamp))  # answers the handshake now
    try:
        files = ServerFiles(runtime_dir(), server_key(argv, stamp))
        sock, lock = connect_or_start(argv, files)
    except LingerError as exc:
        relay.close()
        print(f"glmap-mcp: error: {exc}", file=sys.stderr)
        return exc.status
    relay.forward(sock, lambda: os.close(lock))
    return 0


# ---------------------------------------------------------------------- the server's side
class _SocketLines:
    """The lines a connection brings, as the SDK's stdio transport reads them."""

    def __init__(self, conn: Any) -> None:
        self.conn = conn

    def __aiter__(self) -> Any:
        return self._lines()

    async def _lines(self) -> Any:
        import anyio

        parts: list[bytes] = []
        while True:
            try:
                chunk = await self.conn.receive(1 << 16)
            except (anyio.EndOfStream, anyio.BrokenResourceError, anyio.ClosedResourceError):
                break
            while chunk:
                cut = chunk.find(b"\n")
                if cut < 0:
                    parts.append(chunk)
                    break
                parts.append(chunk[: cut + 1])
                yield b"".join(parts).decode("utf-8", errors="replace")
                parts, chunk = [], chunk[cut + 1 :]
        if b"".join(parts).strip():
            yield b"".join(parts).decode("utf-8", errors="replace")


class _SocketWriter:
    def __init__(self, conn: Any) -> None:
        self.conn = conn

    async def write(self, text: str) -> None:
        await self.conn.send(text.encode())

    async def flush(self) -> None:
        return None


class _Idle:
    """Open connections and how long none has been open."""

    def __init__(self) -> None:
        self.open = 0
        self.since = time.monotonic()

    def opened(self) -> None:
        self.open += 1

    def closed(self) -> None:
        self.open -= 1
        self.since = time.monotonic()

    def idle_for(self) -> float:
        return 0.0 if self.open else time.monotonic() - self.since


def serve_socket(server: Any, path: Path, linger_s: float) -> None:
    """Serve `server` (an MCPServer) to every connection on the Unix socket `path`, one MCP
    session each, sharing one lifespan (the map, the episode), until no connection has been
    open for `linger_s` seconds; then remove the socket and return."""
    import anyio
    from mcp.server.runner import serve_dual_era_loop
    from mcp.server.stdio import stdio_server

    lowlevel = server._lowlevel_server
    files = ServerFiles(path.parent, path.name.removesuffix(".sock"))
    idle = _Idle()

    async def leave_when_idle() -> int:
        """Wait until idle with the lock taken exclusively; its file descriptor."""
        lock = files.open_lock()
        while True:
            await anyio.sleep(min(1.0, max(linger_s / 4, POLL_S)))
            if idle.idle_for() < linger_s:
                continue
            try:
                fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:  # a relay is connecting
                continue
            if idle.open == 0:
                return lock
            fcntl.flock(lock, fcntl.LOCK_UN)

    async def run() -> None:
        async with lowlevel.lifespan(lowlevel) as state:
            options = lowlevel.create_initialization_options()

            async def session(conn: Any) -> None:
                idle.opened()
                try:
                    async with (
                        conn,
                        stdio_server(stdin=_SocketLines(conn), stdout=_SocketWriter(conn)) as (  # type: ignore[arg-type]
                            read,
                            write,
                        ),
                    ):
                        await serve_dual_era_loop(
                            lowlevel, read, write, lifespan_state=state, init_options=options
                        )
                except (anyio.BrokenResourceError, anyio.ClosedResourceError, OSError):
                    pass  # the relay went away mid-answer
                except Exception:  # one client's broken session must not end the others'
                    logger.exception("glmap-mcp: a lingering server's session failed")
                finally:
                    idle.closed()

            with contextlib.suppress(FileNotFoundError):
                path.unlink()
            listener = await anyio.create_unix_listener(path)
            async with anyio.create_task_group() as tasks:
                tasks.start_soon(listener.serve, session)
                await leave_when_idle()
                tasks.cancel_scope.cancel()  # no session is open: only the accept loop ends
            await listener.aclose()
            with contextlib.suppress(FileNotFoundError):
                path.unlink()

    def stop(signum: int, _frame: Any) -> None:  # `kill`: leave at once, without the socket
        with contextlib.suppress(OSError):
            path.unlink()
        os._exit(128 + signum)

    signal.signal(signal.SIGTERM, stop)
    anyio.run(run)


def lingering_servers(marker: str = "") -> list[int]:
    """The pids of this user's lingering servers whose command line holds `marker` (Linux)."""
    pids = []
    proc = Path("/proc")
    for entry in proc.iterdir() if proc.is_dir() else ():
        if not entry.name.isdigit():
            continue
        try:
            if entry.stat().st_uid != os.getuid():
                continue
            argv = (entry / "cmdline").read_bytes().split(b"\0")
        except OSError:
            continue
        if SERVE_FLAG.encode() in argv and any(marker.encode() in a for a in argv):
            pids.append(int(entry.name))
    return pids
