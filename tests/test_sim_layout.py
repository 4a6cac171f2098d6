"""Layout JSON: loading, validation errors, scan object lists."""

from __future__ import annotations

import copy
import json
import math

import numpy as np
import pytest

from glmap_tools.errors import InvalidInputError
from glmap_tools.sim.layout import LayoutWarning
from glmap_tools.sim.layout_io import layout_from_dict, layout_to_dict, load_layout, save_layout
from glmap_tools.worlds.scan import layout_from_scan

HAND_WRITTEN = {
    "name": "two rooms",
    "rooms": [
        {"id": 1, "type": "kitchen", "polygon": [[0, 0], [4, 0], [4, 3], [0, 3]]},
        {"id": 2, "type": "living room", "polygon": [[4, 0], [9, 0], [9, 4], [4, 4]]},
    ],
    "openings": [{"id": 1, "rooms": [1, 2], "center": [4, 1.5], "width": 0.9}],
    "objects": [
        {
            "id": 1,
            "category": "sofa",
            "mesh": "kenney/loungeSofa",
            "position": [6.5, 3.5, 0],
            "heading": -math.pi / 2,
            "attributes": {"color": "blue", "material": "fabric"},
            "description": "a blue fabric sofa",
        },
        {"id": 2, "category": "chair", "mesh": "kenney/chairCushion", "position": [1, 1, 0]},
        {"id": 3, "category": "table", "mesh": "primitive/table", "position": [2, 1.5, 0]},
    ],
    "regions": [{"id": 1, "description": "dining area: a table and a chair", "members": [2, 3]}],
}


def _bad(**changes: object) -> dict:
    data = copy.deepcopy(HAND_WRITTEN)
    for path, value in changes.items():
        target = data
        keys = path.split("__")
        for key in keys[:-1]:
            target = target[int(key)] if key.isdigit() else target[key]
        last = keys[-1]
        target[int(last) if last.isdigit() else last] = value
    return data


def test_a_hand_written_layout_loads_with_defaults_and_rooms_filled_in() -> None:
    layout = layout_from_dict(HAND_WRITTEN)
    sofa, chair, table = layout.objects
    assert (sofa.room, chair.room, table.room) == (2, 1, 1)
    np.testing.assert_allclose(chair.size, (0.45, 0.5, 0.9))  # the catalog's real size
    assert layout.regions[0].name == "dining area"


def test_a_layout_round_trips_through_a_json_file(tmp_path) -> None:
    layout = layout_from_dict(HAND_WRITTEN)
    save_layout(layout, tmp_path / "scene.json")
    again = load_layout(tmp_path / "scene.json")
    assert layout_to_dict(again) == layout_to_dict(layout)
    assert json.loads((tmp_path / "scene.json").read_text())["format"] == "glmap-sim-layout"


def test_an_unknown_mesh_is_refused_with_the_closest_known_name() -> None:
    with pytest.raises(InvalidInputError, match="Did you mean 'kenney/chairCushion'"):
        layout_from_dict(_bad(objects__1__mesh="kenney/chairCushon"))


def test_an_object_outside_every_room_is_refused_with_its_position() -> None:
    with pytest.raises(InvalidInputError, match=r"object 2 .* at \(12.00, 1.00\) is outside"):
        layout_from_dict(_bad(objects__1__position=[12, 1, 0]))


def test_two_objects_with_the_same_id_are_refused() -> None:
    with pytest.raises(InvalidInputError, match="object id 1 is used twice"):
        layout_from_dict(_bad(objects__1__id=1))


def test_an_opening_away_from_the_shared_wall_is_refused() -> None:
    with pytest.raises(InvalidInputError, match="put it on the wall the two rooms share"):
        layout_from_dict(_bad(openings__0__center=[2, 1.5]))


def test_a_region_naming_a_missing_object_is_refused() -> None:
    with pytest.raises(InvalidInputError, match=r"unknown object ids \[9\]"):
        layout_from_dict(_bad(regions__0__members=[2, 9]))


