"""The HTTP listener's defences: a connection cap, request deadlines, no Nagle, quiet logs.

uvicorn alone accepts any number of connections and waits forever for a request's headers
and body, so half-sent requests (even without a token) used to exhaust the process's file
descriptors while authorised calls timed out, and its per-request warnings filled the log.
Here each connection is an `h11` protocol that

- sets TCP_NODELAY (the listening socket is also created as IPPROTO_TCP, so asyncio sets
  it too): replies on a reused connection no longer wait ~40 ms for Nagle's algorithm;
- must deliver a whole request (headers and body) within `request_timeout` seconds of its
  first byte, or is closed;
- counts against `max_connections`: a new connection over the cap closes the oldest one
  still sending its request (never one whose request has arrived and is being answered), so
  an attacker's half-sent requests cannot lock out a client that sends whole requests;
- may send a request line and headers of at most MAX_HEADER_BYTES (16 KiB), else gets 431
  and is closed: every head counts, on a new connection and on a kept-alive one whose
  previous reply is still being made (that reply is sent first).

`RepeatFilter` lets the same log message through a few times a minute and then counts it;
`DisconnectFilter` drops the SDK's traceback of a client gone before its request arrived
(the deadline's own line says so).
"""

from __future__ import annotations

import logging
import socket
import stat
import time
from pathlib import Path
from typing import Any

import h11
from uvicorn.protocols.http.h11_impl import H11Protocol

from glmap_tools.app.config import MAX_CONNECTIONS, REQUEST_TIMEOUT_S

# Imports inside functions stay there: starlette load on first use.

LISTEN_BACKLOG = 128
MAX_HEADER_BYTES = 16 * 1024  # request line and headers; h11's own limit for a head in pieces


def listening_socket(host: str, port: int) -> socket.socket:
    """A bound, listening TCP socket (IPPROTO_TCP, so asyncio sets TCP_NODELAY on accepts)."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM, socket.IPPROTO_TCP)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    sock.bind((host, port))
    sock.listen(LISTEN_BACKLOG)
    return sock


def token_file_warning(path: Path) -> str | None:
    """A warning when the token file at `path` can be read by its group or by others.

    glmap-mcp's `--token-file` reading (server/cli.py `read_token`) prints it on stderr.
    """
    try:
        mode = path.stat().st_mode
    except OSError:
        return None  # the read itself reports what is wrong
    if mode & (stat.S_IRWXG | stat.S_IRWXO):
        return (
            f"glmap-mcp: warning: --token-file {path.name!r} can be read by other users "
            f"(mode {stat.S_IMODE(mode):04o}); run `chmod 600 {path.name}`."
        )
    return None


class GuardedH11Protocol(H11Protocol):
    """uvicorn's h11 protocol with TCP_NODELAY, a request deadline and a connection cap."""

    request_timeout: float = REQUEST_TIMEOUT_S
    max_connections: int = MAX_CONNECTIONS
    max_header_bytes: int = MAX_HEADER_BYTES
    closed_slow = 0  # connections closed for a late request, process-wide (for tests and logs)
    closed_header = 0  # requests refused for an overlong head
    closed_over_cap = 0

    def connection_made(self, transport: Any) -> None:  # type: ignore[override]
        sock = transport.get_extra_info("socket")
        if sock is not None and sock.family in (socket.AF_INET, socket.AF_INET6):
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        super().connection_made(transport)
        self.opened = time.monotonic()
        self._deadline: Any = None
        self._head_bytes = 0  # bytes of the current request's head received so far
        self._tail = b""  # the last bytes received, to find a head's end across reads
        self._refused = False  # an overlong head arrived while a reply was being made
        self._arm()
        if len(self.connections) > self.max_connections:
            self._close_one_receiving()

    def _head_too_long(self, data: bytes) -> bool:
        """Whether this request's line and headers, with `data`, pass MAX_HEADER_BYTES.

        Counted on every read that carries a head: on an idle connection, and on a kept-alive
        one whose previous reply is still being made (h11 then only buffers the bytes, and
        parses the whole head at once when the reply is done). h11 limits only a head it
        parses in pieces; one sent whole (200 KB in one write, issue 27 item 6) or behind a
        pending reply (issue 41 item 5) was accepted.
        """
        end = (self._tail + data).find(b"\r\n\r\n")
        size = self._head_bytes + (len(data) if end < 0 else max(0, end - len(self._tail)))
        self._tail = data[-3:]
        if size <= self.max_header_bytes:
            self._head_bytes = size if end < 0 else 0
            return False
        return True

    def _refuse_head(self) -> None:
        """Answer 431 and close."""
        type(self).closed_header += 1
        body = f"request line and headers over {self.max_header_bytes} bytes\n".encode()
        self.transport.write(
            b"HTTP/1.1 431 Request Header Fields Too Large\r\ncontent-type: text/plain\r\n"
            + f"content-length: {len(body)}\r\nconnection: close\r\n\r\n".encode()
            + body
        )
        self.transport.close()

    def _receiving(self) -> bool:
        """Still sending its request: its headers, or a body the app is waiting for."""
        return self.conn.their_state in (h11.IDLE, h11.SEND_BODY)

    def _close_one_receiving(self) -> None:
        """Make room: close the oldest connection that has not delivered its request."""
        waiting = [c for c in self.connections if isinstance(c, GuardedH11Protocol)]
        waiting = [c for c in waiting if c._receiving() and not c.transport.is_closing()]
        if waiting:
            oldest = min(waiting, key=lambda c: c.opened)
            type(self).closed_over_cap += 1
            oldest.logger.warning("HTTP connection cap reached: closed a half-sent request.")
            oldest.transport.close()

    def _arm(self) -> None:
        if self._deadline is None:
            self._deadline = self.loop.call_later(self.request_timeout, self._too_slow)

    def _disarm(self) -> None:
        if self._deadline is not None:
            self._deadline.cancel()
            self._deadline = None

    def _too_slow(self) -> None:
        self._deadline = None
        if self._receiving() and not self.transport.is_closing():
            type(self).closed_slow += 1
            self.logger.warning(
                "HTTP request not received within %.0f s: connection closed.", self.request_timeout
            )
            self.transport.close()

    def data_received(self, data: bytes) -> None:
        self._arm()  # a request starts (or goes on): it has request_timeout to finish
        if self._refused:
            return  # an overlong head behind a pending reply: 431 once the reply is sent
        before = self.conn.their_state
        if before in (h11.IDLE, h11.DONE) and self._head_too_long(data):
            if before is h11.IDLE:
                self._refuse_head()
            else:  # the previous request is still being answered: answer it first
                self._refused = True
            return
        super().data_received(data)
        if before is h11.IDLE and self.conn.their_state is not h11.IDLE:
            self._head_bytes, self._tail = 0, b""  # the head is parsed; the next counts anew
        if not self._receiving():
            self._disarm()

    def on_response_complete(self) -> None:
        super().on_response_complete()
        if self._refused and not self.transport.is_closing():
            self._refuse_head()
            return
        if self._receiving() and self.conn.their_state is h11.SEND_BODY:
            self._arm()

    def connection_lost(self, exc: Exception | None) -> None:
        self._disarm()
        super().connection_lost(exc)


