"""A stateful HTTP session that ends lets go of what the server kept for it (issue 41 item 4),
served by uvicorn in this process on 127.0.0.1 and reached by a real MCP client."""

from __future__ import annotations

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
    uv = uvicorn.Server(uvicorn.Config(app, log_level="warning", lifespan="on"))
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
