"""Navigation episodes: seeded generation, JSON episode sets, validation against a layout.

An episode is a start (position, heading) and a goal: every instance of a category
(ObjectNav) or one instance named by a unique description (InstNav). Success means stopping
within `success_distance` metres of a goal object's footprint surface with no wall in
between (`reach.py`). `geodesic_distance` is the shortest path on the navigable grid from
the start to the goal cells (the navigable cells within `success_distance - cell` of a goal
footprint and on its side of the walls, so standing in one is a success).
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from glmap_tools.errors import InvalidInputError, UnknownIdError, did_you_mean
from glmap_tools.sim.instnav import instance_goals
from glmap_tools.sim.jsonfile import read_json
from glmap_tools.sim.layout import Layout, SceneObject
from glmap_tools.sim.navgrid import NavGrid, build_nav_grid
from glmap_tools.sim.reach import clear_of_walls_reference, nearest_footprint_points, reaches

FORMAT = "glmap-sim-episodes"
VERSION = 1
TASKS = ("objectnav", "instnav")
SUCCESS_DISTANCE = 1.0  # metres
MAX_PASSAGE_CELLS = 100  # 5 m of free floor at 5 cm: wider than any passage of a home
MIN_START_DISTANCE = 1.5  # metres of geodesic distance from start to goal


@dataclass(frozen=True)
class Difficulty:
    """How hard an episode is (`glmap_tools.worlds.difficulty.DifficultyMeter` measures it).

    Attributes:
        geodesic_m: shortest navigable path from the start to a goal cell, metres.
        passage_cells: the narrowest passage the agent must pass: the largest width w
            (navigable cells of the agent's centre) with start and goal joined in
            `NavGrid.passable_parts(w)`; capped at `difficulty.MAX_PASSAGE_CELLS` (then: at
            least that).
        passage_m: that passage as a gap between obstacles, metres: passage_cells x cell +
            the agent's diameter.
        goal_in_sight: a goal object is in sight from the start (`sight.SightChecker`).
    """

    geodesic_m: float
    passage_cells: int
    passage_m: float
    goal_in_sight: bool


@dataclass(frozen=True)
class Episode:
    """One navigation episode (with its difficulty when measured)."""

    episode_id: int
    task: str
    start_position: tuple[float, float]
    start_heading: float
    goal_text: str
    goal_object_ids: tuple[int, ...]
    geodesic_distance: float
    difficulty: Difficulty | None = None


@dataclass(frozen=True)
class EpisodeSet:
    """Episodes of one task in one scene."""

    task: str
    scene: str
    scene_seed: int | None
    episodes: list[Episode]
    success_distance: float = SUCCESS_DISTANCE


def goal_cells(
    grid: NavGrid, targets: Sequence[SceneObject], success_distance: float
) -> np.ndarray:
    """[H, W] bool navigable cells whose centre reaches a target (`reach.reaches`).

    A cell reaches a target when its centre is within `success_distance - cell` of the
    target's footprint with no wall in between. Only the window around each footprint
    (grown by the reach) is measured, so the cost does not grow with the apartment.
    """
    near = np.zeros(grid.shape, dtype=bool)
    reach = success_distance - grid.cell
    h, w = grid.shape
    for obj in targets:
        corners = obj.footprint()
        (r0, c0), (r1, c1) = grid.to_cell(
            np.stack([corners.min(0) - reach, corners.max(0) + reach])
        )
        r0, c0 = max(int(r0), 0), max(int(c0), 0)
        r1, c1 = min(int(r1) + 1, h - 1), min(int(c1) + 1, w - 1)
        if r0 > r1 or c0 > c1:
            continue
        rows, cols = np.mgrid[r0 : r1 + 1, c0 : c1 + 1]
        pts = grid.to_world(np.column_stack([rows.ravel(), cols.ravel()]))
        inside = reaches(grid, obj, pts, reach).reshape(rows.shape)
        near[r0 : r1 + 1, c0 : c1 + 1] |= inside
    return near & grid.navigable


def goal_cells_reference(
    grid: NavGrid, targets: Sequence[SceneObject], success_distance: float
) -> np.ndarray:
    """Slow reference of `goal_cells`: every cell of the grid, one wall check at a time."""
    xs, ys = grid.cell_centers()
    pts = np.column_stack([xs.ravel(), ys.ravel()])
    near = np.zeros(len(pts), dtype=bool)
    for obj in targets:
        for i in np.nonzero(obj.distance_to(pts) <= success_distance - grid.cell)[0]:
            end = nearest_footprint_points(obj, pts[i][None])[0]
            near[i] |= clear_of_walls_reference(grid, pts[i], end)
    return near.reshape(grid.shape) & grid.navigable


def goal_distance_field(
    grid: NavGrid, targets: Sequence[SceneObject], success_distance: float = SUCCESS_DISTANCE
) -> np.ndarray:
    """[H, W] geodesic metres to the nearest goal cell (inf where unreachable)."""
    return grid.distance_field(goal_cells(grid, targets, success_distance))


GoalPool = list[tuple[str, tuple[int, ...], np.ndarray]]  # (text, object ids, field)


MIN_GOAL_SIZE = 0.15  # m: a goal whose largest side is shorter is too small to recognise
MAX_GOAL_BOTTOM = 1.8  # m: a goal starting higher leaves the 0.88 m camera's view ~1 m away


def unseeable(obj: SceneObject) -> str | None:
    """Why the agent's camera cannot be expected to recognise `obj` as a goal, or None."""
    if float(np.max(obj.size)) < MIN_GOAL_SIZE:
        return f"{float(np.max(obj.size)):.2f} m at most, under {MIN_GOAL_SIZE} m"
    if float(obj.position[2]) > MAX_GOAL_BOTTOM:
        return f"its bottom is {float(obj.position[2]):.2f} m up, over {MAX_GOAL_BOTTOM} m"
    return None


def goal_pool(
    layout: Layout,
    task: str,
    grid: NavGrid,
    success_distance: float = SUCCESS_DISTANCE,
    min_distance: float = MIN_START_DISTANCE,
    seeable_only: bool = False,
) -> GoalPool:
    """Every goal of `task` that is reachable from somewhere at least `min_distance` away;
    with `seeable_only`, of the objects the camera can be expected to recognise
    (`unseeable`)."""
    if task not in TASKS:
        raise InvalidInputError(f"task {task!r} is not one of {TASKS}.{did_you_mean(task, TASKS)}")
    if task == "objectnav":
        candidates = [
            (c, tuple(o.id for o in layout.objects if o.category == c)) for c in layout.categories
        ]
    else:
        candidates = [(text, (i,)) for i, text in instance_goals(layout).items()]
    if seeable_only:
        candidates = [
            (text, kept)
            for text, ids in candidates
            if (kept := tuple(i for i in ids if unseeable(layout.object(i)) is None))
        ]
    pool: GoalPool = []
    for text, ids in candidates:
        field = goal_distance_field(grid, [layout.object(i) for i in ids], success_distance)
        if (np.isfinite(field) & (field >= min_distance)).any():
            pool.append((text, ids, field))
    if not pool:
        raise InvalidInputError(
            f"layout {layout.name!r} has no {task} goal reachable from at least {min_distance} m "
            "away; add objects or rooms, or lower min_distance."
        )
    return pool


def sample_episode(
    rng: np.random.Generator,
    grid: NavGrid,
    pool: GoalPool,
    task: str,
    episode_id: int,
    min_distance: float = MIN_START_DISTANCE,
) -> Episode:
    """A random goal from the pool and a random start at least `min_distance` from it."""
    text, ids, field = pool[int(rng.integers(len(pool)))]
    rows, cols = np.nonzero(np.isfinite(field) & (field >= min_distance))
    k = int(rng.integers(len(rows)))
    xy = grid.to_world(np.array([[rows[k], cols[k]]]))[0]
    return Episode(
        episode_id=episode_id,
        task=task,
        start_position=(round(float(xy[0]), 4), round(float(xy[1]), 4)),
        start_heading=round(float(rng.uniform(-math.pi, math.pi)), 5),
        goal_text=text,
        goal_object_ids=ids,
        geodesic_distance=round(float(field[rows[k], cols[k]]), 4),
    )


def passage_pool(grid: NavGrid, pool: GoalPool, width: int, min_distance: float) -> GoalPool:
    """The pool with each goal's field cut to the starts joined to a goal cell through
    passages at least `width` cells wide (`NavGrid.passable_parts`); goals left with no
    start at least `min_distance` away are dropped. The field keeps its geodesic metres.
    """
    parts = grid.passable_parts(width)
    out: GoalPool = []
    for text, ids, field in pool:
        goal_parts = np.unique(parts[(field == 0) & (parts > 0)])
        joined = np.isin(parts, goal_parts) & (parts > 0)
        cut = np.where(joined, field, np.inf)
        if (np.isfinite(cut) & (cut >= min_distance)).any():
            out.append((text, ids, cut))
    return out


def generate_episodes(
    layout: Layout,
    task: str,
    count: int,
    seed: int,
    grid: NavGrid | None = None,
    success_distance: float = SUCCESS_DISTANCE,
    min_distance: float = MIN_START_DISTANCE,
    min_passage_cells: int = 0,
    seeable_only: bool = False,
) -> EpisodeSet:
    """`count` episodes with reachable goals, drawn from `seed` (deterministic).

    Args:
        min_passage_cells: starts are drawn only where the goal is reached through
            passages at least this many navigable cells wide (the bench split's check,
            `navgrid.MIN_PASSAGE_CELLS`; `glmap sim episodes` applies it); 0: no check.
        seeable_only: goals only among objects the camera can be expected to recognise
            (`unseeable`; `glmap sim episodes` applies it).

    Raises:
        InvalidInputError: unknown task, bad count, or no reachable goal in the layout.
    """
    if isinstance(count, bool) or not isinstance(count, int) or count < 1:
        raise InvalidInputError(f"count={count!r} must be a positive integer.")
    if not 0 <= min_passage_cells <= MAX_PASSAGE_CELLS:
        raise InvalidInputError(
            f"min_passage_cells={min_passage_cells!r} must be 0 (no check) to "
            f"{MAX_PASSAGE_CELLS} cells."
        )
    grid = grid or build_nav_grid(layout)
    pool = goal_pool(layout, task, grid, success_distance, min_distance, seeable_only)
    if min_passage_cells > 0:
        pool = passage_pool(grid, pool, min_passage_cells, min_distance)
        if not pool:
            raise InvalidInputError(
                f"layout {layout.name!r}: no {task} goal is reached through passages at least "
                f"{min_passage_cells} cells ({min_passage_cells * grid.cell:.2f} m of free "
                "floor) wide; widen the gaps between furniture, or turn the check off."
            )
    rng = np.random.default_rng([int(seed), 7])
    episodes = [sample_episode(rng, grid, pool, task, i, min_distance) for i in range(count)]
    return EpisodeSet(task, layout.name, layout.seed, episodes, success_distance)


def episodes_to_dict(episode_set: EpisodeSet) -> dict[str, Any]:
    """The JSON object of an episode set."""
    return {
        "format": FORMAT,
        "version": VERSION,
        "task": episode_set.task,
        "scene": episode_set.scene,
        "scene_seed": episode_set.scene_seed,
        "success_distance": episode_set.success_distance,
        "episodes": [
            {
                "episode_id": e.episode_id,
                "start_position": list(e.start_position),
                "start_heading": e.start_heading,
                "goal": {"text": e.goal_text, "object_ids": list(e.goal_object_ids)},
                "geodesic_distance": e.geodesic_distance,
                **({"difficulty": asdict(e.difficulty)} if e.difficulty else {}),
            }
            for e in episode_set.episodes
        ],
    }


def _episode(entry: Mapping[str, Any], task: str, where: str) -> Episode:
    try:
        goal = entry["goal"]
        start = [float(v) for v in entry["start_position"]]
        heading = float(entry.get("start_heading", 0.0))
        if len(start) != 2 or not all(map(math.isfinite, (*start, heading))):
            raise ValueError("start_position must be 2 finite numbers, start_heading finite")
        ids = tuple(int(i) for i in goal["object_ids"])
        return Episode(
            episode_id=int(entry["episode_id"]),
            task=task,
            start_position=(start[0], start[1]),
            start_heading=heading,
            goal_text=str(goal["text"]),
            goal_object_ids=ids,
            geodesic_distance=float(entry.get("geodesic_distance", math.nan)),
            difficulty=_difficulty(entry.get("difficulty")),
        )
    except (KeyError, TypeError, ValueError, IndexError, OverflowError) as exc:
        raise InvalidInputError(
            f"{where} is malformed ({exc!r}); each episode needs episode_id, start_position "
            "[x, y], start_heading and goal {text, object_ids}."
        ) from exc


def _difficulty(data: Any) -> Difficulty | None:
    if data is None:
        return None
    return Difficulty(
        geodesic_m=float(data["geodesic_m"]),
        passage_cells=int(data["passage_cells"]),
        passage_m=float(data["passage_m"]),
        goal_in_sight=bool(data["goal_in_sight"]),
    )


def episodes_from_dict(
    data: Mapping[str, Any], layout: Layout | None = None, grid: NavGrid | None = None
) -> EpisodeSet:
    """Parse an episode set; with a layout, check ids, starts and that every goal is reachable.

    Raises:
        InvalidInputError: malformed JSON, a start off the navigable floor, an unreachable goal.
        UnknownIdError: a goal object id the layout does not have.
    """
    header = data if isinstance(data, Mapping) else {}  # null or a list: no format at all
    if header.get("format") != FORMAT or header.get("version") != VERSION:
        raise InvalidInputError(
            f"episode file format {header.get('format')!r} version {header.get('version')!r} is "
            f"not {FORMAT!r} version {VERSION}; regenerate it with `glmap sim episodes`."
        )
    task = str(data.get("task"))
    if task not in TASKS:
        raise InvalidInputError(f"task {task!r} is not one of {TASKS}.{did_you_mean(task, TASKS)}")
    entries = data.get("episodes")
    if not isinstance(entries, list) or not entries:
        raise InvalidInputError("an episode set needs a non-empty 'episodes' list.")
    episodes = [_episode(e, task, f"episodes[{i}]") for i, e in enumerate(entries)]
    success = data.get("success_distance", SUCCESS_DISTANCE)
    if isinstance(success, bool) or not isinstance(success, int | float) or not 0 < success < 1e3:
        raise InvalidInputError(
            f"success_distance {str(success)[:40]} must be a positive number of metres below "
            f"1000 (the default is {SUCCESS_DISTANCE})."
        )
    episode_set = EpisodeSet(
        task=task,
        scene=str(data.get("scene", "")),
        scene_seed=data.get("scene_seed"),
        episodes=episodes,
        success_distance=float(success),
    )
    if layout is not None:
        validate_episodes(episode_set, layout, grid)
    return episode_set


def validate_episodes(
    episode_set: EpisodeSet,
    layout: Layout,
    grid: NavGrid | None = None,
    fields: dict[tuple[int, ...], np.ndarray] | None = None,
) -> None:
    """Raise unless every episode starts on navigable floor with a reachable goal.

    `fields` (goal object ids -> distance field) caches the goal fields across calls; the
    fields computed here are added to it.
    """
    if episode_set.scene and episode_set.scene != layout.name:
        raise InvalidInputError(
            f"the episodes are for scene {episode_set.scene!r} but the layout is {layout.name!r}; "
            "pass the layout they were generated from."
        )
    grid = grid or build_nav_grid(layout)
    by_id = layout.objects_by_id
    fields = {} if fields is None else fields
    for e in episode_set.episodes:
        missing = [i for i in e.goal_object_ids if i not in by_id]
        if missing or not e.goal_object_ids:
            raise UnknownIdError(
                f"episode {e.episode_id}: goal object ids {missing or '[]'} are not in layout "
                f"{layout.name!r}; regenerate the episodes for this layout."
            )
        start = np.array(e.start_position)
        if not grid.is_navigable(start[None])[0]:
            raise InvalidInputError(
                f"episode {e.episode_id}: start {e.start_position} is not on navigable floor "
                f"(walls, furniture or outside); move it or regenerate the episodes."
            )
        if e.goal_object_ids not in fields:
            targets = [by_id[i] for i in e.goal_object_ids]
            fields[e.goal_object_ids] = goal_distance_field(
                grid, targets, episode_set.success_distance
            )
        r, c = grid.to_cell(start[None])[0]
        if not math.isfinite(float(fields[e.goal_object_ids][r, c])):
            raise InvalidInputError(
                f"episode {e.episode_id}: goal {e.goal_text!r} (objects "
                f"{list(e.goal_object_ids)}) is unreachable from start {e.start_position}: no "
                f"navigable path ends within {episode_set.success_distance} m of it. Add an "
                "opening to its room, move the objects that block the way, or drop the episode."
            )


def save_episodes(episode_set: EpisodeSet, path: str | os.PathLike[str]) -> None:
    with open(path, "w", encoding="utf-8") as f:
        json.dump(episodes_to_dict(episode_set), f, indent=1)
        f.write("\n")


def load_episodes(
    path: str | os.PathLike[str], layout: Layout | None = None, grid: NavGrid | None = None
) -> EpisodeSet:
    """Read (and with a layout, validate) an episode set JSON file."""
    data = read_json(path, "episode file", "`glmap sim episodes`")
    return episodes_from_dict(data, layout, grid)