def guarded_protocol(request_timeout: float, max_connections: int) -> type[GuardedH11Protocol]:
    """The protocol class with these limits (uvicorn's `http=` takes a class)."""
    return type(
        "GuardedH11Protocol",
        (GuardedH11Protocol,),
        {"request_timeout": float(request_timeout), "max_connections": int(max_connections)},
    )


class RepeatFilter(logging.Filter):
    """Let a message through `burst` times per `window` seconds, then count the repeats.

    The first message after a quiet window says how many were left out.
    """

    def __init__(self, burst: int = 5, window: float = 60.0) -> None:
        super().__init__()
        self.burst = burst
        self.window = window
        self._seen: dict[str, list[float]] = {}  # message -> [window start, count]

    def filter(self, record: logging.LogRecord) -> bool:
        key = f"{record.name}:{record.msg}"
        now = time.monotonic()
        entry = self._seen.get(key)
        if entry is None or now - entry[0] > self.window:
            dropped = int(entry[1]) - self.burst if entry is not None else 0
            self._seen[key] = [now, 1]
            if dropped > 0:
                record.msg = f"{record.msg} (and {dropped} more like it in the last minute)"
            if len(self._seen) > 1024:  # many distinct messages: forget the old windows
                self._seen = {k: v for k, v in self._seen.items() if now - v[0] <= self.window}
            return True
        entry[1] += 1
        return entry[1] <= self.burst


def quiet_repeats(names: tuple[str, ...] = ("uvicorn.error", "uvicorn.access")) -> RepeatFilter:
    """Install one RepeatFilter on uvicorn's loggers (and their handlers' records), and a
    DisconnectFilter (`quiet_disconnects`)."""
    quiet_disconnects()
    repeat = RepeatFilter()
    for name in names:
        logging.getLogger(name).addFilter(repeat)
    return repeat


DISCONNECT_LOGGERS = (
    "mcp.server.streamable_http",
    "mcp.server._streamable_http_modern",
    "mcp.server.streamable_http_manager",
    "uvicorn.error",
)


def _is_disconnect(exc: BaseException | None) -> bool:
    """`exc` is starlette's ClientDisconnect (alone, in a group, or as the cause)."""
    from starlette.requests import ClientDisconnect

    seen = 0
    while exc is not None and seen < 8:
        if isinstance(exc, ClientDisconnect):
            return True
        if isinstance(exc, BaseExceptionGroup):
            return all(_is_disconnect(e) for e in exc.exceptions)
        exc, seen = exc.__cause__ or exc.__context__, seen + 1
    return False


class DisconnectFilter(logging.Filter):
    """Drop the record of a request whose client went before its body arrived.

    The request deadline closes such a connection and says so in one line
    (`GuardedH11Protocol._too_slow`); the MCP SDK then logged the same event again as
    "Error handling POST request" with a ClientDisconnect traceback (issue 41 item 6).
    A client that hangs up mid-request is no server error either.

    Attributes:
        dropped: records dropped so far.
    """

    def __init__(self) -> None:
        super().__init__()
        self.dropped = 0

    def filter(self, record: logging.LogRecord) -> bool:
        if record.exc_info and _is_disconnect(record.exc_info[1]):
            self.dropped += 1
            return False
        return True

    def remove(self) -> None:
        """Take this filter off the loggers `quiet_disconnects` put it on."""
        for name in DISCONNECT_LOGGERS:
            logging.getLogger(name).removeFilter(self)


def quiet_disconnects() -> DisconnectFilter:
    """Install one DisconnectFilter on the loggers that report a client's disconnect."""
    quiet = DisconnectFilter()
    for name in DISCONNECT_LOGGERS:
        logging.getLogger(name).addFilter(quiet)
    return quiet
