"""`glmap-mcp --map NAME`: per-call server processes share one saved map and one episode.

Real processes over stdio with the SDK's own client, compared with one long-lived
in-memory server given the same calls; plus the lock, and bad names and files.
"""

from __future__ import annotations

import dataclasses
import fcntl
import json
import os
import sqlite3
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import anyio
import pytest
from mcp import Client
from mcp.client.stdio import StdioServerParameters

from glmap_tools.server import build_server
from glmap_tools.server.cli import main
from tests.test_server_fixtures import config

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
pytestmark = pytest.mark.anyio

RESET = {"scene": 0, "seed": 3, "size": "160x120", "max_steps": 40}
# What one call per process asks, in order; the first list is one process, and so on.
CALLS: list[list[tuple[str, dict[str, Any]]]] = [
    [("sim_reset", RESET)],
    [("sim_step", {"action": "move_forward", "repeat": 3}), ("sim_step", {"action": "turn_left"})],
    [
        ("map_summary", {"include_image": False}),
        ("find_instance", {"query": "sofa"}),
        ("sim_step", {"action": "move_forward", "repeat": 2}),
    ],
]


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"


def process(maps: Path, *extra: str) -> StdioServerParameters:
    """A fresh `glmap-mcp --map ep` as a client that starts one per call would launch it."""
    return StdioServerParameters(
        command=sys.executable,
        args=[
            "-m",
            "glmap_tools.server",
            "--map",
            "ep",
            "--maps-dir",
            str(maps),
            "--embedder",
            "hashing",
            "--voxel-size",
            "0.04",
            "--no-warm-up",
            *extra,
        ],
        env={k: v for k, v in os.environ.items() if k in ("PYTHONPATH", "PYOPENGL_PLATFORM")},
    )


def answer(result: Any) -> Any:
    """The call's text (parsed if JSON), less the map's name: None in memory, 'ep' in a file."""
    assert not result.is_error, result.content[0].text
    text = result.content[0].text
    if not text.startswith("{"):
        return text
    data = json.loads(text)
    assert data.pop("map_name", "ep") in (None, "ep")
    return data


async def calls_answered(one_long_lived: Any, per_batch: Callable[[], Any]) -> tuple[list, list]:
    """The answers to CALLS from one long-lived server, and from a fresh process (or relay)
    `per_batch()` for each batch."""
    expected = []
    async with Client(one_long_lived) as client:
        for batch in CALLS:
            for name, args in batch:
                expected.append(answer(await client.call_tool(name, args)))
    got = []
    for batch in CALLS:
        async with Client(per_batch()) as client:
            for name, args in batch:
                got.append(answer(await client.call_tool(name, args)))
    return expected, got


async def test_per_call_processes_continue_the_episode_one_long_lived_server_would(tmp_path):
    long_lived = build_server(config(tmp_path / "one"))
    expected, got = await calls_answered(long_lived, lambda: process(tmp_path / "maps"))
    assert got == expected
    last = got[-1]
    assert last["steps"] == 6 and last["status"] == "running"
    assert got[3]["summary"]["frames"] == 5  # the third process sees every frame so far


async def test_two_processes_at_once_take_turns_and_lose_no_step(tmp_path):
    maps = tmp_path / "maps"
    async with Client(process(maps)) as client:
        answer(await client.call_tool("sim_reset", RESET))
    done: list[int] = []

    async def turn() -> None:
        async with Client(process(maps, "--map-wait", "120")) as client:
            got = answer(await client.call_tool("sim_step", {"action": "turn_left", "repeat": 2}))
            done.append(got["steps"])

    async with anyio.create_task_group() as group:
        group.start_soon(turn)
        group.start_soon(turn)
    assert sorted(done) == [2, 4]  # one after the other, the second continuing the first
    async with Client(process(maps)) as client:
        summary = answer(await client.call_tool("map_summary", {"include_image": False}))
        status = answer(await client.call_tool("sim_step", {"action": "turn_right"}))
    assert summary["summary"]["frames"] == 5 and status["steps"] == 5


def refused(argv: list[str], capsys: Any) -> str:
    assert main(argv) == 2
    return str(capsys.readouterr().err)


