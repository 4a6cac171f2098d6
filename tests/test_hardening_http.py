"""A stateful HTTP session that ends lets go of what the server kept for it (issue 41 item 4),
served by uvicorn in this process on 127.0.0.1 and reached by a real MCP client."""

from __future__ import annotations

import asyncio
import logging
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from typing import Any

import anyio
import httpx2
import pytest
import uvicorn
from mcp import Client
from mcp.client.streamable_http import streamable_http_client

from glmap_tools.app.frames import observe_arguments
from glmap_tools.server import build_server
from glmap_tools.server.build import GLMapServer
from glmap_tools.server.http import listening_socket
from tests.test_server_fixtures import config, view

pytestmark = pytest.mark.anyio
SETTLE_S = 20.0  # the most the server may take to act on an ended session


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"


@asynccontextmanager
async def served(server: GLMapServer) -> AsyncIterator[str]:
    """`server`'s streamable HTTP app on an ephemeral 127.0.0.1 port; yields its URL."""
    app = server.streamable_http_app(host="127.0.0.1")
    sock = listening_socket("127.0.0.1", 0)
    uv = uvicorn.Server(uvicorn.Config(app, log_config=None, lifespan="on"))
    async with anyio.create_task_group() as tasks:
        tasks.start_soon(lambda: uv.serve(sockets=[sock]))
        with anyio.fail_after(SETTLE_S):
            while not uv.started:
                await anyio.sleep(0.01)
        try:
            yield f"http://127.0.0.1:{sock.getsockname()[1]}/mcp"
        finally:
            uv.should_exit = True


def client(url: str) -> Client:
    http = httpx2.AsyncClient(timeout=httpx2.Timeout(60.0))
    return Client(streamable_http_client(url, http_client=http), mode="legacy")


def unannotated() -> dict[str, Any]:
    frame, _ = view((0.0, -2.6, 1.4), 320, 240)
    return observe_arguments(frame)


async def until(condition: Any) -> None:
    """Wait (at most SETTLE_S) for `condition()`: the server acts on a DELETE after it answers."""
    with anyio.fail_after(SETTLE_S):
        while not condition():
            await anyio.sleep(0.02)


async def test_an_ended_http_session_lets_go_of_its_pending_frames_and_its_map(tmp_path):
    server = build_server(config(tmp_path))
    async with served(server) as url:
        async with client(url) as first:
            result = await first.call_tool("observe_frame", unannotated())
            assert not result.is_error, result.content[0].text
            assert result.structured_content["pending"] is not None
            handle = result.structured_content["session"]
            state = server.state
            assert state is not None and state.pending is not None
            assert state.pending.held() > 0
        # The client's exit sent DELETE /mcp: the session and what it kept are gone.
        await until(lambda: state.pending.held() == 0)
        async with client(url) as second:
            gone = await second.call_tool("map_summary", {"session": handle})
            assert gone.is_error and handle in gone.content[0].text
            other = await second.call_tool("observe_frame", unannotated())
            assert not other.is_error, other.content[0].text
            assert state.pending.held() > 0  # the other session's frame is still counted


class RecordingTransport(asyncio.Transport):
    """Records what the protocol writes; no socket."""

    def __init__(self) -> None:
        super().__init__()
        self.written, self.closed = b"", False

    def write(self, data: bytes) -> None:  # type: ignore[override]
        self.written += data

    def close(self) -> None:
        self.closed = True

    def is_closing(self) -> bool:
        return self.closed

    def get_extra_info(self, name: str, default: object = None) -> object:
        return {"peername": ("127.0.0.1", 50000), "sockname": ("127.0.0.1", 8000)}.get(name)

    def pause_reading(self) -> None:
        pass

    def resume_reading(self) -> None:
        pass


@pytest.mark.parametrize("pieces", [1, 8], ids=["one-read", "eight-reads"])
async def test_an_overlong_head_behind_a_pending_reply_gets_431_after_that_reply(pieces):
    # A kept-alive connection whose reply is still being made only buffered the next head,
    # and h11 parsed it whole afterwards: a 17-250 KiB head got 200 (issue 41 item 5).
    from uvicorn.server import ServerState

    from glmap_tools.server.http import MAX_HEADER_BYTES, guarded_protocol

    release = asyncio.Event()
    served: list[str] = []

    async def app(scope: dict, receive: Any, send: Any) -> None:  # type: ignore[type-arg]
        served.append(scope["path"])
        await release.wait()
        await send({"type": "http.response.start", "status": 200, "headers": []})
        await send({"type": "http.response.body", "body": b"first"})

    config = uvicorn.Config(app, log_level="warning")
    config.load()
    protocol = guarded_protocol(30.0, 8)(
        config=config, server_state=ServerState(), app_state={}, _loop=asyncio.get_running_loop()
    )
    transport = RecordingTransport()
    protocol.connection_made(transport)
    protocol.data_received(b"GET /first HTTP/1.1\r\nHost: x\r\n\r\n")
    head = b"GET /second HTTP/1.1\r\nHost: x\r\nX-Big: " + b"a" * 20_000 + b"\r\n\r\n"
    assert len(head) > MAX_HEADER_BYTES
    step = -(-len(head) // pieces)
    for i in range(0, len(head), step):
        protocol.data_received(head[i : i + step])  # while /first is still being answered
    release.set()
    with anyio.fail_after(SETTLE_S):
        while not transport.closed:
            await anyio.sleep(0.01)
    protocol.connection_lost(None)
    assert transport.written.startswith(b"HTTP/1.1 200"), transport.written[:80]
    assert b"first" in transport.written  # the pending reply was sent whole, first
    assert b"HTTP/1.1 431" in transport.written
    assert served == ["/first"]  # the overlong request never reached the app


@pytest.mark.parametrize("stateless", [False, True], ids=["stateful", "stateless"])
async def test_a_body_cut_off_by_the_request_deadline_logs_one_line_and_no_traceback(
    tmp_path, caplog, stateless
):
    # The deadline's close reached the SDK as a ClientDisconnect, logged with its traceback.
    from glmap_tools.server.http import guarded_protocol, quiet_disconnects

    server = build_server(config(tmp_path))
    app = server.streamable_http_app(host="127.0.0.1", stateless_http=stateless)
    sock = listening_socket("127.0.0.1", 0)
    protocol = guarded_protocol(1.0, 8)
    uv = uvicorn.Server(uvicorn.Config(app, log_config=None, lifespan="on", http=protocol))
    quiet = quiet_disconnects()
    try:
        with caplog.at_level(logging.INFO):
            async with anyio.create_task_group() as tasks:
                tasks.start_soon(lambda: uv.serve(sockets=[sock]))
                await until(lambda: uv.started)
                port = sock.getsockname()[1]
                stream = await anyio.connect_tcp("127.0.0.1", port)
                await stream.send(
                    f"POST /mcp HTTP/1.1\r\nHost: 127.0.0.1:{port}".encode()
                    + b"\r\nContent-Type: application/json"
                    + b"\r\nAccept: application/json, text/event-stream"
                    + b"\r\nContent-Length: 5000\r\n\r\n{\"jsonrpc\": "
                )  # fmt: skip
                await until(lambda: protocol.closed_slow > 0)
                await until(lambda: quiet.dropped > 0)  # the SDK reported the disconnect
                await stream.aclose()
                uv.should_exit = True
    finally:
        quiet.remove()
    tracebacks = [r for r in caplog.records if r.exc_info is not None]
    assert tracebacks == [], [r.getMessage() for r in tracebacks]
    said = [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
    assert len([m for m in said if "not received within 1 s" in m]) == 1, said
