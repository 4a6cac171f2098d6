"""The fixed navigation benchmark: large generated apartments and checked-in episode files.

Two splits that never share a scene: "tune" (scene seeds 1000-1099, for tuning thresholds)
and "bench" (seeds 2000+, for the reported figures). Apartments are large: rooms of 1.3x the
usual area lined up along a hallway that runs the apartment's length
(`generate_apartment(..., area_scale, hallway=True)`). Since issue 38 these two are the
regression set; the house splits "house-tune" (seeds 3000+) and "house-bench" (seeds 4000+)
hold houses (`generate_house`: 8-12 rooms, repeated room types, clutter, goal objects in
unlikely rooms), ObjectNav goals weighted towards HM3D's six categories
(`SplitSpec.hm3d_share`), InstNav goals mostly among same-category instances
(`SplitSpec.multi_share`), and a `perception` default ("detector") in `split.json`. Every
episode:

- starts on navigable floor at least `MIN_GEODESIC` metres (geodesic) from the goal;
- starts out of sight of every goal object (`sight.SightChecker`: walls and tall objects
  block, the agent may look all around);
- reaches a goal through passages at least `MIN_PASSAGE_CELLS` (3) navigable cells wide
  (`NavGrid.passable_parts`): a start joined to its goal only by a one-cell sliver between
  furniture, which a discrete-action agent cannot follow, is drawn again;
- succeeds when the agent stops within `SUCCESS_DISTANCE` (1 m) of a goal object's
  footprint *surface* (the planar distance from the agent's centre to the nearest point of
  the footprint rectangle, 0 inside it), not its centre, within `MAX_STEPS` (500) steps.

Files (`glmap_tools/data/benchmark/<split>/`): `split.json` (seeds, generator parameters,
the command), and per scene `sNN/layout.json` (through `layout_io`, so later generator
changes cannot move the benchmark) with `sNN/objectnav.json` and `sNN/instnav.json`
(`episodes.py` episode sets). Regenerate (deterministic)::

    python -m glmap_tools.worlds.splits --out glmap_tools/data/benchmark
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from glmap_tools.errors import InvalidInputError, UnknownIdError, did_you_mean
from glmap_tools.sim.episodes import (
    SUCCESS_DISTANCE,
    TASKS,
    Episode,
    EpisodeSet,
    episodes_to_dict,
    goal_pool,
)
from glmap_tools.sim.layout import Layout
from glmap_tools.sim.layout_io import layout_to_dict, load_layout
from glmap_tools.sim.navgrid import MIN_PASSAGE_CELLS, NavGrid, build_nav_grid
from glmap_tools.sim.sight import SightChecker
from glmap_tools.worlds.clutter import GOAL_CATEGORIES, UNLIKELY_RATE
from glmap_tools.worlds.scene_dirs import (
    BUILT_IN_SPLITS,
    BenchEpisode,
    SceneDirs,
    read_scene_episodes,
    scene_dir_episode,
    scene_dir_episodes,
    split_perception_of,
)
from glmap_tools.worlds.split_specs import SPLIT_SPECS, SplitSpec, goal_weights, make_layout

if TYPE_CHECKING:  # importing env pulls in the renderer
    from glmap_tools.sim.env import NavEnv
    from glmap_tools.sim.render import CameraSpec

# Imports inside functions stay there: cv2, gaussians, language.embed, pyrender, numba load on first
# use.

SPLITS = BUILT_IN_SPLITS  # ("tune", "bench", "house-tune", "house-bench")
DATA_ROOT = Path(__file__).resolve().parent.parent / "data" / "benchmark"
MAX_STEPS = 500
MIN_GEODESIC = 2.0  # metres from start to the nearest goal cell
START_TRIES = 400  # starts drawn per episode before its goal is given up
COMMAND = "python -m glmap_tools.worlds.splits --out glmap_tools/data/benchmark"


def _check_split(split: str) -> None:
    if split not in SPLITS:
        raise InvalidInputError(
            f"split {split!r} is not one of {SPLITS}.{did_you_mean(split, SPLITS)}"
        )


def _check_task(task: str) -> None:
    if task not in TASKS:
        raise InvalidInputError(f"task {task!r} is not one of {TASKS}.{did_you_mean(task, TASKS)}")


def scene_name(index: int) -> str:
    return f"s{index:02d}"


def hidden_episodes(
    layout: Layout,
    task: str,
    count: int,
    seed: int,
    grid: NavGrid | None = None,
    min_distance: float = MIN_GEODESIC,
    tries: int = START_TRIES,
    spec: SplitSpec | None = None,
) -> EpisodeSet:
    """`count` episodes whose starts are out of sight of every goal object (deterministic).

    Goals are drawn uniformly from the task's reachable goals, starts uniformly from the
    navigable cells at least `min_distance` geodesic metres away; a start with a goal in
    sight, or joined to every goal cell only through a passage narrower than
    `MIN_PASSAGE_CELLS` (`NavGrid.passable_parts`), is drawn again. A house split's `spec`
    weights the goals (`goal_weights`) and keeps only seeable ones.

    Raises:
        InvalidInputError: more than twice as many goals in a row as there are goals found
            no hidden start in `tries` draws each; a bad task or count.
    """
    _check_task(task)
    if isinstance(count, bool) or not isinstance(count, int) or count < 1:
        raise InvalidInputError(f"count={count!r} must be a positive integer.")
    grid = grid or build_nav_grid(layout)
    sight = SightChecker(layout, grid)
    seeable = spec is not None and spec.seeable_only
    pool = goal_pool(layout, task, grid, SUCCESS_DISTANCE, min_distance, seeable)
    weights = goal_weights(layout, task, pool, spec) if spec is not None else None
    starts = [np.argwhere(np.isfinite(f) & (f >= min_distance)) for _, _, f in pool]
    parts = grid.passable_parts()
    goal_parts = [set(np.unique(parts[(f == 0) & (parts > 0)]).tolist()) for _, _, f in pool]
    rng = np.random.default_rng([int(seed), TASKS.index(task), 11])
    episodes: list[Episode] = []
    misses = 0

    def hidden_start(g: int, draw: np.random.Generator) -> tuple[int, int] | None:
        for _ in range(tries):
            r, c = starts[g][int(draw.integers(len(starts[g])))]
            if not sight.in_sight(grid.to_world(np.array([[r, c]]))[0], pool[g][1]):
                return int(r), int(c)
        return None

    while len(episodes) < count:
        g = _draw_goal(rng, len(pool), weights)
        cell = hidden_start(g, rng)
        if cell is not None and int(parts[cell]) not in goal_parts[g]:
            # Joined to the goal only through a sliver the agent cannot follow: draw the
            # start again from a stream of this episode's own, so that the episodes after
            # it stay as they were before the check existed.
            own = np.random.default_rng([int(seed), TASKS.index(task), 11, len(episodes)])
            for _ in range(tries):
                cell = hidden_start(g, own)
                if cell is None or int(parts[cell]) in goal_parts[g]:
                    break
            else:
                cell = None
        if cell is None:
            misses += 1  # every draw saw the goal: draw another goal
            if misses > 2 * len(pool):
                raise InvalidInputError(
                    f"layout {layout.name!r}: no start out of sight of its {task} goals after "
                    f"{misses} goals x {tries} draws; add walls or rooms, or lower "
                    "min_distance."
                )
            continue
        misses = 0
        episodes.append(_episode(len(episodes), task, grid, cell, rng, pool[g]))
    return EpisodeSet(task, layout.name, layout.seed, episodes, SUCCESS_DISTANCE)


def _draw_goal(rng: np.random.Generator, goals: int, weights: np.ndarray | None) -> int:
    """A goal index: uniform, or with the given weights ([goals], summing to 1)."""
    return int(rng.integers(goals)) if weights is None else int(rng.choice(goals, p=weights))


def _episode(
    episode_id: int,
    task: str,
    grid: NavGrid,
    cell: tuple[int, int],
    rng: np.random.Generator,
    goal: tuple[str, tuple[int, ...], np.ndarray],
) -> Episode:
    """The episode starting at `cell` (row, column) with a random heading, towards `goal`
    (its text, object ids and geodesic field [rows, cols] in metres)."""
    text, ids, field = goal
    xy = grid.to_world(np.array([cell]))[0]
    return Episode(
        episode_id=episode_id,
        task=task,
        start_position=(round(float(xy[0]), 4), round(float(xy[1]), 4)),
        start_heading=round(float(rng.uniform(-math.pi, math.pi)), 5),
        goal_text=text,
        goal_object_ids=ids,
        geodesic_distance=round(float(field[cell]), 4),
    )


def scene_episodes(spec: SplitSpec, seed: int, layout: Layout, task: str) -> EpisodeSet:
    """The split's episode set of one scene and task (what `sNN/<task>.json` holds)."""
    return hidden_episodes(layout, task, spec.episodes_per_scene, seed, spec=spec)


