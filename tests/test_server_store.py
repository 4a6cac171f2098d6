"""new_map, save_map, load_map and list_maps: names only, confined to the maps folder."""

from __future__ import annotations

from pathlib import Path

import pytest
from mcp import Client

from glmap_tools.server import build_server
from tests.test_server_fixtures import config, counts, frame_args

pytestmark = pytest.mark.anyio


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"


def files(folder: Path) -> set[str]:
    return {p.name for p in folder.iterdir()} if folder.exists() else set()


async def test_a_saved_map_reopens_with_every_unit_in_a_new_server(tmp_path):
    async with Client(build_server(config(tmp_path))) as client:
        await client.call_tool("observe_frame", frame_args())
        saved = await client.call_tool("save_map", {"name": "flat-3"})
        assert saved.structured_content["written"] and saved.structured_content["bytes"] > 0
        listed = await client.call_tool("list_maps", {})
        (entry,) = listed.structured_content["maps"]
        assert (entry["name"], entry["open"]) == ("flat-3", True)
    assert files(tmp_path / "maps") == {"flat-3.glmap"}
    async with Client(build_server(config(tmp_path))) as client:
        assert await counts(client) == (0, 0, 0)
        loaded = await client.call_tool("load_map", {"name": "flat-3"})
        assert loaded.structured_content["map_name"] == "flat-3"
        assert await counts(client) == (1, 3, 1)
        hits = await client.call_tool("find_instance", {"query": "red wooden chair"})
        assert hits.structured_content["hits"][0]["description"] == "a red wooden chair"


async def test_frames_observed_after_saving_are_committed_to_the_saved_map(tmp_path):
    async with Client(build_server(config(tmp_path))) as client:
        await client.call_tool("save_map", {"name": "live"})
        await client.call_tool("observe_frame", frame_args())
        again = await client.call_tool("save_map", {"name": "live"})
        assert again.structured_content["written"] is False
    async with Client(build_server(config(tmp_path))) as client:
        await client.call_tool("load_map", {"name": "live"})
        assert await counts(client) == (1, 3, 1)


async def test_new_map_with_a_name_creates_the_file_and_refuses_an_existing_name(tmp_path):
    async with Client(build_server(config(tmp_path))) as client:
        await client.call_tool("observe_frame", frame_args())
        created = await client.call_tool("new_map", {"name": "kitchen"})
        assert created.structured_content["map_name"] == "kitchen"
        assert await counts(client) == (0, 0, 0)
        twice = await client.call_tool("new_map", {"name": "kitchen"})
        assert twice.is_error and "already exists; open it with load_map" in twice.content[0].text
        scratch = await client.call_tool("new_map", {})
        assert scratch.structured_content["map_name"] is None
    assert files(tmp_path / "maps") == {"kitchen.glmap"}


async def test_saving_over_an_existing_map_needs_overwrite(tmp_path):
    async with Client(build_server(config(tmp_path))) as client:
        await client.call_tool("save_map", {"name": "a"})
        await client.call_tool("new_map", {})
        await client.call_tool("observe_frame", frame_args())
        refused = await client.call_tool("save_map", {"name": "a"})
        assert refused.is_error and "pass overwrite=true" in refused.content[0].text
        replaced = await client.call_tool("save_map", {"name": "a", "overwrite": True})
        assert not replaced.is_error, replaced.content[0].text
    async with Client(build_server(config(tmp_path))) as client:
        await client.call_tool("load_map", {"name": "a"})
        assert await counts(client) == (1, 3, 1)


@pytest.mark.parametrize(
    "name",
    ["../escape", "a/b", "/etc/passwd", "..", "~root", "sub\\dir", ".hidden", "a b", "x" * 65],
)
async def test_a_map_name_with_a_path_in_it_is_refused_and_nothing_is_written(tmp_path, name):
    async with Client(build_server(config(tmp_path))) as client:
        await client.call_tool("observe_frame", frame_args())
        for tool in ("save_map", "load_map", "new_map"):
            result = await client.call_tool(tool, {"name": name})
            assert result.is_error, (tool, name)
            text = result.content[0].text
            assert "contains a path" in text or "is not allowed" in text or "at most 70" in text
        assert await counts(client) == (1, 3, 1)
    assert files(tmp_path / "maps") == set()
    assert files(tmp_path) == {"maps"}


async def test_loading_an_unknown_map_suggests_the_closest_saved_name(tmp_path):
    async with Client(build_server(config(tmp_path))) as client:
        await client.call_tool("save_map", {"name": "living-room"})
        result = await client.call_tool("load_map", {"name": "living-rom"})
    assert result.is_error
    assert "Did you mean 'living-room'?" in result.content[0].text


