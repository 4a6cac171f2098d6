"""`glmap-mcp --map NAME --linger SECONDS`: the processes a client starts per call relay to one
server that keeps running in the background.

Real processes over stdio with the SDK's own client, compared with one long-lived in-memory
server given the same calls; the relay's imports; the server's exit when idle; refusals.
"""

from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import anyio
import pytest
from mcp import Client, ClientSession
from mcp.client.stdio import StdioServerParameters, stdio_client

from glmap_tools.server import build_server
from glmap_tools.server.cli import main
from glmap_tools.server.linger import SERVE_FLAG, lingering_servers
from tests.test_server_fixtures import config
from tests.test_server_persist import RESET, answer, calls_answered, process

pytestmark = pytest.mark.anyio


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"


@pytest.fixture
def run_dir() -> Iterator[Path]:
    """A short XDG_RUNTIME_DIR (a socket path holds ~100 bytes); its servers are stopped after."""
    folder = Path(tempfile.mkdtemp(prefix="glr"))
    yield folder
    for pid in lingering_servers(str(folder)):
        os.kill(pid, signal.SIGTERM)
    shutil.rmtree(folder, ignore_errors=True)


def relay(maps: Path, run: Path, *extra: str) -> StdioServerParameters:
    """`glmap-mcp --map ep --linger 30` as a client that starts one per call would launch it."""
    params = process(maps, "--linger", "30", *extra)
    params.env = {**(params.env or {}), "XDG_RUNTIME_DIR": str(run)}
    return params


async def test_per_call_relays_continue_the_episode_one_long_lived_server_would(tmp_path, run_dir):
    long_lived = build_server(config(tmp_path / "one"))
    maps = tmp_path / "maps"
    expected, got = await calls_answered(long_lived, lambda: relay(maps, run_dir))
    assert got == expected
    assert got[-1]["steps"] == 6 and got[3]["summary"]["frames"] == 5
    assert len(lingering_servers(str(run_dir))) == 1  # every call after the first found it
    assert (maps / "ep.glmap").exists()  # each frame is committed to the map, as without it
    assert await imported_by_a_later_call(maps, run_dir, tmp_path / "imports.txt") & HEAVY == set()


HEAVY = {"numpy", "mcp", "anyio", "pydantic", "numba", "scipy"}


async def imported_by_a_later_call(maps: Path, run_dir: Path, log: Path) -> set[str]:
    """The modules a relay process imports for one `sim_step` (PYTHONPROFILEIMPORTTIME)."""
    params = relay(maps, run_dir)
    params.env = {**(params.env or {}), "PYTHONPROFILEIMPORTTIME": "1"}
    with open(log, "w") as errlog:
        async with (
            stdio_client(params, errlog=errlog) as (read, write),
            ClientSession(read, write) as session,
        ):
            await session.initialize()
            answer(await session.call_tool("sim_step", {"action": "turn_left"}))
    imported = {
        line.split("|")[-1].strip()
        for line in log.read_text().splitlines()
        if line.startswith("import time:")
    }
    assert "glmap_tools.server.linger" in imported  # the relay's own imports were logged
    return imported


async def test_a_relay_killed_while_its_server_starts_leaves_the_next_call_that_server(
    tmp_path, run_dir
):
    # LangChain's get_tools() kills the process it started once it has the tool list, which the
    # relay answers from the prepared answers: its server may still be importing then.
    params = relay(tmp_path / "maps", run_dir)
    first = subprocess.Popen(
        [params.command, *params.args],
        env=params.env,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
    )
    deadline = time.monotonic() + 30
    while not lingering_servers(str(run_dir)) and time.monotonic() < deadline:
        time.sleep(0.01)
    first.kill()
    first.wait()
    (starting,) = lingering_servers(str(run_dir))
    assert list((run_dir / "glmap").glob("*.sock")) == []  # not listening yet
    async with Client(relay(tmp_path / "maps", run_dir)) as client:
        answer(await client.call_tool("map_summary", {"include_image": False}))
    assert lingering_servers(str(run_dir)) == [starting]  # the next call waited for it