def _dump(data: dict[str, Any]) -> str:
    return json.dumps(data, separators=(",", ":")) + "\n"


def write_split(split: str, out: Path) -> tuple[dict[str, list[EpisodeSet]], dict[str, Layout]]:
    """Generate and write one split under `out/<split>/`.

    Returns:
        (episode sets by task, layouts by layout name).
    """
    _check_split(split)
    spec = SPLIT_SPECS[split]
    folder = out / split
    sets: dict[str, list[EpisodeSet]] = {t: [] for t in TASKS}
    layouts: dict[str, Layout] = {}
    scenes = []
    for index, seed in enumerate(spec.seeds):
        layout = make_layout(spec, seed)
        layouts[layout.name] = layout
        scene_dir = folder / scene_name(index)
        scene_dir.mkdir(parents=True, exist_ok=True)
        (scene_dir / "layout.json").write_text(_dump(layout_to_dict(layout)), encoding="utf-8")
        for task in TASKS:
            episode_set = scene_episodes(spec, seed, layout, task)
            (scene_dir / f"{task}.json").write_text(
                _dump(episodes_to_dict(episode_set)), encoding="utf-8"
            )
            sets[task].append(episode_set)
        scenes.append({"scene": scene_name(index), "seed": seed, "layout": layout.name})
    generator: dict[str, Any] = {
        "area_scale": spec.area_scale,
        "hallway": spec.hallway,
        "n_rooms": "6 + seed % 2",
    }
    if spec.house:
        generator = {
            "house": True,
            "area_scale": spec.area_scale,
            "n_rooms": "7-11 + hallway",
            "unlikely_rate": UNLIKELY_RATE,
        }
    manifest = {
        "format": "glmap-sim-benchmark",
        "version": 1,
        "split": split,
        "command": COMMAND,
        "generator": generator,
        **({"perception": spec.perception} if spec.house else {}),
        **({"goals": {"hm3d_share": spec.hm3d_share, "hm3d_categories": list(GOAL_CATEGORIES),
                      "instnav_multi_share": spec.multi_share,
                      "seeable_only": spec.seeable_only}} if spec.house else {}),
        "episodes_per_scene": spec.episodes_per_scene,
        "min_geodesic": MIN_GEODESIC,
        "min_passage_cells": MIN_PASSAGE_CELLS,
        "success_distance": SUCCESS_DISTANCE,
        "success": "stop within success_distance of a goal footprint's surface",
        "max_steps": MAX_STEPS,
        "scenes": scenes,
    }  # fmt: skip
    (folder / "split.json").write_text(json.dumps(manifest, indent=1) + "\n", encoding="utf-8")
    return sets, layouts


