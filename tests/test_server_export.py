"""export_ply through an in-memory client: PLY files by bare name, only in the maps folder."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from mcp import Client

from glmap_tools.gaussians.ply import read_ply
from glmap_tools.server import build_server
from tests.test_server_fixtures import config, frame_args

pytestmark = pytest.mark.anyio


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"


def files(folder: Path) -> set[str]:
    return {p.name for p in folder.iterdir()} if folder.exists() else set()


async def test_the_map_an_instance_and_a_region_export_as_ply_files_in_the_maps_folder(tmp_path):
    async with Client(build_server(config(tmp_path))) as client:
        observed = await client.call_tool("observe_frame", frame_args())
        report = observed.structured_content["report"]
        chair, table = report["local_to_global"]["1"], report["local_to_global"]["2"]
        region = report["regions_added"][0]["global_id"]
        whole = await client.call_tool("export_ply", {"name": "flat"})
        one = await client.call_tool("export_ply", {"name": "chair.ply", "unit_id": chair})
        group = await client.call_tool("export_ply", {"name": "corner", "unit_id": region})
        listed = await client.call_tool("list_maps", {})
    for result in (whole, one, group):
        assert not result.is_error, result.content[0].text
    assert files(tmp_path / "maps") == {"flat.ply", "chair.ply", "corner.ply"}
    assert files(tmp_path) == {"maps"}
    assert listed.structured_content["maps"] == []  # exports are not maps
    w, c, g = (r.structured_content for r in (whole, one, group))
    assert (w["file"], w["what"]) == ("flat.ply", "whole map")
    assert (c["file"], c["what"], c["instance_ids"]) == ("chair.ply", "instance 1 (chair)", [chair])
    assert (g["what"], sorted(g["instance_ids"])) == (f"region {region}", sorted([chair, table]))
    assert c["gaussians"] < g["gaussians"] < w["gaussians"]
    for result in (w, c, g):
        path = tmp_path / "maps" / result["file"]
        assert path.stat().st_size == result["bytes"]
        assert len(read_ply(path)) == result["gaussians"]
    chair_ply = read_ply(tmp_path / "maps" / "chair.ply")
    assert np.all(chair_ply.colors[:, 0] > chair_ply.colors[:, 2])  # the red chair


@pytest.mark.parametrize(
    "name", ["../escape", "a/b", "/tmp/x", "..", "~root", "sub\\dir", ".hidden", "a b", "x" * 71]
)
async def test_an_export_name_with_a_path_in_it_is_refused_and_nothing_is_written(tmp_path, name):
    async with Client(build_server(config(tmp_path))) as client:
        await client.call_tool("observe_frame", frame_args())
        result = await client.call_tool("export_ply", {"name": name})
    assert result.is_error
    text = result.content[0].text
    assert "contains a path" in text or "is not allowed" in text or "at most 70" in text
    assert files(tmp_path / "maps") == set()
    assert files(tmp_path) == {"maps"}


async def test_an_unknown_id_or_an_empty_map_is_refused_before_any_file_is_written(tmp_path):
    async with Client(build_server(config(tmp_path))) as client:
        empty = await client.call_tool("export_ply", {"name": "nothing"})
        await client.call_tool("observe_frame", frame_args())
        unknown = await client.call_tool("export_ply", {"name": "ghost", "unit_id": 5})
    assert empty.is_error and "the map is empty; observe frames" in empty.content[0].text
    assert unknown.is_error and "does not exist" in unknown.content[0].text
    assert "Closest id: 4" in unknown.content[0].text
    assert files(tmp_path / "maps") == set()


async def test_replacing_an_export_needs_overwrite_and_a_failed_one_leaves_it_untouched(
    tmp_path, monkeypatch
):
    async with Client(build_server(config(tmp_path))) as client:
        observed = await client.call_tool("observe_frame", frame_args())
        chair = observed.structured_content["report"]["local_to_global"]["1"]
        first = await client.call_tool("export_ply", {"name": "keep", "unit_id": chair})
        assert not first.is_error, first.content[0].text
        before = (tmp_path / "maps" / "keep.ply").read_bytes()
        again = await client.call_tool("export_ply", {"name": "keep"})
        assert again.is_error and "pass overwrite=true" in again.content[0].text
        unknown = await client.call_tool(
            "export_ply", {"name": "keep", "unit_id": 99, "overwrite": True}
        )
        assert unknown.is_error and "does not exist" in unknown.content[0].text

        def disk_full(fd: int) -> None:
            raise OSError(28, "No space left on device")

        monkeypatch.setattr(os, "fsync", disk_full)  # the write fails after the bytes are out
        failed = await client.call_tool("export_ply", {"name": "keep", "overwrite": True})
        monkeypatch.undo()
        assert failed.is_error
        text = failed.content[0].text
        assert "could not write 'keep.ply' in the maps folder (No space left" in text
        assert str(tmp_path) not in text  # names only, never the server's paths
        assert (tmp_path / "maps" / "keep.ply").read_bytes() == before
        assert files(tmp_path / "maps") == {"keep.ply"}  # no temporary file left behind
        replaced = await client.call_tool("export_ply", {"name": "keep", "overwrite": True})
    assert not replaced.is_error, replaced.content[0].text
    assert replaced.structured_content["what"] == "whole map"
    assert (tmp_path / "maps" / "keep.ply").read_bytes() != before
    assert len(read_ply(tmp_path / "maps" / "keep.ply")) == replaced.structured_content["gaussians"]
