"""Simulator credibility (issue 8): rugs, walls, mesh aliases, map-eval options, tours."""

from __future__ import annotations

import dataclasses
import json
import os
import warnings

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

import numpy as np
import pytest

from glmap_tools.cli import main as glmap_main
from glmap_tools.errors import InvalidInputError
from glmap_tools.sim.catalog import CATEGORY_ALIASES, CATEGORY_MESH, resolve_category
from glmap_tools.sim.layout import LayoutWarning
from glmap_tools.sim.layout_io import layout_from_dict, load_layout, save_layout
from glmap_tools.sim.navgrid import build_nav_grid, is_flat
from glmap_tools.sim.wallfit import clears_walls
from glmap_tools.worlds.scan import layout_from_scan
from glmap_tools.worlds.tour import plan_tour

ROOM = {"id": 1, "type": "living room", "polygon": [[0, 0], [6, 0], [6, 4], [0, 4]]}


def _box(category: str, center: list[float], size: list[float]) -> dict:
    return {"category": category, "center": center, "size": size}


def _scan(*objects: dict) -> dict:
    return {"up": "z", "room": ROOM, "objects": list(objects)}


def test_a_scanned_rug_ten_centimetres_high_is_walked_over_but_a_low_box_is_not() -> None:
    layout = layout_from_scan(
        _scan(
            _box("sofa", [1.5, 3.4, 0.4], [2.0, 0.9, 0.8]),
            _box("Area-Rug", [3.0, 2.0, 0.05], [2.5, 1.8, 0.1]),
            _box("bath mat", [5.0, 0.8, 0.06], [0.8, 0.5, 0.12]),
            _box("box", [1.0, 0.8, 0.05], [0.6, 0.6, 0.1]),
        )
    )
    sofa, rug, mat, box = layout.objects
    grid = build_nav_grid(layout)
    assert is_flat(rug) and is_flat(mat) and not is_flat(box) and not is_flat(sofa)
    assert grid.navigable_at(3.0, 2.0) and grid.navigable_at(5.0, 0.8)
    assert not grid.navigable_at(1.0, 0.8), "a 10 cm box that is not a floor covering blocks"
    tall_rug = dataclasses.replace(rug, size=np.array([2.5, 1.8, 0.3]))
    assert not is_flat(tall_rug), "a 'rug' 30 cm high is not a floor covering"
    assert not is_flat(dataclasses.replace(rug, category="mattress"))


def test_a_footprint_crossing_a_wall_is_moved_inside_with_a_warning() -> None:
    data = {
        "rooms": [ROOM],
        "objects": [
            {"id": 1, "category": "bed", "mesh": "kenney/bedSingle",
             "position": [5.6, 2.0, 0.0], "heading": 0.0, "size": [1.0, 1.2, 0.6]},
        ],
    }  # fmt: skip
    with pytest.warns(LayoutWarning, match=r"objects\[0\] \(object 1, 'bed'\) crossed a wall"):
        layout = layout_from_dict(data)
    bed = layout.objects[0]
    assert clears_walls(layout.rooms[0], bed.footprint())
    # heading 0 (front +x): the 1.0 m width runs along y, the 1.2 m depth along x; the wall
    # stands 5 cm inside the polygon edge x = 6.
    assert bed.position[0] == pytest.approx(6.0 - 0.05 - 0.6, abs=1e-6)
    assert bed.position[1] == pytest.approx(2.0)


def test_a_footprint_far_through_a_wall_or_wider_than_the_room_is_refused() -> None:
    far = {"id": 1, "category": "bed", "mesh": "kenney/bedSingle",
           "position": [5.9, 2.0, 0.0], "heading": 0.0, "size": [2.0, 1.2, 0.6]}  # fmt: skip
    with pytest.raises(InvalidInputError, match=r"object 1, 'bed'\) crosses a wall of room 1"):
        layout_from_dict({"rooms": [ROOM], "objects": [far]})
    # heading 90 deg (front +y): the 4.5 m depth runs along y, the room is 4 m deep.
    wide = dict(far, position=[3.0, 2.0, 0.0], heading=1.5708, size=[1.0, 4.5, 0.6])
    with pytest.raises(InvalidInputError, match="does not clear the walls"):
        layout_from_dict({"rooms": [ROOM], "objects": [wide]})


def test_from_scan_prints_a_warning_for_a_box_through_the_wall(tmp_path, capsys) -> None:
    scan = tmp_path / "scan.json"
    scan.write_text(json.dumps(_scan(_box("wardrobe", [3.0, 3.8, 1.0], [1.2, 0.6, 2.0]))))
    out = tmp_path / "scene.json"
    assert glmap_main(["sim", "from-scan", str(scan), "--out", str(out)]) == 0
    assert "warning: objects[0] (object 1, 'wardrobe') crossed a wall" in capsys.readouterr().out
    wardrobe = load_layout(out).objects[0]
    assert wardrobe.position[1] == pytest.approx(4.0 - 0.05 - 0.3, abs=1e-6)