def split_statistics(sets: list[EpisodeSet], layouts: dict[str, Layout]) -> dict[str, Any]:
    """Median/p90/max geodesic metres, episodes per scene and goal categories of a task."""
    dist = np.array([e.geodesic_distance for s in sets for e in s.episodes])
    categories: dict[str, int] = {}
    for s in sets:
        for e in s.episodes:
            cat = layouts[s.scene].object(e.goal_object_ids[0]).category
            categories[cat] = categories.get(cat, 0) + 1
    return {
        "episodes": int(len(dist)),
        "scenes": len(sets),
        "episodes_per_scene": sorted({len(s.episodes) for s in sets}),
        "geodesic_median": round(float(np.median(dist)), 2),
        "geodesic_p90": round(float(np.percentile(dist, 90)), 2),
        "geodesic_max": round(float(dist.max()), 2),
        "geodesic_min": round(float(dist.min()), 2),
        "share_over_12m": round(float((dist >= 12.0).mean()), 3),
        "categories": dict(sorted(categories.items(), key=lambda kv: (-kv[1], kv[0]))),
    }


# ---------------------------------------------------------------------- reading the files
def split_dir(split: str, root: Path | None = None) -> Path:
    _check_split(split)
    return (root or DATA_ROOT) / split


def split_perception(split: str) -> str:
    """The perception a built-in split is played with by default: its `split.json`'s
    "perception" ("detector" for the house splits), "gt" where the file has none (each
    `BenchEpisode.perception` carries it too)."""
    _manifest(split)  # a missing split.json says how to regenerate it
    return split_perception_of(split_dir(split))