async def test_a_file_that_is_not_a_map_is_a_store_error_and_stays_untouched(tmp_path):
    maps = tmp_path / "maps"
    maps.mkdir()
    (maps / "junk.glmap").write_bytes(b"not sqlite at all" * 10)
    async with Client(build_server(config(tmp_path))) as client:
        result = await client.call_tool("load_map", {"name": "junk"})
        assert result.is_error and "is not a GLMap store" in result.content[0].text
        assert await counts(client) == (0, 0, 0)
    assert (maps / "junk.glmap").read_bytes() == b"not sqlite at all" * 10


def truncate(path: Path) -> None:
    """Cut a file to half its size, as a crash or a full disk in another program might."""
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])


async def test_saving_with_overwrite_over_its_own_damaged_file_writes_the_map_afresh(tmp_path):
    # Issue 27 item 3: this answered ok with written: false and left the file corrupt.
    path = tmp_path / "maps" / "flat.glmap"
    async with Client(build_server(config(tmp_path))) as client:
        await client.call_tool("observe_frame", frame_args())
        await client.call_tool("save_map", {"name": "flat"})
        truncate(path)
        plain = await client.call_tool("save_map", {"name": "flat"})
        assert plain.is_error and "damaged" in plain.content[0].text
        assert "overwrite=true" in plain.content[0].text
        assert str(tmp_path) not in plain.content[0].text
        saved = await client.call_tool("save_map", {"name": "flat", "overwrite": True})
        assert not saved.is_error and saved.structured_content["written"] is True
    async with Client(build_server(config(tmp_path))) as client:
        loaded = await client.call_tool("load_map", {"name": "flat"})
        assert not loaded.is_error, loaded.content[0].text
        assert await counts(client) == (1, 3, 1)


async def test_a_commit_to_a_damaged_file_is_an_error_that_names_no_server_path(tmp_path):
    path = tmp_path / "maps" / "flat.glmap"
    async with Client(build_server(config(tmp_path))) as client:
        await client.call_tool("observe_frame", frame_args())
        await client.call_tool("save_map", {"name": "flat"})
        truncate(path)
        res = await client.call_tool("observe_frame", frame_args((0.3, -2.6, 1.4)))
        assert res.is_error
        assert str(tmp_path) not in res.content[0].text, res.content[0].text
        assert "flat.glmap" in res.content[0].text


@pytest.mark.parametrize("where", ["rename", "sqlite"])
async def test_a_save_that_fills_the_disk_is_an_error_and_leaves_the_old_file(
    tmp_path, monkeypatch, where
):
    import errno
    import os
    import sqlite3

    from glmap_tools.map import store

    path = tmp_path / "maps" / "flat.glmap"
    async with Client(build_server(config(tmp_path))) as client:
        await client.call_tool("observe_frame", frame_args())
        await client.call_tool("save_map", {"name": "flat"})
        before = path.read_bytes()
        await client.call_tool("new_map", {})
        await client.call_tool("observe_frame", frame_args((0.3, -2.6, 1.4), groups=False))
        if where == "rename":
            real = os.replace

            def full(src: str, dst: str) -> None:
                if str(dst).endswith(".glmap"):
                    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), src, None, dst)
                real(src, dst)

            monkeypatch.setattr(store.os, "replace", full)
        else:

            def full_db(self: store.MapStore, glmap: object) -> None:
                raise sqlite3.OperationalError("database or disk is full")

            monkeypatch.setattr(store.MapStore, "_write_everything", full_db)
        res = await client.call_tool("save_map", {"name": "flat", "overwrite": True})
        assert res.is_error, res.content[0].text
        text = res.content[0].text
        assert "could not write" in text and "old file is unchanged" in text
        assert str(tmp_path) not in text
    assert path.read_bytes() == before
    assert files(tmp_path / "maps") == {"flat.glmap"}  # no temporary file left


async def test_loading_a_map_during_a_simulator_episode_ends_it_and_never_writes_its_frames(
    tmp_path,
):
    async with Client(build_server(config(tmp_path, sim_size=(96, 72)))) as client:
        await client.call_tool("observe_frame", frame_args())
        await client.call_tool("save_map", {"name": "mine"})
        await client.call_tool("sim_reset", {"scene": 0, "seed": 1})
        await client.call_tool("sim_step", {"action": "turn_left"})
        loaded = await client.call_tool("load_map", {"name": "mine"})
        assert not loaded.is_error, loaded.content[0].text
        assert "episode was ended" in loaded.structured_content["simulator"]
        assert await counts(client) == (1, 3, 1)
        step = await client.call_tool("sim_step", {"action": "move_forward"})
        assert step.is_error and "call sim_reset" in step.content[0].text
        assert await counts(client) == (1, 3, 1)
    async with Client(build_server(config(tmp_path))) as client:
        await client.call_tool("load_map", {"name": "mine"})
        assert await counts(client) == (1, 3, 1)  # the file on disk holds only the user's frame