def test_a_map_name_with_a_path_is_refused_before_anything_is_written(tmp_path, capsys):
    for bad in ("../ep", "a/b", "~ep", ".."):
        err = refused(["--map", bad, "--maps-dir", str(tmp_path / "maps")], capsys)
        assert "bare name" in err and repr(bad) in err
    assert not (tmp_path / "maps").exists()


def test_a_corrupt_map_file_is_refused_and_left_as_it_is(tmp_path, capsys):
    maps = tmp_path / "maps"
    maps.mkdir()
    (maps / "ep.glmap").write_bytes(b"not a database at all" * 100)
    err = refused(["--map", "ep", "--maps-dir", str(maps), "--embedder", "hashing"], capsys)
    assert "ep.glmap is not a GLMap store" in err and "left as it is" in err
    assert (maps / "ep.glmap").read_bytes() == b"not a database at all" * 100
    other = maps / "other.glmap"
    with sqlite3.connect(other) as conn:
        conn.execute("CREATE TABLE meta (key TEXT, value TEXT)")
    err = refused(["--map", "other", "--maps-dir", str(maps), "--embedder", "hashing"], capsys)
    assert "not a GLMap store" in err


async def test_a_relative_maps_dir_opens_the_saved_map_on_every_later_launch(tmp_path, monkeypatch):
    from glmap_tools.server.cli import check_pinned_map

    monkeypatch.chdir(tmp_path)
    pinned = dataclasses.replace(config(tmp_path), maps_dir=Path("maps"), map_name="flat-3")
    assert pinned.maps_dir == tmp_path / "maps"
    for _ in range(2):  # the first launch makes the file, the second opens it
        check_pinned_map(pinned)
        async with Client(build_server(pinned)) as client:
            result = await client.call_tool("map_summary", {"include_image": False})
        assert not result.is_error, result.content[0].text
    assert (tmp_path / "maps" / "flat-3.glmap").is_file()


async def test_a_map_made_with_another_embedder_or_voxel_size_is_refused(tmp_path, capsys):
    maps = tmp_path / "maps"
    async with Client(process(maps)) as client:  # hashing embedder, 4 cm voxels
        answer(await client.call_tool("sim_reset", RESET))
    before = (maps / "ep.glmap").read_bytes()
    err = refused(["--map", "ep", "--maps-dir", str(maps), "--voxel-size", "0.04"], capsys)
    assert "--embedder hashing" in err and "--embedder minilm" in err
    err = refused(["--map", "ep", "--maps-dir", str(maps), "--embedder", "hashing"], capsys)
    assert "voxel_size=0.04" in err and "--voxel-size" in err
    assert (maps / "ep.glmap").read_bytes() == before


async def test_sim_reset_without_keep_map_starts_the_saved_map_anew(tmp_path):
    pinned = config(tmp_path, map_name="ep")  # a fresh server each time, on the saved map
    for _ in range(2):
        async with Client(build_server(pinned)) as client:
            answer(await client.call_tool("sim_reset", {**RESET, "seed": 4}))
            summary = answer(await client.call_tool("map_summary", {"include_image": False}))
            assert summary["summary"]["frames"] == 1
    async with Client(build_server(pinned)) as client:
        answer(await client.call_tool("sim_reset", {**RESET, "keep_map": True}))
        summary = answer(await client.call_tool("map_summary", {"include_image": False}))
        assert summary["summary"]["frames"] == 2


def test_the_launch_check_knows_the_store_format():
    from glmap_tools.app.persist import MAP_FORMAT
    from glmap_tools.map.store import FORMAT

    assert MAP_FORMAT == FORMAT


def kept_episode(path: Path) -> dict[str, Any]:
    """The episode record a --map file keeps (navigator memory included)."""
    with sqlite3.connect(path) as conn:
        (text,) = conn.execute("SELECT value FROM meta WHERE key = 'extra.sim_episode'").fetchone()
    return dict(json.loads(text))


