"""The checked-in benchmark split: regenerates identically, long episodes, hidden starts."""

from __future__ import annotations

import json
import os

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

import numpy as np
import pytest

from glmap_tools.errors import InvalidInputError, UnknownIdError
from glmap_tools.sim.episodes import TASKS, episodes_to_dict, goal_cells
from glmap_tools.sim.layout_io import layout_to_dict
from glmap_tools.sim.navgrid import NavGrid, build_nav_grid
from glmap_tools.sim.render import CameraSpec
from glmap_tools.sim.sight import SightChecker
from glmap_tools.worlds.generator import generate_apartment
from glmap_tools.worlds.splits import (
    SPLIT_SPECS,
    SPLITS,
    bench_episode,
    bench_grid,
    bench_layout,
    hidden_episodes,
    load_split,
    make_env,
    make_layout,
    scene_episodes,
    split_dir,
)


def test_regenerating_a_scene_reproduces_its_checked_in_layout_and_episodes() -> None:
    spec = SPLIT_SPECS["tune"]
    seed = spec.seeds[1]
    folder = split_dir("tune") / "s01"
    layout = make_layout(spec, seed)
    assert layout_to_dict(layout) == json.loads((folder / "layout.json").read_text())
    episodes = scene_episodes(spec, seed, layout, "instnav")
    assert episodes_to_dict(episodes) == json.loads((folder / "instnav.json").read_text())


def test_a_scene_whose_starts_were_redrawn_for_a_sliver_regenerates_as_checked_in() -> None:
    spec = SPLIT_SPECS["tune"]
    folder = split_dir("tune") / "s03"
    layout = make_layout(spec, spec.seeds[3])
    episodes = scene_episodes(spec, spec.seeds[3], layout, "objectnav")
    assert episodes_to_dict(episodes) == json.loads((folder / "objectnav.json").read_text())


def _two_rooms(passage_cells: int) -> NavGrid:
    """Two 10 x 10 navigable rooms joined by a 4-cell-long passage `passage_cells` wide."""
    nav = np.zeros((12, 26), dtype=bool)
    nav[1:11, 1:11] = nav[1:11, 15:25] = True
    nav[5 : 5 + passage_cells, 11:15] = True
    return NavGrid(np.zeros(2), 0.05, nav.copy(), nav, 0.18)


@pytest.mark.parametrize(("width", "joined"), [(1, False), (2, False), (3, True), (4, True)])
def test_passable_parts_close_passages_narrower_than_three_cells(width: int, joined: bool) -> None:
    parts = _two_rooms(width).passable_parts()
    left, right = parts[5, 5], parts[5, 20]
    assert left > 0 and right > 0
    assert bool(left == right) is joined
    assert (parts[1:11, 1:11] == left).all(), "a room keeps every cell, walls included"


@pytest.mark.parametrize("split", SPLITS)
def test_every_checked_in_start_reaches_its_goal_through_a_passable_part(split: str) -> None:
    grids: dict[str, tuple[NavGrid, np.ndarray]] = {}
    for be in load_split(split, "objectnav"):
        if be.scene not in grids:
            grid = bench_grid(be.layout_path)
            grids[be.scene] = (grid, grid.passable_parts())
        grid, parts = grids[be.scene]
        layout = bench_layout(be.layout_path)
        goals = goal_cells(grid, [layout.object(i) for i in be.episode.goal_object_ids], 1.0)
        start = parts[grid.cell_of(*be.episode.start_position)]
        assert start > 0 and start in set(parts[goals].tolist()), be.episode_id


def test_the_splits_never_share_a_scene_and_use_their_seed_ranges() -> None:
    tune = set(SPLIT_SPECS["tune"].seeds)
    bench = set(SPLIT_SPECS["bench"].seeds)
    assert not tune & bench
    assert all(1000 <= s <= 1099 for s in tune) and all(s >= 2000 for s in bench)
    layouts = {
        split: {bench_layout(be.layout_path).name for be in load_split(split, "objectnav")}
        for split in SPLITS
    }
    assert len(layouts["bench"]) >= 10 and not layouts["tune"] & layouts["bench"]


@pytest.mark.parametrize("task", TASKS)
def test_the_bench_split_has_200_long_episodes_per_task(task: str) -> None:
    episodes = load_split("bench", task)
    dist = np.array([be.episode.geodesic_distance for be in episodes])
    assert len(episodes) >= 200
    assert np.median(dist) >= 6.0 and dist.max() >= 12.0
    assert len({be.episode_id for be in episodes}) == len(episodes)


def test_every_checked_in_start_of_a_scene_is_out_of_sight_of_its_goal() -> None:
    episodes = [be for be in load_split("bench", "objectnav") if be.scene == "s02"]
    layout, grid = bench_layout(episodes[0].layout_path), bench_grid(episodes[0].layout_path)
    sight = SightChecker(layout, grid)
    for be in episodes:
        start = np.array(be.episode.start_position)
        assert not sight.in_sight_reference(start, be.episode.goal_object_ids)
        assert grid.navigable_at(*be.episode.start_position)


def test_sight_is_blocked_by_walls_and_tall_objects_but_not_by_low_furniture() -> None:
    layout = generate_apartment(4)
    sight = SightChecker(layout, build_nav_grid(layout))
    fridge = next(o for o in layout.objects if o.top >= 1.2 and o.position[2] < 0.5)
    assert (sight.blockers == fridge.id).any()
    low = next(o for o in layout.objects if o.top < 0.6 and o.position[2] == 0)
    assert not (sight.blockers == low.id).any()
    assert (sight.blockers == -1).any()
    rng = np.random.default_rng(0)
    cells = np.argwhere(sight.grid.navigable)
    goal = (low.id,)
    seen = []
    for r, c in cells[rng.choice(len(cells), 60, replace=False)]:
        xy = sight.grid.to_world(np.array([[r, c]]))[0]
        fast = sight.in_sight(xy, goal)
        assert fast == sight.in_sight_reference(xy, goal)
        seen.append(fast)
    assert any(seen) and not all(seen), "some points see the object and some do not"