def test_scan_categories_without_a_mesh_go_through_the_alias_table() -> None:
    expected = {
        "book": "kenney/books",
        "indoor-plant": "kenney/pottedPlant",
        "bin": "kenney/trashcan",
        "tv-screen": "primitive/tv",
        "Chairs": "kenney/chairCushion",
    }
    objects = [_box(c, [1.0 + i, 2.0, 0.2], [0.3, 0.3, 0.4]) for i, c in enumerate(expected)]
    with warnings.catch_warnings():
        warnings.simplefilter("error", LayoutWarning)  # known through aliases: no warning
        layout = layout_from_scan(_scan(*objects))
    assert [o.mesh for o in layout.objects] == list(expected.values())
    assert [o.category for o in layout.objects] == list(expected), "scan labels are kept"
    assert all(target in CATEGORY_MESH for target in CATEGORY_ALIASES.values())
    with pytest.warns(LayoutWarning, match=r"'microwave' \(2 objects\) has no mesh"):
        boxes = layout_from_scan(
            _scan(*[_box("microwave", [1.0 + i, 1.0, 0.2], [0.5, 0.4, 0.3]) for i in range(2)])
        )
    assert {o.mesh for o in boxes.objects} == {"primitive/box"}
    assert resolve_category("garbage-can") == "trash can"


def test_a_one_room_tour_walks_through_the_room() -> None:
    layout = layout_from_scan(
        _scan(
            _box("sofa", [1.5, 3.4, 0.4], [2.0, 0.9, 0.8]), _box("table", [3, 2, 0.4], [1, 1, 0.8])
        )
    )
    stops = plan_tour(layout, step=0.4, spin=8)
    xy = np.array([[s.x, s.y] for s in stops])
    walked = float(np.linalg.norm(np.diff(xy, axis=0), axis=1).sum())
    assert walked >= 4.0, f"the tour walked {walked:.2f} m"
    assert np.ptp(xy[:, 0]) >= 3.0, "it crosses the 6 m room"
    assert len({(round(s.x, 3), round(s.y, 3)) for s in stops}) >= 8
    assert build_nav_grid(layout).is_navigable(xy).all()


@pytest.fixture(scope="module")
def small_scene(tmp_path_factory):
    layout = layout_from_scan(
        _scan(
            _box("sofa", [1.5, 3.4, 0.4], [2.0, 0.9, 0.8]), _box("table", [3, 2, 0.4], [1, 1, 0.8])
        )
    )
    path = tmp_path_factory.mktemp("scene") / "scene.json"
    save_layout(layout, path)
    return path


def test_map_eval_min_pixels_reaches_the_annotations(small_scene, capsys) -> None:
    pytest.importorskip("glmap_tools.map")
    base = ["sim", "map-eval", str(small_scene), "--embedder", "hashing", "--max-frames", "3"]
    base += ["--width", "160", "--height", "120"]
    assert glmap_main(base) == 0
    default = capsys.readouterr().out
    assert " 0 visible objects" not in default
    assert glmap_main([*base, "--min-pixels", "20000"]) == 0  # more than the 19200 px frame
    assert "0 map instances for 0 visible objects" in capsys.readouterr().out
    assert glmap_main([*base, "--min-pixels", "0"]) == 1
    assert "--min-pixels 0 must be at least 1" in capsys.readouterr().err


def test_stopping_behind_the_wall_of_the_goal_room_is_not_a_success() -> None:
    from glmap_tools.sim.env import ObjectNavEnv
    from glmap_tools.sim.episodes import Episode, EpisodeSet
    from glmap_tools.sim.render import CameraSpec

    data = {
        "name": "two rooms",
        "rooms": [
            {"id": 1, "type": "bedroom", "polygon": [[0, 0], [4, 0], [4, 4], [0, 4]]},
            {"id": 2, "type": "hallway", "polygon": [[4, 0], [8, 0], [8, 4], [4, 4]]},
        ],
        "openings": [{"id": 1, "rooms": [1, 2], "center": [4, 3.3], "width": 0.9}],
        "objects": [
            {"id": 1, "category": "wardrobe", "mesh": "primitive/wardrobe",
             "position": [3.6, 1.0, 0.0], "heading": 0.0, "size": [0.6, 0.6, 2.0]},
        ],
    }  # fmt: skip
    layout = layout_from_dict(data)

    def stop_at(x: float, y: float) -> dict:
        episode = Episode(0, "objectnav", (x, y), 0.0, "wardrobe", (1,), 3.0)
        env = ObjectNavEnv(layout, EpisodeSet("objectnav", "two rooms", None, [episode]),
                           camera=CameraSpec(64, 48))  # fmt: skip
        try:
            env.reset(seed=0, options={"episode_index": 0})
            surface = env.surface_distance()
            return {"surface": surface, **env.step(0)[4]}
        finally:
            env.close()

    behind = stop_at(4.4, 1.0)  # 0.5 m from the wardrobe, through the wall
    assert behind["surface"] <= 1.0 and not behind["success"]
    assert behind["distance_to_goal"] > 1.0, "the goal cells lie in the bedroom"
    inside = stop_at(2.8, 1.0)
    assert inside["success"] and inside["distance_to_goal"] == 0.0