async def test_a_benchmark_episode_and_the_navigator_memory_go_on_in_the_next_server(tmp_path):
    start = {"episode": "tune/objectnav/s00-000", "size": "160x120"}
    calls = [
        ("sim_reset", start),
        ("nav_step", {"actions": 2}),
        ("sim_step", {"action": "turn_left"}),
        ("nav_step", {"actions": 1, "policy": "egocentric"}),
    ]
    expected = []
    async with Client(build_server(config(tmp_path / "one", map_name="ep"))) as client:
        for name, args in calls:
            expected.append(answer(await client.call_tool(name, args)))
    got = []
    for name, args in calls:  # in memory, a fresh server per call on the same saved map
        async with Client(build_server(config(tmp_path, map_name="ep"))) as client:
            got.append(answer(await client.call_tool(name, args)))
    assert got == expected
    assert got[-1]["episode"] == "tune/objectnav/s00-000" and got[-1]["steps"] == 4
    kept = kept_episode(tmp_path / "maps" / "ep.glmap")
    assert kept == kept_episode(tmp_path / "one" / "maps" / "ep.glmap")
    assert kept["actions"] and kept["nav"]["steps"] >= 3 and kept["nav"]["last_waypoint"]


async def test_a_server_waits_for_another_process_holding_the_map_then_says_it_is_busy(tmp_path):
    # A server on a --map map (built in process here) respects another process's lock.
    maps = tmp_path / "maps"
    async with Client(build_server(config(tmp_path, map_name="ep"))) as client:
        answer(await client.call_tool("sim_reset", RESET))
    before = (maps / "ep.glmap").read_bytes()
    fd = os.open(maps / ".ep.glmap.lock", os.O_RDWR)
    fcntl.flock(fd, fcntl.LOCK_EX)  # another process in a long call
    try:
        async with Client(build_server(config(tmp_path, map_name="ep", map_wait_s=0.3))) as c:
            busy = await c.call_tool("sim_step", {"action": "turn_left"})
    finally:
        os.close(fd)
    assert busy.is_error
    text = busy.content[0].text
    assert "'ep' is in use" in text and "--map-wait" in text
    assert (maps / "ep.glmap").read_bytes() == before
    async with Client(build_server(config(tmp_path, map_name="ep"))) as client:  # free again
        assert answer(await client.call_tool("sim_step", {"action": "turn_left"}))["steps"] == 1


def test_the_navigator_memory_survives_its_json_form():
    from glmap_tools.app.episode_record import apply_memory, nav_memory
    from glmap_tools.nav import NavState
    from glmap_tools.nav.choose import GoalProgress
    from glmap_tools.nav.waypoint import Waypoint

    state = NavState(
        avoid=[(1.0, 2.5)],
        rejected_units={4, 9},
        blocked={(3, -2), (0, 7)},
        last_waypoint=Waypoint((0.5, -1.25), "frontier", None, 0.3, "the nearest frontier"),
        last_action="turn_left",
        last_xy=(0.1, 0.2),
        last_heading=1.5,
        since_progress=3,
        steps=7,
        goal_progress=GoalProgress(5, 0.73, 11),
    )
    again = NavState()
    apply_memory(again, json.loads(json.dumps(nav_memory(state))))
    assert again == state
    apply_memory(again, json.loads(json.dumps(nav_memory(NavState()))))
    assert again == NavState() and again.best_distance == float("inf")
    assert again.goal_progress.best_distance == float("inf")


async def test_a_map_file_spoilt_after_launch_fails_the_call_and_is_left_as_it_is(tmp_path):
    (tmp_path / "maps").mkdir()
    spoilt = tmp_path / "maps" / "ep.glmap"
    spoilt.write_bytes(b"SQLite format 3\x00" + b"\xff" * 2000)
    async with Client(build_server(config(tmp_path, map_name="ep"))) as client:
        result = await client.call_tool("map_summary", {"include_image": False})
    assert result.is_error and "ep.glmap is not a GLMap store" in result.content[0].text
    assert spoilt.read_bytes() == b"SQLite format 3\x00" + b"\xff" * 2000


