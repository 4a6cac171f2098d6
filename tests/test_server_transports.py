"""The console entry over stdio (a spawned process) and streamable HTTP on 127.0.0.1.

Everything is bounded: processes are polled for readiness with a timeout, never slept on.
"""

from __future__ import annotations

import contextlib
import json
import queue
import shutil
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import anyio
import httpx2
import pytest
from mcp import Client
from mcp.client.stdio import StdioServerParameters
from mcp.client.streamable_http import streamable_http_client

from glmap_tools.server import cli
from tests.test_server_fixtures import frame_args

pytestmark = pytest.mark.anyio
REPO = Path(__file__).resolve().parents[1]
TOKEN = "test-token-4f1c"
STARTUP_TIMEOUT = 90.0


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"


def server_command() -> list[str]:
    """`glmap-mcp` when installed as a console script, else the module entry."""
    script = shutil.which("glmap-mcp", path=str(Path(sys.executable).parent))
    return [script] if script else [sys.executable, "-m", "glmap_tools.server"]


FAST = ["--embedder", "hashing", "--no-warm-up", "--voxel-size", "0.04"]


async def test_glmap_mcp_over_stdio_serves_a_real_client_session(tmp_path):
    command = server_command()
    params = StdioServerParameters(
        command=command[0],
        args=[*command[1:], *FAST, "--maps-dir", str(tmp_path / "maps")],
        cwd=str(REPO),
    )
    with anyio.fail_after(STARTUP_TIMEOUT):
        async with Client(params) as client:
            tools = {t.name for t in (await client.list_tools()).tools}
            observed = await client.call_tool("observe_frame", frame_args())
            hits = await client.call_tool("find_instance", {"query": "blue office chair"})
            bad = await client.call_tool("load_map", {"name": "../../etc/passwd"})
    assert {"observe_frame", "find_instance", "render_view", "sim_step", "map_summary"} <= tools
    assert not observed.is_error, observed.content[0].text
    assert hits.structured_content["hits"][0]["description"] == "a blue office chair"
    assert bad.is_error and "contains a path" in bad.content[0].text


@pytest.fixture
def http_server(tmp_path: Path) -> Iterator[str]:
    """A glmap-mcp process on 127.0.0.1 with a bearer token; yields its URL."""
    with serving(tmp_path) as url:
        yield url


@pytest.fixture
def pinned_http_server(tmp_path: Path) -> Iterator[str]:
    """The same with --map shared: the saved map every connection works on."""
    with serving(tmp_path, "--map", "shared") as url:
        yield url


@contextlib.contextmanager
def serving(tmp_path: Path, *extra: str) -> Iterator[str]:
    command = [
        *server_command(),
        "--transport",
        "streamable-http",
        "--port",
        "0",
        "--token",
        TOKEN,
        "--max-frame-mb",
        "1",
        "--maps-dir",
        str(tmp_path / "maps"),
        *FAST,
        *extra,
    ]
    proc = subprocess.Popen(command, cwd=REPO, stderr=subprocess.PIPE, text=True)
    lines: queue.Queue[str] = queue.Queue()

    def pump() -> None:
        assert proc.stderr is not None
        for line in proc.stderr:
            lines.put(line)
        lines.put("")

    threading.Thread(target=pump, daemon=True).start()
    try:
        seen = []
        while True:
            line = lines.get(timeout=STARTUP_TIMEOUT)
            seen.append(line)
            if not line:
                raise AssertionError("glmap-mcp exited before serving:\n" + "".join(seen))
            if line.startswith("glmap-mcp: serving "):
                break
        yield line.split()[-1]
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=20)


def connect(url: str, mode: str) -> Client:
    http = httpx2.AsyncClient(
        headers={"Authorization": f"Bearer {TOKEN}"}, timeout=httpx2.Timeout(60.0)
    )
    return Client(streamable_http_client(url, http_client=http), mode=mode)


async def instances_of(client: Client, **kw: str) -> list[str]:
    result = await client.call_tool("find_instance", {"query": "chair", "top_k": 10, **kw})
    return sorted(h["description"] for h in result.structured_content["hits"])


