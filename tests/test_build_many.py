"""`glmap build` over many folders: a map per scan on two worker processes or a local Ray
instance, equal to the single-folder builds; resumable; failures reported; bad input refused
before anything on disk changes."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import pytest

from glmap_tools.cli import main as glmap_main
from glmap_tools.language.embed import HashingEmbedder
from glmap_tools.map import GLMap
from tests.build_helpers import assert_same_map, write_small_tour

SCENES = ("s00", "s01")
FAST = ["--embedder", "hashing", "--quiet"]


@pytest.fixture(scope="module")
def scans(tmp_path_factory) -> Path:
    """A parent folder with two small tours and a folder that is no scan."""
    parent = tmp_path_factory.mktemp("scans")
    for scene in SCENES:
        write_small_tour(scene, parent / scene, frames=6)
    (parent / "notes").mkdir()
    (parent / "notes" / "readme.txt").write_text("not a scan")
    return parent


@pytest.fixture(scope="module")
def single_maps(scans, tmp_path_factory) -> dict[str, Path]:
    """Each scan built alone by the single-folder `glmap build`."""
    out = tmp_path_factory.mktemp("single")
    maps = {}
    for scene in SCENES:
        maps[scene] = out / f"{scene}.glmap"
        assert glmap_main(["build", str(scans / scene), "--out", str(maps[scene]), *FAST]) == 0
    return maps


@pytest.fixture(scope="module")
def built_on_two_workers(scans, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("many") / "maps"
    assert glmap_main(["build", str(scans), "--out", str(out), "--workers", "2", *FAST]) == 0
    return out


def _assert_maps_equal(out: Path, single_maps: dict[str, Path]) -> None:
    for scene, path in single_maps.items():
        a = GLMap.open(out / f"{scene}.glmap", embedder=HashingEmbedder())
        b = GLMap.open(path, embedder=HashingEmbedder())
        try:
            assert len(a.instances) >= 2
            assert_same_map(a, b)
        finally:
            a.close()
            b.close()


def _summary(out: Path) -> dict:
    return json.loads((out / "build-summary.json").read_text())


def test_two_workers_build_each_scan_as_the_single_folder_build_does(
    built_on_two_workers, single_maps
) -> None:
    out = built_on_two_workers
    assert sorted(p.name for p in out.iterdir()) == ["build-summary.json", "s00.glmap", "s01.glmap"]
    _assert_maps_equal(out, single_maps)


def test_the_summary_has_a_row_per_scan_with_its_figures(built_on_two_workers) -> None:
    rows = _summary(built_on_two_workers)["scans"]
    assert [r["scan"] for r in rows] == list(SCENES)
    for r in rows:
        assert r["status"] == "built" and r["frames"] == 6 and r["error"] == ""
        assert r["instances"] >= 2 and r["regions"] >= 0
        assert r["seconds"] > 0 and r["peak_rss_mb"] > 50 and r["host"]


def test_a_rerun_skips_the_finished_maps_and_says_so(scans, built_on_two_workers, capsys):
    out = built_on_two_workers
    before = {p.name: p.stat().st_mtime_ns for p in out.glob("*.glmap")}
    capsys.readouterr()
    assert glmap_main(["build", str(scans), "--out", str(out), "--workers", "2", *FAST]) == 0
    text = capsys.readouterr().out
    assert "skipping 2 scan(s) whose maps exist" in text and "--overwrite" in text
    assert {p.name: p.stat().st_mtime_ns for p in out.glob("*.glmap")} == before
    rows = _summary(out)["scans"]
    assert [r["status"] for r in rows] == ["skipped", "skipped"]
    assert all(r["frames"] == 6 for r in rows)  # the figures of the run that built them


def test_an_earlier_summary_row_of_the_wrong_shape_is_left_out(tmp_path) -> None:
    from glmap_tools.ingest.summary import read_summary

    good = {"scan": "s00", "folder": "f", "map": "m", "status": "built", "frames": 3}
    good |= {"seconds": 1.5, "cpu_s": 2, "host": "h", "error": ""}
    path = tmp_path / "build-summary.json"
    rows = [good, [1], "s01", {**good, "scan": "s02", "frames": "x"}]
    rows += [{**good, "scan": "s03", "cpu_s": {}}, {**good, "scan": "s04", "host": 1}]
    rows += [{**good, "scan": "s05", "frames": 2.5}, {"scan": "s06"}, {**good, "scan": 7}]
    path.write_text(json.dumps({"scans": rows}))
    assert list(read_summary(path)) == ["s00"]
    for text in ('{"scans": 3}', "[]", "null", '{"scans": [1', "\udcff"):
        path.write_text(text, errors="surrogateescape")
        assert read_summary(path) == {}


def test_a_list_file_names_scans_and_a_half_written_map_of_a_killed_build_is_removed(
    scans, single_maps, tmp_path, capsys
) -> None:
    out = tmp_path / "maps"
    out.mkdir()
    leftovers = [out / ".own.glmap.k3x9.tmp", out / ".own.glmap.building"]
    for path in leftovers:
        path.write_bytes(b"half a map")
    listing = tmp_path / "scans.txt"
    listing.write_text(f"# one scan, named\nown={scans / 's01'}\n\n")
    assert glmap_main(["build", str(listing), "--out", str(out), *FAST]) == 0
    assert "removed 2 temporary file(s)" in capsys.readouterr().out
    assert sorted(p.name for p in out.iterdir()) == ["build-summary.json", "own.glmap"]
    _assert_maps_equal_one(out / "own.glmap", single_maps["s01"])


def _assert_maps_equal_one(path: Path, reference: Path) -> None:
    a = GLMap.open(path, embedder=HashingEmbedder())
    b = GLMap.open(reference, embedder=HashingEmbedder())
    try:
        assert_same_map(a, b)
    finally:
        a.close()
        b.close()


def test_a_scan_that_fails_is_reported_while_the_others_are_built(scans, tmp_path, capsys) -> None:
    broken = tmp_path / "broken"
    shutil.copytree(scans / "s00", broken)
    (broken / "depth" / "00002.png").write_bytes(b"not a png")
    listing = tmp_path / "scans.txt"
    listing.write_text(f"broken\n{scans / 's01'}\n")  # a relative folder and an absolute one
    out = tmp_path / "maps"
    code = glmap_main(["build", str(listing), "--out", str(out), "--workers", "2", *FAST])
    text = capsys.readouterr().out
    assert code == 1
    assert (
        "FAILED broken: cannot read depth image" in text
        and "00002.png" in text
        and "rerun the same command" in text
    )
    assert sorted(p.name for p in out.iterdir()) == ["build-summary.json", "s01.glmap"]
    rows = {r["scan"]: r for r in _summary(out)["scans"]}
    assert rows["broken"]["status"] == "failed" and "00002.png" in rows["broken"]["error"]
    assert rows["s01"]["status"] == "built"


def _refused(args: list[str], capsys) -> str:
    assert glmap_main(["build", *args, *FAST]) == 1
    return capsys.readouterr().err


def test_bad_inputs_are_refused_by_name_and_nothing_is_written(scans, tmp_path, capsys) -> None:
    out = tmp_path / "maps"
    missing = tmp_path / "list.txt"
    missing.write_text(f"{scans / 's00'}\n{tmp_path / 'nowhere'}\n")
    err = _refused([str(missing), "--out", str(out)], capsys)
    assert "line 2" in err and "nowhere" in err and "not a folder" in err

    twice = tmp_path / "twice.txt"
    twice.write_text(f"{scans / 's00'}\na/s00={scans / 's01'}\n")
    assert "cannot name a map file" in _refused([str(twice), "--out", str(out)], capsys)
    twice.write_text(f"{scans / 's00'}\ns00={scans / 's01'}\n")
    err = _refused([str(twice), "--out", str(out)], capsys)
    assert "'s00'" in err and "used twice" in err and "NAME=FOLDER" in err

    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / "x").mkdir()
    assert "nothing to build" in _refused([str(empty), "--out", str(out)], capsys)

    a_file = tmp_path / "maps.txt"
    a_file.write_text("keep me")
    assert "is a file" in _refused([str(scans), "--out", str(a_file)], capsys)
    assert a_file.read_text() == "keep me"

    assert "--workers 0" in _refused([str(scans), "--out", str(out), "--workers", "0"], capsys)
    err = _refused([str(scans), "--out", str(out), "--ray-address", "nohost"], capsys)
    assert "'nohost'" in err and "ray://HOST:PORT" in err
    assert "pass --out FOLDER" in _refused([str(scans)], capsys)
    err = _refused([str(scans), "--out", str(out), "--perception", "geometric"], capsys)
    assert "one at a time" in err
    err = _refused([str(scans / "s00"), "--out", str(out / "m.glmap"), "--workers", "2"], capsys)
    assert "--workers is for many scans" in err
    assert sorted(os.listdir(tmp_path)) == ["empty", "list.txt", "maps.txt", "twice.txt"]


@pytest.mark.slow  # a Ray start and two scans: ~30 s on two busy cores
def test_a_local_ray_instance_builds_each_scan_as_the_single_folder_build_does(
    scans, single_maps, tmp_path, capsys
) -> None:
    # Not `running_ray`: with no instance in the process, `--ray-address local` starts one
    # and stops it after the build; with one running, it builds on that and leaves it running.
    ray = pytest.importorskip("ray")
    running = ray.is_initialized()
    out = tmp_path / "maps"
    args = [str(scans), "--out", str(out), "--ray-address", "local", "--workers", "2", *FAST]
    assert glmap_main(["build", *args]) == 0
    assert ray.is_initialized() == running
    assert "built 2, skipped 0, failed 0" in capsys.readouterr().out
    _assert_maps_equal(out, single_maps)
    assert glmap_main(["build", *args]) == 0  # resuming needs no Ray start at all
    assert "built 0, skipped 2, failed 0" in capsys.readouterr().out