async def test_an_unreadable_episode_record_leaves_the_map_usable_and_asks_for_sim_reset(tmp_path):
    async with Client(build_server(config(tmp_path, map_name="ep"))) as client:
        answer(await client.call_tool("sim_reset", RESET))
    with sqlite3.connect(tmp_path / "maps" / "ep.glmap") as conn:
        conn.execute("UPDATE meta SET value = '{\"format\": 3' WHERE key = 'extra.sim_episode'")
    async with Client(build_server(config(tmp_path, map_name="ep"))) as client:
        step = await client.call_tool("sim_step", {"action": "turn_left"})
        assert step.is_error and "call sim_reset" in step.content[0].text
        summary = answer(await client.call_tool("map_summary", {"include_image": False}))
        assert summary["summary"]["frames"] == 1
        assert answer(await client.call_tool("sim_reset", RESET))["steps"] == 0


def test_a_map_another_process_wrote_to_refuses_a_stale_frame_until_read_again(tmp_path):
    from glmap_tools import synthetic as scenes
    from glmap_tools.errors import StoreError
    from glmap_tools.language.embed import HashingEmbedder
    from glmap_tools.map import GLMap, MapConfig

    path = tmp_path / "room.glmap"
    texts = {1: ("table", "a brown wooden dining table")}
    boxes = scenes.floor() + scenes.table(0.0, 0.0, 1)
    frames = [
        scenes.view(boxes, eye, (0.0, 0.0, 0.4)) for eye in [(0.3, -3.0, 1.4), (-2.5, -1.5, 1.4)]
    ]
    first = GLMap.open(path, MapConfig(floor_z=0.0), embedder=HashingEmbedder())
    second = GLMap.open(path, embedder=HashingEmbedder())  # as a second server would
    frame, ids = frames[0]
    first.integrate(frame, scenes.semantics(ids, texts, []))
    frame, ids = frames[1]
    with pytest.raises(StoreError, match="changed by another process"):
        second.integrate(frame, scenes.semantics(ids, texts, []))
    assert len(second.trajectory) == 0  # nothing changed in memory either
    second.close()
    second = GLMap.open(path, embedder=HashingEmbedder())
    second.integrate(frame, scenes.semantics(ids, texts, []))
    assert len(GLMap.open(path, embedder=HashingEmbedder()).trajectory) == 2
    first.close()
    second.close()


async def test_calls_of_one_pinned_server_take_turns_and_one_that_waits_too_long_says_so(tmp_path):
    server = build_server(config(tmp_path, map_name="ep", map_wait_s=0.2))
    async with Client(server) as client:
        answer(await client.call_tool("sim_reset", RESET))
        before = (tmp_path / "maps" / "ep.glmap").read_bytes()
        turns, taken, done = server._turns, anyio.Event(), anyio.Event()
        assert turns is not None

        async def long_call() -> None:  # holds the turn as another client's long call would
            async with turns:
                taken.set()
                await done.wait()

        async with anyio.create_task_group() as group:
            group.start_soon(long_call)
            await taken.wait()
            busy = await client.call_tool("sim_step", {"action": "turn_left"})
            done.set()
        assert busy.is_error
        text = busy.content[0].text
        assert "'ep' is in use by another call to this server" in text and "--map-wait" in text
        assert (tmp_path / "maps" / "ep.glmap").read_bytes() == before
        assert answer(await client.call_tool("sim_step", {"action": "turn_left"}))["steps"] == 1


async def test_a_map_file_removed_under_a_running_server_starts_anew_as_a_new_process_would(
    tmp_path,
):
    pinned = config(tmp_path, map_name="ep")
    path = tmp_path / "maps" / "ep.glmap"
    async with Client(build_server(pinned)) as client:  # one server (a lingering one, say)
        answer(await client.call_tool("sim_reset", RESET))
        path.unlink()  # the user removes the map between two calls
        summary = answer(await client.call_tool("map_summary", {"include_image": False}))
        step = await client.call_tool("sim_step", {"action": "turn_left"})
    assert summary["summary"]["frames"] == 0
    assert step.is_error and "no simulator episode" in step.content[0].text
    async with Client(build_server(pinned)) as client:  # the new file has this server's settings
        assert answer(await client.call_tool("map_summary", {"include_image": False}))
