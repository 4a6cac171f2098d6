"""Tours on disk (Redwood layout, readable by the ingest code), the CLI, and map building."""

from __future__ import annotations

import json
import os

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

import cv2
import numpy as np
import pytest

from glmap_tools.cli import main as glmap_main
from glmap_tools.geometry import Pose
from glmap_tools.ingest.datasets import open_sequence
from glmap_tools.ingest.images import read_annotation
from glmap_tools.sim.layout_io import load_layout, save_layout
from glmap_tools.sim.render import CameraSpec, SceneRenderer
from glmap_tools.worlds.generator import generate_apartment
from glmap_tools.worlds.tour import plan_tour, write_tour

SMALL = CameraSpec(160, 120)


@pytest.fixture(scope="module")
def layout():
    return generate_apartment(5, n_rooms=3)


def test_the_tour_visits_every_room_and_stays_on_navigable_floor(layout) -> None:
    from glmap_tools.sim.navgrid import build_nav_grid

    stops = plan_tour(layout, step=0.4, spin=4)
    grid = build_nav_grid(layout)
    assert {s.room for s in stops} == {r.id for r in layout.rooms}
    assert grid.is_navigable(np.array([[s.x, s.y] for s in stops])).all()


@pytest.mark.parametrize(
    ("step", "spin"),
    [(float("nan"), 8), (1e-300, 8), (1e-4, 8), (float("inf"), 8), (0.4, 10**6), (0.4, -1)],
)
def test_a_tour_step_or_spin_outside_its_range_is_refused(layout, step, spin) -> None:
    # nan and 1e-300 crashed in np.arange; 0.1 mm steps planned for minutes
    from glmap_tools.errors import InvalidInputError

    with pytest.raises(InvalidInputError, match=r"must lie in \[0.05, 50.0\] m and spin="):
        plan_tour(layout, step=step, spin=spin)


def test_a_tour_folder_reads_back_through_the_ingest_code(layout, tmp_path) -> None:
    n = write_tour(layout, tmp_path, SMALL, step=0.5, spin=2, max_frames=5, preview_every=2)
    assert n == 5
    for sub, count in (("color", 5), ("depth", 5), ("preview", 3)):
        assert len(list((tmp_path / sub).glob("*.png"))) == count
    assert (tmp_path / "topdown.png").is_file()
    sequence = open_sequence(tmp_path, up_axis="z")  # poses are z-up already
    stops = plan_tour(layout, step=0.5, spin=2)[:5]
    renderer = SceneRenderer(layout, SMALL)
    for i, frame in enumerate(sequence.frames()):
        stop = stops[i]
        expected = Pose.from_position_heading(stop.x, stop.y, SMALL.camera_height, stop.heading)
        np.testing.assert_allclose(frame.frame.pose.matrix, expected.matrix, atol=1e-6)
        assert frame.frame.intrinsics == SMALL.intrinsics
        view = renderer.render(expected)
        np.testing.assert_allclose(frame.frame.depth, view.depth, atol=6e-4)  # millimetre PNG
        np.testing.assert_array_equal(frame.frame.rgb, view.rgb)
        semantics = read_annotation(tmp_path, f"{i:05d}", view.depth.shape)
        assert semantics is not None
        assert {o.local_id for o in semantics.objects} <= {o.id for o in layout.objects}
    depth_png = cv2.imread(str(tmp_path / "depth" / "00000.png"), cv2.IMREAD_UNCHANGED)
    assert depth_png.dtype == np.uint16


def test_cli_new_then_episodes_eval_and_qa(tmp_path, capsys) -> None:
    scene = tmp_path / "scene.json"
    assert glmap_main(["sim", "new", "--seed", "5", "--rooms", "3", "--out", str(scene)]) == 0
    assert load_layout(scene).name == "apartment-5"
    assert glmap_main(["sim", "new", "--seed", "5", "--out", str(scene)]) == 1  # exists
    episodes = tmp_path / "episodes.json"
    assert glmap_main(["sim", "episodes", str(scene), "--count", "3", "--out", str(episodes)]) == 0
    args = ["sim", "eval", str(scene), str(episodes), "--width", "32", "--height", "24"]
    assert glmap_main(args) == 0
    assert "oracle agent on 3 objectnav episodes: success 100.0%" in capsys.readouterr().out
    qa = tmp_path / "qa.json"
    assert glmap_main(["sim", "qa", str(scene), "--situations", "3", "--out", str(qa)]) == 0
    assert json.loads(qa.read_text())["format"] == "glmap-sim-sqa"


def test_cli_converts_a_scan_object_list(tmp_path) -> None:
    scan = tmp_path / "scan.json"
    scan.write_text(
        json.dumps(
            {"objects": [{"category": "sofa", "center": [1, 1, 0.4], "size": [2, 0.9, 0.8]}]}
        )
    )
    out = tmp_path / "scene.json"
    assert glmap_main(["sim", "from-scan", str(scan), "--out", str(out)]) == 0
    assert load_layout(out).objects[0].mesh == "kenney/loungeSofa"


def test_cli_reports_a_bad_layout_with_a_clear_error(tmp_path, capsys, layout) -> None:
    path = tmp_path / "scene.json"
    save_layout(layout, path)
    data = json.loads(path.read_text())
    data["objects"][0]["mesh"] = "kenney/loungeSofaa"
    path.write_text(json.dumps(data))
    assert glmap_main(["sim", "episodes", str(path), "--out", str(tmp_path / "e.json")]) == 1
    assert "Did you mean 'kenney/loungeSofa'" in capsys.readouterr().err


def test_a_tour_with_detector_perception_writes_fewer_and_different_annotations(
    layout, tmp_path
) -> None:
    counts = {}
    for perception in ("gt", "detector"):
        out = tmp_path / perception
        write_tour(layout, out, SMALL, step=0.5, spin=4, max_frames=12, perception=perception)
        labels = []
        for i in range(12):
            semantics = read_annotation(out, f"{i:05d}", (SMALL.height, SMALL.width))
            assert semantics is not None
            labels += [(i, o.local_id, o.label) for o in semantics.objects]
        counts[perception] = labels
    assert len(counts["detector"]) < len(counts["gt"])  # misses
    assert set(counts["detector"]) != set(counts["gt"])
    with pytest.raises(Exception, match="perception='yolo'"):
        write_tour(layout, tmp_path / "x", SMALL, max_frames=1, perception="yolo")
