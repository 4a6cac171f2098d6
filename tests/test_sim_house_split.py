"""The house splits: HM3D goal categories, InstNav among same-category instances, reachable
goals, a perception default, and files that regenerate as checked in."""

from __future__ import annotations

import collections
import json
import os

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

import numpy as np
import pytest

from glmap_tools.errors import InvalidInputError
from glmap_tools.sim.episodes import TASKS, episodes_to_dict, goal_distance_field, goal_pool
from glmap_tools.sim.layout_io import layout_to_dict
from glmap_tools.worlds.clutter import GOAL_CATEGORIES, unlikely_categories
from glmap_tools.worlds.scene_dirs import read_scene_episodes
from glmap_tools.worlds.splits import (
    SPLIT_SPECS,
    bench_episode,
    bench_grid,
    bench_layout,
    goal_weights,
    load_split,
    make_layout,
    scene_episodes,
    split_dir,
    split_perception,
)

HOUSE_SPLITS = ("house-tune", "house-bench")


@pytest.mark.parametrize("split", HOUSE_SPLITS)
def test_a_house_split_has_its_scenes_and_20_episodes_per_task_per_scene(split: str) -> None:
    spec = SPLIT_SPECS[split]
    assert len(spec.seeds) == (4 if split == "house-tune" else 12)
    for task in TASKS:
        per_scene = collections.Counter(be.scene for be in load_split(split, task))
        assert len(per_scene) == len(spec.seeds)
        assert set(per_scene.values()) == {20}
    names = {bench_layout(be.layout_path).name for be in load_split(split, "objectnav")}
    assert all(n.startswith("house-") for n in names)


def test_house_splits_share_no_scene_with_each_other_or_the_regression_splits() -> None:
    seeds = [set(spec.seeds) for spec in SPLIT_SPECS.values()]
    assert sum(len(s) for s in seeds) == len(set().union(*seeds))


@pytest.mark.parametrize("split", HOUSE_SPLITS)
def test_a_house_split_is_played_with_detector_perception_by_default(split: str) -> None:
    assert split_perception(split) == "detector"
    assert split_perception("bench") == "gt"
    manifest = json.loads((split_dir(split) / "split.json").read_text())
    assert manifest["perception"] == "detector" and manifest["generator"]["house"] is True


@pytest.mark.parametrize("split", HOUSE_SPLITS)
def test_objectnav_goals_include_the_six_hm3d_categories(split: str) -> None:
    goals = collections.Counter(be.episode.goal_text for be in load_split(split, "objectnav"))
    assert set(GOAL_CATEGORIES) <= set(goals), goals
    share = sum(goals[c] for c in GOAL_CATEGORIES) / sum(goals.values())
    assert 0.45 <= share <= 0.75, share  # hm3d_share = 0.6


@pytest.mark.parametrize("split", HOUSE_SPLITS)
def test_most_instnav_targets_have_another_object_of_their_category(split: str) -> None:
    multi, total = 0, 0
    for be in load_split(split, "instnav"):
        layout = bench_layout(be.layout_path)
        (target,) = be.episode.goal_object_ids
        category = layout.object(target).category
        multi += sum(o.category == category for o in layout.objects) >= 2
        total += 1
        # Described by attributes and a relation that singles the target out.
        assert be.episode.goal_text.startswith("the ")
        assert any(w in be.episode.goal_text for w in (" next to ", " on the ", " in the "))
    assert multi / total >= 0.6, (multi, total)


@pytest.mark.parametrize("split", HOUSE_SPLITS)
@pytest.mark.parametrize("task", TASKS)
def test_every_house_episode_reaches_its_goal_from_at_least_2_m(split: str, task: str) -> None:
    fields: dict[tuple[object, ...], np.ndarray] = {}
    for be in load_split(split, task):
        layout, grid = bench_layout(be.layout_path), bench_grid(be.layout_path)
        goals = [layout.object(i) for i in be.episode.goal_object_ids]
        key = (be.layout_path, be.episode.goal_object_ids)
        if key not in fields:
            fields[key] = goal_distance_field(grid, goals, 1.0)
        field = fields[key]
        d = field[grid.cell_of(*be.episode.start_position)]
        assert np.isfinite(d) and d >= 2.0, be.episode_id
        assert d == pytest.approx(be.episode.geodesic_distance, abs=1e-3), be.episode_id
        if task == "objectnav":
            assert {g.category for g in goals} == {be.episode.goal_text}


def test_the_house_splits_hold_unlikely_goal_objects() -> None:
    hits = rooms = 0
    for split in HOUSE_SPLITS:
        for path in {be.layout_path for be in load_split(split, "objectnav")}:
            layout = bench_layout(path)
            rooms += len(layout.rooms)
            hits += len(
                {
                    o.room
                    for o in layout.objects
                    if o.category in unlikely_categories(layout.room(o.room).type)
                }
            )
    assert 0.05 <= hits / rooms <= 0.3, (hits, rooms)


def test_regenerating_a_house_scene_reproduces_its_checked_in_files() -> None:
    spec = SPLIT_SPECS["house-tune"]
    folder = split_dir("house-tune") / "s02"
    layout = make_layout(spec, spec.seeds[2])
    assert layout_to_dict(layout) == json.loads((folder / "layout.json").read_text())
    for task in TASKS:
        episodes = scene_episodes(spec, spec.seeds[2], layout, task)
        assert episodes_to_dict(episodes) == json.loads((folder / f"{task}.json").read_text())


def test_goal_weights_give_each_group_its_share_and_leave_the_old_splits_uniform() -> None:
    be = bench_episode("house-tune/objectnav/s00-000")
    layout, grid = bench_layout(be.layout_path), bench_grid(be.layout_path)
    pool = goal_pool(layout, "objectnav", grid, 1.0, 2.0, seeable_only=True)
    weights = goal_weights(layout, "objectnav", pool, SPLIT_SPECS["house-tune"])
    assert weights is not None and weights.sum() == pytest.approx(1.0)
    hm3d = np.array([text in GOAL_CATEGORIES for text, _, _ in pool])
    assert weights[hm3d].sum() == pytest.approx(0.6)
    assert goal_weights(layout, "objectnav", pool, SPLIT_SPECS["bench"]) is None


def test_every_episode_carries_its_split_perception_and_a_scene_folder_may_name_one(
    tmp_path,
) -> None:
    assert {be.perception for be in load_split("house-tune", "objectnav")} == {"detector"}
    assert {be.perception for be in load_split("tune", "objectnav")} == {"gt"}
    scene = tmp_path / "mine" / "a"
    scene.mkdir(parents=True)
    source = split_dir("house-tune") / "s00"
    for name in ("layout.json", "objectnav.json"):
        (scene / name).write_text((source / name).read_text())
    folder = tmp_path / "mine"
    assert {be.perception for be in load_split("mine", "objectnav", {"mine": folder})} == {"gt"}
    (folder / "split.json").write_text(json.dumps({"perception": "detector"}))
    read_scene_episodes.cache_clear()
    assert {be.perception for be in load_split("mine", "objectnav", {"mine": folder})} == {
        "detector"
    }
    (folder / "split.json").write_text(json.dumps({"perception": "noisy"}))
    read_scene_episodes.cache_clear()
    with pytest.raises(InvalidInputError, match="'noisy' is not one of"):
        load_split("mine", "objectnav", {"mine": folder})