@functools.lru_cache(maxsize=8)
def _manifest(split: str) -> dict[str, Any]:
    path = split_dir(split) / "split.json"
    if not path.exists():
        raise InvalidInputError(f"{path} is missing; regenerate the benchmark with `{COMMAND}`.")
    data: dict[str, Any] = json.loads(path.read_text(encoding="utf-8"))
    return data


def _split_task(split: str, task: str) -> tuple[BenchEpisode, ...]:
    scenes = tuple(s["scene"] for s in _manifest(split)["scenes"])
    return read_scene_episodes(split_dir(split), split, task, scenes)


def load_split(split: str, task: str, scene_dirs: SceneDirs | None = None) -> list[BenchEpisode]:
    """Every episode of `task` in `split` (a built-in split, or a folder of `scene_dirs`
    by its name), in scene then episode order."""
    _check_task(task)
    if scene_dirs and split in scene_dirs:
        return list(scene_dir_episodes(split, scene_dirs[split], task))
    _check_split(split)
    return list(_split_task(split, task))


def bench_episode(episode_id: str, scene_dirs: SceneDirs | None = None) -> BenchEpisode:
    """The episode with this id ("bench/objectnav/s03-017"), of a built-in split or of a
    scene folder of `scene_dirs` ("mine/objectnav/kitchen-003").

    Raises:
        UnknownIdError: no such episode (with the closest id).
    """
    parts = str(episode_id).split("/")
    if scene_dirs and parts[0] in scene_dirs:
        return scene_dir_episode(episode_id, scene_dirs)
    if len(parts) != 3 or parts[0] not in SPLITS or parts[1] not in TASKS:
        raise UnknownIdError(
            f"episode id {episode_id!r} is not '<split>/<task>/<scene>-<index>' with split in "
            f"{[*SPLITS, *(scene_dirs or ())]} and task in {TASKS}, e.g. "
            "'bench/objectnav/s03-017'; a scene folder's episodes need the folder given to "
            "the server (glmap-mcp --scenes-dir NAME=DIR)."
        )
    episodes = {be.episode_id: be for be in _split_task(parts[0], parts[1])}
    if episode_id not in episodes:
        raise UnknownIdError(
            f"no benchmark episode {episode_id!r}.{did_you_mean(episode_id, episodes)} "
            f"{parts[0]}/{parts[1]} has {len(episodes)} episodes."
        )
    return episodes[episode_id]


@functools.lru_cache(maxsize=16)
def bench_layout(layout_path: Path) -> Layout:
    """The layout of a benchmark scene (read once per process)."""
    return load_layout(layout_path)


@functools.lru_cache(maxsize=16)
def bench_grid(layout_path: Path) -> NavGrid:
    """The navigation grid of a benchmark scene (built once per process)."""
    return build_nav_grid(bench_layout(layout_path))


def make_env(
    bench: BenchEpisode,
    camera: CameraSpec | None = None,
    max_steps: int = MAX_STEPS,
    perception: str | None = None,
) -> NavEnv:
    """An environment on the episode's scene with `perception` ('gt' | 'detector'; None:
    the split's own, `bench.perception`); start it with
    `env.reset(seed=..., options={"episode": bench.episode})`."""
    from glmap_tools.sim.env import InstNavEnv, ObjectNavEnv

    env_cls = ObjectNavEnv if bench.task == "objectnav" else InstNavEnv
    return env_cls(
        layout=bench_layout(bench.layout_path),
        camera=camera,
        max_steps=max_steps,
        grid=bench_grid(bench.layout_path),
        perception=perception or bench.perception,
    )


# ---------------------------------------------------------------------- command line
def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m glmap_tools.worlds.splits",
        description="Regenerate the benchmark split files (deterministic) and print statistics.",
    )
    parser.add_argument("--out", type=Path, required=True, help="folder that gets <split>/")
    parser.add_argument("--split", choices=[*SPLITS, "all"], default="all")
    args = parser.parse_args(argv)
    for split in SPLITS if args.split == "all" else (args.split,):
        spec = SPLIT_SPECS[split]
        sets, layouts = write_split(split, args.out)
        print(
            f"split {split}: scene seeds {spec.seeds[0]}-{spec.seeds[-1]}, {len(spec.seeds)} scenes"
        )
        for task in TASKS:
            st = split_statistics(sets[task], layouts)
            cats = ", ".join(f"{k} {v}" for k, v in st.pop("categories").items())
            print(f"  {task}: " + ", ".join(f"{k} {v}" for k, v in st.items()))
            print(f"    goal categories: {cats}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