def test_a_negative_size_is_refused() -> None:
    with pytest.raises(InvalidInputError, match="size"):
        layout_from_dict(_bad(objects__0__size=[2, -1, 1]))


@pytest.mark.parametrize(
    ("changes", "match"),
    [
        ({"objects__1": 3}, r"objects\[1\] must be a JSON object, got 3"),
        ({"objects__1__position": [10**400, 1, 0]}, r"position\[0\] must be a finite number"),
        ({"regions__0__room": [1]}, r"region.*room must be an integer, got \[1\]"),
        ({"version": "x"}, "version 'x' is not"),
        ({"seed": "x"}, "layout seed must be an integer, got 'x'"),
    ],
    ids=["object a number", "coordinate past float64", "room a list", "version", "seed"],
)
def test_a_value_of_the_wrong_type_is_refused_naming_it(changes, match) -> None:
    with pytest.raises(InvalidInputError, match=match):
        layout_from_dict(_bad(**changes))


def test_a_clockwise_room_polygon_is_turned_counter_clockwise() -> None:
    layout = layout_from_dict(_bad(rooms__0__polygon=[[0, 0], [0, 3], [4, 3], [4, 0]]))
    assert layout.rooms[0].area == pytest.approx(12.0)
    assert layout.room_at(np.array([1.0, 1.0])) == 1


def test_footprint_distance_is_zero_inside_and_metric_outside() -> None:
    table = layout_from_dict(HAND_WRITTEN).objects[2]  # 1.6 x 0.9 at (2, 1.5), heading 0
    # heading 0: the front faces +x, so the 1.6 m width runs along y.
    d = table.distance_to(np.array([[2.0, 1.5], [2.0 + 0.45 + 1.0, 1.5], [2.0, 1.5 + 0.8 + 0.5]]))
    np.testing.assert_allclose(d, [0.0, 1.0, 0.5], atol=1e-9)


