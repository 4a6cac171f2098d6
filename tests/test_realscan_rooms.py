"""Our own real-room scans (tests/realscan_rooms.py) go through `glmap sim from-scan` and
`glmap sim episodes` as a user's scans would: every one is accepted (turned rooms, scanner
boxes, thin pictures), no floor is cut off by a narrow passage, and episodes are drawn."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import pytest

from glmap_tools import cli
from glmap_tools.sim.layout import LayoutWarning
from glmap_tools.worlds.scan import layout_from_scan, narrow_passages
from tests.realscan_rooms import scans, write_scans


@pytest.mark.parametrize("name", sorted(scans()))
def test_each_room_of_our_own_converts_with_no_impassable_floor(name: str) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LayoutWarning)
        layout = layout_from_scan(scans()[name])
    assert len(layout.objects) == len(scans()[name]["objects"])
    assert narrow_passages(layout) == []


@pytest.mark.filterwarnings("ignore::glmap_tools.sim.layout.LayoutWarning")
def test_the_rooms_become_a_scene_folder_with_episodes(tmp_path: Path) -> None:
    for scan in write_scans(tmp_path / "scans"):
        scene = tmp_path / "scenes" / scan.stem
        layout = scene / "layout.json"
        assert cli.main(["sim", "from-scan", str(scan), "--out", str(layout), "--boxes"]) == 0
        for task in ("objectnav", "instnav"):
            out = scene / f"{task}.json"
            argv = ["sim", "episodes", str(layout), "--task", task, "--count", "2"]
            assert cli.main([*argv, "--seed", "2", "--out", str(out)]) == 0
            assert len(json.loads(out.read_text())["episodes"]) == 2