def test_hidden_episodes_are_deterministic_and_start_out_of_sight() -> None:
    layout = generate_apartment(4)
    a = hidden_episodes(layout, "objectnav", 6, seed=3)
    b = hidden_episodes(layout, "objectnav", 6, seed=3)
    assert a == b
    sight = SightChecker(layout, build_nav_grid(layout))
    for e in a.episodes:
        assert not sight.in_sight(np.array(e.start_position), e.goal_object_ids)
        assert e.geodesic_distance >= 2.0


def test_bench_episode_finds_an_id_and_suggests_the_closest_on_a_miss() -> None:
    be = bench_episode("bench/objectnav/s03-017")
    assert (be.split, be.task, be.scene, be.episode.episode_id) == ("bench", "objectnav", "s03", 17)
    with pytest.raises(UnknownIdError, match="bench/objectnav/s03-017"):
        bench_episode("bench/objectnav/s03-0017")
    with pytest.raises(UnknownIdError, match="<split>/<task>"):
        bench_episode("objectnav/s03-017")
    with pytest.raises(InvalidInputError, match="Did you mean 'bench'"):
        load_split("bencj", "objectnav")


def test_a_benchmark_env_starts_at_the_episode_start_and_scores_it() -> None:
    be = load_split("tune", "instnav")[3]
    env = make_env(be, CameraSpec(160, 120), max_steps=5)
    try:
        obs, info = env.reset(seed=0, options={"episode": be.episode})
        assert obs["goal"] == be.episode.goal_text
        assert np.allclose(info["position"], be.episode.start_position)
        assert info["distance_to_goal"] == pytest.approx(be.episode.geodesic_distance, abs=1e-4)
        assert env.max_steps == 5
    finally:
        env.close()


def test_a_benchmark_env_plays_with_the_split_s_perception_unless_told_otherwise() -> None:
    # The bench loops and the replay check build their envs here: a house episode must see
    # what `glmap eval` and the server's simulator see (the detector), not exact labels.
    house = load_split("house-tune", "objectnav")[0]
    assert house.perception == "detector"
    for perception, want in ((None, "detector"), ("gt", "gt")):
        env = make_env(house, CameraSpec(32, 24), max_steps=2, perception=perception)
        try:
            assert env.perception == want
        finally:
            env.close()
    env = make_env(load_split("tune", "objectnav")[0], CameraSpec(32, 24), max_steps=2)
    try:
        assert env.perception == "gt"
    finally:
        env.close()


def test_the_oracle_solves_benchmark_episodes_within_the_step_limit() -> None:
    from glmap_tools.sim.agents import OracleAgent

    episodes = load_split("bench", "instnav")
    longest = max(episodes, key=lambda be: be.episode.geodesic_distance)
    env = make_env(longest, CameraSpec(32, 24))
    try:
        obs, info = env.reset(seed=0, options={"episode": longest.episode})
        agent = OracleAgent(env)
        terminated = truncated = False
        while not (terminated or truncated):
            obs, _, terminated, truncated, info = env.step(agent.act(obs))
        assert info["success"] and info["spl"] > 0.8, (longest.episode_id, info["spl"])
        assert info["steps"] < 500
    finally:
        env.close()


def test_a_single_open_room_has_no_hidden_start_and_says_so() -> None:
    from glmap_tools.sim.layout_io import layout_from_dict

    layout = layout_from_dict(
        {
            "name": "open room",
            "rooms": [{"id": 1, "type": "room", "polygon": [[0, 0], [8, 0], [8, 6], [0, 6]]}],
            "objects": [
                {"id": 1, "category": "sofa", "mesh": "kenney/loungeSofa",
                 "position": [2.0, 1.0, 0.0], "heading": 1.5708},
                {"id": 2, "category": "table", "mesh": "primitive/table",
                 "position": [6.0, 4.5, 0.0]},
            ],
        }
    )  # fmt: skip
    with pytest.raises(InvalidInputError, match="no start out of sight"):
        hidden_episodes(layout, "objectnav", 3, seed=0, tries=20)


def test_books_on_a_tall_bookcase_are_in_sight_in_front_of_it_but_not_behind_a_wall() -> None:
    from glmap_tools.sim.layout_io import layout_from_dict

    layout = layout_from_dict(
        {
            "rooms": [
                {"id": 1, "type": "office", "polygon": [[0, 0], [6, 0], [6, 4], [0, 4]]},
                {"id": 2, "type": "hallway", "polygon": [[6, 0], [9, 0], [9, 4], [6, 4]]},
            ],
            "openings": [{"id": 1, "rooms": [1, 2], "center": [6, 0.7], "width": 0.9}],
            "objects": [
                {"id": 1, "category": "bookcase", "mesh": "kenney/bookcaseOpen",
                 "position": [3.0, 3.75, 0.0], "heading": -1.5708},
                {"id": 2, "category": "books", "mesh": "kenney/books",
                 "position": [3.0, 3.75, 1.0], "supported_by": 1},
            ],
        }
    )  # fmt: skip
    sight = SightChecker(layout, build_nav_grid(layout))
    assert (sight.blockers == 1).any(), "the bookcase is tall enough to block"
    for xy, seen in (([3.0, 1.5], True), ([7.5, 3.0], False)):
        assert sight.in_sight(np.array(xy), (2,)) is seen
        assert sight.in_sight_reference(np.array(xy), (2,)) is seen