def test_a_y_up_scan_object_list_with_rotations_becomes_a_one_room_layout() -> None:
    yaw = 0.4
    scan = {
        "up": "y",
        "objects": [
            # y-up boxes: x width, y height, z depth
            {"id": 4, "category": "Chair", "center": [1.0, 0.55, -2.0], "size": [0.5, 0.9, 0.6],
             "yaw": yaw},
            {"id": 7, "category": "couch", "center": [3.0, 0.5, -1.0], "size": [2.0, 0.8, 0.9]},
            {"id": 9, "category": "widget", "center": [2.0, 0.6, -3.0], "size": [0.3, 0.2, 0.4],
             "rotation": np.eye(3).tolist()},
        ],
    }  # fmt: skip
    with pytest.warns(LayoutWarning, match="'widget' .* no mesh"):
        layout = layout_from_scan(scan)
    chair, couch, widget = layout.objects
    assert [o.id for o in layout.objects] == [4, 7, 9]
    assert chair.mesh == "kenney/chairCushion" and couch.mesh == "kenney/loungeSofa"
    assert widget.mesh == "primitive/box"
    # y-up (x, y, z) -> z-up (x, -z, y); the floor (lowest bottom, 0.1) goes to z = 0.
    np.testing.assert_allclose(chair.position, [1.0, 2.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(chair.size, [0.5, 0.6, 0.9])
    np.testing.assert_allclose(widget.size, [0.3, 0.4, 0.2])
    assert chair.heading == pytest.approx(yaw - math.pi / 2)
    assert layout.rooms[0].contains(np.array([o.position[:2] for o in layout.objects])).all()


def test_a_tilted_scan_box_is_refused() -> None:
    tilt = [[1, 0, 0], [0, math.cos(0.5), -math.sin(0.5)], [0, math.sin(0.5), math.cos(0.5)]]
    scan = [{"category": "chair", "center": [0, 0, 0.5], "size": [0.5, 0.5, 1], "rotation": tilt}]
    with pytest.raises(InvalidInputError, match="tilted"):
        layout_from_scan(scan)


SCAN_BOX = {"id": 1, "category": "chair", "center": [1.0, 1.0, 0.45], "size": [0.5, 0.5, 0.9]}
SQUARE = [[0, 0], [3, 0], [3, 3], [0, 3]]


@pytest.mark.parametrize(
    ("scan", "match"),
    [
        ({"room": 3}, "'room' must be a room object, got 3"),
        ({"room": {"polygon": 5}}, r"room.polygon must list at least 3 \[x, y\] corners"),
        ({"rooms": [{"polygon": [[0, 0], [3, 0], ["a", 3]]}]}, r"rooms\[0\].polygon must list"),
        ({"room": {"polygon": [[0, 0], [10**400, 0], [3, 3]]}}, r"room.polygon must list"),
        ({"objects": [{**SCAN_BOX, "id": [1]}]}, r"objects\[0\].id must be an integer, got \[1\]"),
        ({"objects": [{**SCAN_BOX, "attributes": [1]}]}, r"objects\[0\].attributes must be"),
        ({"objects": [{**SCAN_BOX, "yaw": 10**400}]}, r"objects\[0\].yaw must be a finite"),
        ({"objects": [{**SCAN_BOX, "rotation": [[10**400] * 3] * 3}]}, "finite 3x3 matrix"),
        ({"objects": [{**SCAN_BOX, "center": [10**400, 1, 0.45]}]}, "needs 'center'"),
        ({"openings": 3}, "non-empty list|list 'openings'"),
        ({"room": {"polygon": [[0, 0], [1e6, 0], [1e6, 3], [0, 3]]}}, "spans at most 200 m"),
    ],
    ids=[
        "room a number", "polygon a number", "corner text", "corner past float64", "id a list",
        "attributes a list", "yaw past float64", "rotation past float64", "centre past float64",
        "openings a number", "a million metres",
    ],
)  # fmt: skip
def test_a_scan_value_of_the_wrong_kind_is_refused_naming_it(scan, match) -> None:
    data = {"room": {"polygon": SQUARE}, "objects": [SCAN_BOX], **scan}
    layout_from_scan({"room": {"polygon": SQUARE}, "objects": [SCAN_BOX]})  # as given, it loads
    with pytest.raises(InvalidInputError, match=match):
        layout_from_scan(data)


def test_from_scan_takes_an_alias_file_and_reports_the_shape_each_category_got(
    tmp_path, capsys
) -> None:
    import json

    from glmap_tools import cli

    box = {"center": [2.0, 2.0, 0.4], "size": [0.4, 0.4, 0.8], "yaw": 0.0}
    scan = {
        "objects": [
            {"id": 1, "category": "bed", **box, "center": [1.0, 1.0, 0.3]},
            {"id": 2, "category": "plant-stand", **box},
            {"id": 3, "category": "candle", **box, "center": [3.0, 3.0, 0.1]},
        ]
    }
    (tmp_path / "scan.json").write_text(json.dumps(scan))
    (tmp_path / "aliases.json").write_text(json.dumps({"plant-stand": "side table"}))
    (tmp_path / "bad.json").write_text(json.dumps({"candle": "spaceship"}))

    def run(*extra: str) -> int:
        return cli.main(["sim", "from-scan", str(tmp_path / "scan.json"), *extra])

    assert run("--out", str(tmp_path / "plain.json")) == 0
    plain = capsys.readouterr().out
    assert run("--aliases", str(tmp_path / "aliases.json"), "--out", str(tmp_path / "a.json")) == 0
    aliased = capsys.readouterr().out
    assert run("--aliases", str(tmp_path / "bad.json"), "--out", str(tmp_path / "b.json")) != 0
    refused = capsys.readouterr()
    assert "plant-stand x1 -> a plain box (unknown)" in plain and "alias file" in plain
    assert "plant-stand x1 -> side table (kenney/sideTable)" in aliased
    assert "candle x1 -> a plain box (unknown)" in aliased  # reported once, with its shape
    meshes = {
        o["category"]: o["mesh"] for o in json.loads((tmp_path / "a.json").read_text())["objects"]
    }
    assert meshes["plant-stand"] == "kenney/sideTable"
    assert "'spaceship'" in refused.err + refused.out and not (tmp_path / "b.json").exists()
