"""Episode sets (JSON, reachability) and InstNav goal descriptions."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from glmap_tools.errors import InvalidInputError, UnknownIdError
from glmap_tools.sim.episodes import (
    episodes_from_dict,
    episodes_to_dict,
    generate_episodes,
    load_episodes,
    save_episodes,
)
from glmap_tools.sim.instnav import describe_instance, instance_goals
from glmap_tools.sim.layout_io import layout_from_dict
from glmap_tools.sim.navgrid import build_nav_grid
from glmap_tools.worlds.generator import generate_apartment


@pytest.fixture(scope="module")
def layout():
    return generate_apartment(8, n_rooms=4)


def _chair(i, x, y, color="blue", material="metal"):
    return {"id": i, "category": "chair", "mesh": "kenney/chairCushion", "position": [x, y, 0],
            "attributes": {"color": color, "material": material}}  # fmt: skip


def _room(room_id: int, name: str, x0: float, x1: float) -> dict:
    return {
        "id": room_id,
        "type": name,
        "name": name,
        "polygon": [[x0, 0], [x1, 0], [x1, 4], [x0, 4]],
    }


ROOMS = {
    "rooms": [_room(1, "kitchen", 0, 5), _room(2, "office", 5, 9), _room(3, "closet", 9, 11)],
    "openings": [{"id": 1, "rooms": [1, 2], "center": [5, 2], "width": 0.9}],
}


def _scene(objects):
    return layout_from_dict({**copy.deepcopy(ROOMS), "objects": objects})


def test_episodes_are_seeded_reachable_and_round_trip_through_json(layout, tmp_path) -> None:
    a = generate_episodes(layout, "objectnav", 12, seed=3)
    b = generate_episodes(layout, "objectnav", 12, seed=3)
    assert episodes_to_dict(a) == episodes_to_dict(b)
    grid = build_nav_grid(layout)
    for e in a.episodes:
        assert grid.is_navigable(np.array([e.start_position]))[0]
        assert 1.5 <= e.geodesic_distance < np.inf
        assert {layout.object(i).category for i in e.goal_object_ids} == {e.goal_text}
        assert e.goal_object_ids == tuple(o.id for o in layout.objects if o.category == e.goal_text)
    save_episodes(a, tmp_path / "episodes.json")
    again = load_episodes(tmp_path / "episodes.json", layout)
    assert episodes_to_dict(again) == episodes_to_dict(a)


def test_an_episode_whose_goal_cannot_be_reached_is_refused() -> None:
    # The closet (room 3) has no opening: its chair is unreachable from the kitchen.
    scene = _scene([_chair(1, 1, 1), _chair(2, 10, 2, color="red")])
    data = {
        "format": "glmap-sim-episodes", "version": 1, "task": "objectnav",
        "scene": scene.name, "scene_seed": None,
        "episodes": [{"episode_id": 0, "start_position": [3.0, 2.0], "start_heading": 0.0,
                      "goal": {"text": "red chair", "object_ids": [2]}}],
    }  # fmt: skip
    with pytest.raises(InvalidInputError, match=r"episode 0: goal 'red chair' .* is unreachable"):
        episodes_from_dict(data, scene)
    data["episodes"][0]["goal"]["object_ids"] = [1]
    episodes_from_dict(data, scene)  # the kitchen chair is fine
    data["episodes"][0]["goal"]["object_ids"] = [5]
    with pytest.raises(UnknownIdError, match=r"goal object ids \[5\]"):
        episodes_from_dict(data, scene)
    data["episodes"][0]["goal"]["object_ids"] = [1]
    data["episodes"][0]["start_position"] = [1.0, 1.0]  # on the chair
    with pytest.raises(InvalidInputError, match="not on navigable floor"):
        episodes_from_dict(data, scene)


@pytest.mark.parametrize(
    ("key", "value", "match"),
    [
        ("start_position", [10**400, 2.0], "episodes\\[0\\] is malformed .*OverflowError"),
        ("start_position", [float("nan"), 2.0], "episodes\\[0\\] is malformed .*finite"),
        ("start_position", [3.0, 2.0, 1.0], "episodes\\[0\\] is malformed .*2 finite numbers"),
        ("start_heading", float("inf"), "episodes\\[0\\] is malformed .*finite"),
        ("success_distance", "x", "success_distance x must be a positive number of metres"),
        ("success_distance", -1.0, "success_distance -1.0 must be a positive number"),
    ],
    ids=["past float64", "nan start", "three numbers", "inf heading", "text", "negative"],
)
def test_an_episode_value_of_the_wrong_kind_is_refused_naming_it(key, value, match) -> None:
    data = {
        "format": "glmap-sim-episodes", "version": 1, "task": "objectnav", "scene": "",
        "episodes": [{"episode_id": 0, "start_position": [3.0, 2.0], "start_heading": 0.0,
                      "goal": {"text": "chair", "object_ids": [1]}}],
    }  # fmt: skip
    episodes_from_dict(data)  # as given, it loads
    (data if key == "success_distance" else data["episodes"][0])[key] = value
    with pytest.raises(InvalidInputError, match=match):
        episodes_from_dict(data)


def test_an_unknown_task_suggests_the_closest() -> None:
    with pytest.raises(InvalidInputError, match="Did you mean 'objectnav'"):
        generate_episodes(_scene([_chair(1, 1, 1)]), "objnav", 1, seed=0)


def test_identical_chairs_are_told_apart_by_what_they_stand_next_to() -> None:
    table = {"id": 3, "category": "table", "mesh": "kenney/tableRound", "position": [1.5, 2.8, 0],
             "attributes": {"shape": "round"}}  # fmt: skip
    desk = {"id": 4, "category": "desk", "mesh": "kenney/desk", "position": [7.0, 3.3, 0]}
    scene = _scene([_chair(1, 1.5, 1.7), _chair(2, 7.0, 2.5), table, desk])
    assert (
        describe_instance(scene, scene.object(1)) == "the blue metal chair next to the round table"
    )
    assert describe_instance(scene, scene.object(2)) == "the blue metal chair next to the desk"


def test_a_chair_with_its_own_colour_needs_no_relation_beyond_its_room() -> None:
    scene = _scene([_chair(1, 1.5, 1.7), _chair(2, 3.5, 1.7, color="red")])
    assert describe_instance(scene, scene.object(2)) == "the red metal chair in the kitchen"


def test_two_identical_chairs_side_by_side_cannot_be_singled_out() -> None:
    scene = _scene([_chair(1, 1.5, 1.7), _chair(2, 2.2, 1.7)])
    assert describe_instance(scene, scene.object(1)) is None
    assert instance_goals(scene) == {}


def test_every_instnav_goal_matches_only_its_target(layout) -> None:
    goals = instance_goals(layout)
    assert len(goals) >= 10
    descriptions = list(goals.values())
    assert len(set(descriptions)) == len(descriptions)
    episodes = generate_episodes(layout, "instnav", 5, seed=0)
    for e in episodes.episodes:
        assert len(e.goal_object_ids) == 1 and goals[e.goal_object_ids[0]] == e.goal_text


def test_windowed_goal_cells_equal_the_whole_grid_reference(layout) -> None:
    from glmap_tools.sim.episodes import goal_cells, goal_cells_reference

    grid = build_nav_grid(layout)
    for obj in layout.objects[::6]:
        fast = goal_cells(grid, [obj], 1.0)
        assert np.array_equal(fast, goal_cells_reference(grid, [obj], 1.0)), obj.id
    pair = layout.objects[:2]
    assert np.array_equal(goal_cells(grid, pair, 0.6), goal_cells_reference(grid, pair, 0.6))


def test_goal_cells_stop_at_the_walls_of_the_goal_room(layout) -> None:
    from glmap_tools.sim.episodes import goal_cells

    grid = build_nav_grid(layout)
    xs, ys = grid.cell_centers()
    through_wall = 0
    for obj in layout.objects:
        cells = goal_cells(grid, [obj], 1.0)
        pts = np.column_stack([xs[cells], ys[cells]])
        other = np.array([layout.room_at(p) != obj.room for p in pts], dtype=bool)
        # Cells of another room reach the object only through an opening.
        for p in pts[other]:
            door = min(np.linalg.norm(o.center - p) for o in layout.openings)
            assert door <= 1.5, (obj.id, obj.category, p)
        naive = (obj.distance_to(np.column_stack([xs.ravel(), ys.ravel()])) <= 0.95).reshape(
            grid.shape
        ) & grid.navigable
        through_wall += int((naive & ~cells).sum())
    assert through_wall > 0, "without the wall check some cells behind walls would count"


def test_episodes_leave_out_goals_too_small_or_too_high_for_the_camera(tmp_path, capsys) -> None:
    import json

    from glmap_tools import cli
    from glmap_tools.sim.layout_io import save_layout
    from glmap_tools.worlds.scan import layout_from_scan

    def box(i: int, category: str, xyz: list[float], size: list[float]) -> dict:
        return {"id": i, "category": category, "center": xyz, "size": size, "yaw": 0.0}

    scan = {
        "objects": [
            box(1, "bed", [1.0, 1.0, 0.3], [2.0, 1.6, 0.6]),
            box(2, "chair", [4.0, 4.0, 0.45], [0.5, 0.5, 0.9]),
            box(3, "camera", [5.0, 0.2, 2.3], [0.12, 0.1, 0.1]),  # wall-mounted, 12 cm
            box(4, "candle", [3.0, 3.0, 0.05], [0.08, 0.08, 0.1]),
        ],
    }
    save_layout(layout_from_scan(scan, use_meshes=False), tmp_path / "layout.json")
    args = ["sim", "episodes", str(tmp_path / "layout.json"), "--count", "20", "--seed", "1"]
    assert cli.main([*args, "--out", str(tmp_path / "seen.json")]) == 0
    listed = capsys.readouterr().out
    assert cli.main([*args, "--all-goals", "--out", str(tmp_path / "all.json")]) == 0
    seen = {e["goal"]["text"] for e in json.loads((tmp_path / "seen.json").read_text())["episodes"]}
    every = {e["goal"]["text"] for e in json.loads((tmp_path / "all.json").read_text())["episodes"]}
    assert "object 3 'camera' (0.12 m at most" in listed and "object 4 'candle'" in listed
    assert seen <= {"bed", "chair"} and {"camera", "candle"} & every


@pytest.mark.parametrize("cells", [-1, 101, 100_000])  # 100000 asked scipy for a MemoryError
def test_a_passage_width_outside_its_range_is_refused_before_any_work(layout, cells) -> None:
    with pytest.raises(InvalidInputError, match=f"min_passage_cells={cells} must be 0"):
        generate_episodes(layout, "objectnav", 2, seed=0, min_passage_cells=cells)


@pytest.mark.parametrize("command", ["episodes", "qa", "eval"])
def test_a_negative_seed_is_refused_by_the_command_line(layout, tmp_path, capsys, command):
    # numpy's generators raised "expected non-negative integer" from inside the command
    from glmap_tools import cli
    from glmap_tools.sim.layout_io import save_layout

    save_layout(layout, tmp_path / "layout.json")
    files = [str(tmp_path / "layout.json")] + (
        [str(tmp_path / "e.json")] if command == "eval" else []
    )
    with pytest.raises(SystemExit):
        cli.main(["sim", command, *files, "--seed", "-1"])
    assert "argument --seed: '-1' is not a seed: give an integer >= 0" in capsys.readouterr().err