async def test_two_clients_at_once_over_http_each_keep_their_own_map(http_server):
    seen: dict[str, list[str]] = {}

    async def legacy_client(name: str, objects: dict[int, str]) -> None:
        args = frame_args()
        for obj in args["annotations"]["objects"]:
            obj["description"] = objects.get(obj["id"], obj["description"])
        async with connect(http_server, "legacy") as client:
            for _ in range(2):
                result = await client.call_tool("observe_frame", args)
                assert not result.is_error, result.content[0].text
            seen[name] = await instances_of(client)

    with anyio.fail_after(120):
        async with anyio.create_task_group() as tg:
            tg.start_soon(legacy_client, "a", {1: "a chair of client a"})
            tg.start_soon(legacy_client, "b", {1: "a chair of client b"})
    assert "a chair of client a" in seen["a"] and "a chair of client b" not in seen["a"]
    assert "a chair of client b" in seen["b"] and "a chair of client a" not in seen["b"]

    # Stateless (2026-07-28) clients have no session: new_map hands out a handle each.
    with anyio.fail_after(120):
        async with connect(http_server, "auto") as one, connect(http_server, "auto") as two:
            h1 = (await one.call_tool("new_map", {})).structured_content["session"]
            h2 = (await two.call_tool("new_map", {})).structured_content["session"]
            assert h1 != h2
            await one.call_tool("observe_frame", {**frame_args(), "session": h1})
            assert len(await instances_of(one, session=h1)) == 3
            assert await instances_of(two, session=h2) == []
            # Opening one saved map from both sessions shares it, consistently.
            await one.call_tool("save_map", {"name": "shared", "session": h1})
            loaded = await two.call_tool("load_map", {"name": "shared", "session": h2})
            assert loaded.structured_content["map_name"] == "shared"
            assert len(await instances_of(two, session=h2)) == 3
            await two.call_tool("observe_frame", {**frame_args((0.4, -2.5, 1.4)), "session": h2})
            summary = await one.call_tool("map_summary", {"include_image": False, "session": h1})
            assert json.loads(summary.content[0].text)["summary"]["frames"] == 2


async def test_with_map_every_http_connection_sees_the_saved_map_and_new_map_spares_it(
    pinned_http_server,
):
    with anyio.fail_after(120):
        async with connect(pinned_http_server, "legacy") as one:
            observed = await one.call_tool("observe_frame", frame_args())
            assert not observed.is_error, observed.content[0].text
        async with connect(pinned_http_server, "legacy") as two:
            seen = await instances_of(two)  # a new connection, no session argument
            fresh = await two.call_tool("new_map", {})
            handle = fresh.structured_content["session"]
            assert await instances_of(two, session=handle) == []
            assert await instances_of(two) == seen  # the saved map was not started anew
    assert len(seen) == 3 and handle != "default"


async def test_http_refuses_requests_without_the_token_and_bodies_over_the_limit(http_server):
    body = {"jsonrpc": "2.0", "id": 1, "method": "tools/list", "params": {}}
    headers = {"Accept": "application/json, text/event-stream"}
    async with httpx2.AsyncClient(timeout=httpx2.Timeout(30.0)) as http:
        unauthorised = await http.post(http_server, json=body, headers=headers)
        big = "x" * (3 * 1024 * 1024)  # over the 1 MiB frame limit's ~2.3 MiB body limit
        too_big = await http.post(
            http_server,
            content=json.dumps({**body, "pad": big}),
            headers={**headers, "Authorization": f"Bearer {TOKEN}"},
        )
    assert unauthorised.status_code == 401
    assert too_big.status_code == 413


def test_a_host_beyond_loopback_without_a_token_is_refused(capsys, monkeypatch):
    monkeypatch.delenv(cli.TOKEN_ENV, raising=False)
    code = cli.main(
        ["--transport", "streamable-http", "--host", "0.0.0.0", "--embedder", "hashing"]
    )
    assert code == 2
    assert "bearer token" in capsys.readouterr().err