async def test_calls_at_once_start_one_server_take_turns_and_other_settings_get_their_own(
    tmp_path, run_dir
):
    maps = tmp_path / "maps"
    got: list[Any] = []

    async def call(tool: str, args: dict[str, Any], *extra: str) -> None:
        async with Client(relay(maps, run_dir, *extra)) as client:
            got.append(answer(await client.call_tool(tool, args)))

    async with anyio.create_task_group() as group:  # no server yet: both start one?
        group.start_soon(call, "map_summary", {"include_image": False})
        group.start_soon(call, "map_summary", {"include_image": False})
    assert len(got) == 2 and len(lingering_servers(str(run_dir))) == 1
    await call("sim_reset", RESET)
    got.clear()
    async with anyio.create_task_group() as group:  # one episode, two steps at once
        group.start_soon(call, "sim_step", {"action": "turn_left", "repeat": 2})
        group.start_soon(call, "sim_step", {"action": "turn_left", "repeat": 2})
    assert sorted(step["steps"] for step in got) == [2, 4]  # one after the other
    await call("map_summary", {"include_image": False}, "--map-wait", "5")
    servers = sorted(lingering_servers(str(run_dir)))
    assert len(servers) == 2
    for path in (run_dir / "glmap").glob("*.sock"):  # a client that sends garbage and leaves
        with socket.socket(socket.AF_UNIX) as raw:
            raw.connect(str(path))
            raw.sendall(b'\xff\xfe not json\n{"jsonrpc": "2.0", "id": 1}\n[1, 2\n')
    await call("map_summary", {"include_image": False})
    assert sorted(lingering_servers(str(run_dir))) == servers  # both serve on


async def test_a_map_made_with_other_settings_is_refused_with_the_servers_message(
    tmp_path, run_dir
):
    maps = tmp_path / "maps"
    params = relay(maps, run_dir)
    async with Client(params) as client:  # makes the map, voxel 0.04
        answer(await client.call_tool("map_summary", {"include_image": False}))
    (pid,) = lingering_servers(str(run_dir))
    os.kill(pid, signal.SIGTERM)  # as `kill` would: it leaves at once and takes its socket
    deadline = time.monotonic() + 10
    while lingering_servers(str(run_dir)) and time.monotonic() < deadline:
        await anyio.sleep(0.05)
    assert list((run_dir / "glmap").glob("*.sock")) == []
    before = (maps / "ep.glmap").read_bytes()
    args = [a if a != "0.04" else "0.05" for a in params.args]
    refused = subprocess.run(
        [params.command, *args], input=b"", env=params.env, capture_output=True
    )
    assert refused.returncode == 2
    said = refused.stderr.decode()
    assert "--map 'ep'" in said and "voxel" in said, said
    assert (maps / "ep.glmap").read_bytes() == before
    assert lingering_servers(str(run_dir)) == []


@pytest.mark.parametrize(
    ("argv", "said"),
    [
        (["--linger", "30"], "--linger needs --map NAME"),
        (["--map", "ep", "--linger", "0"], "in (0, 86400]"),
        (["--map", "ep", "--linger", "inf"], "in (0, 86400]"),  # would never idle out
        (["--map", "ep", "--linger", "30", "--transport", "streamable-http"], "for stdio"),
        (["--map", "ep", SERVE_FLAG, "/tmp/x.sock"], "use --linger"),
    ],
)
def test_linger_asks_for_a_map_stdio_and_seconds(argv, said, capsys, tmp_path):
    assert main([*argv, "--maps-dir", str(tmp_path)]) == 2
    assert said in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


async def test_a_server_leaves_when_idle_one_that_died_is_replaced_and_the_map_keeps_the_episode(
    tmp_path, run_dir
):
    maps = tmp_path / "maps"
    async with Client(relay(maps, run_dir, "--linger", "1")) as client:
        answer(await client.call_tool("sim_reset", RESET))
        answer(await client.call_tool("sim_step", {"action": "turn_left"}))
    deadline = time.monotonic() + 30
    while lingering_servers(str(run_dir)) and time.monotonic() < deadline:
        await anyio.sleep(0.1)
    assert lingering_servers(str(run_dir)) == []  # idle for its second: it left
    assert list((run_dir / "glmap").glob("*.sock")) == []  # and removed its socket
    async with Client(relay(maps, run_dir)) as client:  # a new server reads the file
        assert answer(await client.call_tool("sim_step", {"action": "turn_left"}))["steps"] == 2
    # A server killed outright leaves its socket behind: the next call starts another.
    ep = set(lingering_servers(str(run_dir)))
    summary = {"include_image": False}
    async with Client(relay(maps, run_dir, "--map", "other")) as client:
        assert not (await client.call_tool("map_summary", summary)).is_error
    (dead,) = set(lingering_servers(str(run_dir))) - ep
    os.kill(dead, signal.SIGKILL)
    deadline = time.monotonic() + 10
    while dead in lingering_servers(str(run_dir)) and time.monotonic() < deadline:
        await anyio.sleep(0.05)
    assert len(list((run_dir / "glmap").glob("*.sock"))) == 2  # ep's, and the dead one's
    async with Client(relay(maps, run_dir, "--map", "other")) as client:
        assert not (await client.call_tool("map_summary", summary)).is_error
    (alive,) = set(lingering_servers(str(run_dir))) - ep
    assert alive != dead
