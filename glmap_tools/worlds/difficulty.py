"""How hard an episode is: geodesic length, the narrowest passage it needs, goal in sight.

The narrowest passage is a bottleneck width: the largest w such that the start and a goal
cell lie in one part of `NavGrid.passable_parts(w)` (the navigable space with passages under
w cells closed). It is the width of the narrowest gap on the widest way to the goal, so it
is at least that of the shortest path's narrowest gap, and it is the quantity the bench
split's check bounds (w >= `MIN_PASSAGE_CELLS`). Widths are measured up to
`MAX_PASSAGE_CELLS` (a wider way is reported as that).

Bins for tables (`DIFFICULTY_BINS`): geodesic < 5 m, 5-10 m, > 10 m; passage gap < 0.7 m or
not; goal in sight from the start or not.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence

import numpy as np

from glmap_tools.sim.episodes import (
    SUCCESS_DISTANCE,
    Difficulty,
    Episode,
    EpisodeSet,
    goal_distance_field,
)
from glmap_tools.sim.layout import Layout
from glmap_tools.sim.navgrid import AGENT_RADIUS, NavGrid, build_nav_grid
from glmap_tools.sim.sight import SightChecker

MAX_PASSAGE_CELLS = 24  # 1.2 m of free centre positions at 5 cm cells
NARROW_GAP_M = 0.7


def _geodesic_bin(d: Difficulty) -> str:
    if d.geodesic_m < 5.0:
        return "< 5 m"
    return "5-10 m" if d.geodesic_m <= 10.0 else "> 10 m"


# (dimension, bin of an episode, bins in table order)
DIFFICULTY_BINS: tuple[tuple[str, Callable[[Difficulty], str], tuple[str, ...]], ...] = (
    ("geodesic", _geodesic_bin, ("< 5 m", "5-10 m", "> 10 m")),
    (
        "narrowest passage",
        lambda d: f"< {NARROW_GAP_M} m" if d.passage_m < NARROW_GAP_M else f">= {NARROW_GAP_M} m",
        (f"< {NARROW_GAP_M} m", f">= {NARROW_GAP_M} m"),
    ),
    ("goal in sight at start", lambda d: "yes" if d.goal_in_sight else "no", ("yes", "no")),
)


class DifficultyMeter:
    """Measures episodes of one scene; goal fields, sight and passage parts are cached.

    Args:
        layout: the scene.
        grid: its navigation grid (built when not given).
        success_distance: metres from a goal footprint that count as reaching it.
    """

    def __init__(
        self,
        layout: Layout,
        grid: NavGrid | None = None,
        success_distance: float = SUCCESS_DISTANCE,
    ) -> None:
        self.layout = layout
        self.grid = grid or build_nav_grid(layout)
        self.success_distance = success_distance
        self._sight: SightChecker | None = None
        self._fields: dict[tuple[int, ...], np.ndarray] = {}
        self._parts: dict[int, np.ndarray] = {}

    def _field(self, ids: tuple[int, ...]) -> np.ndarray:
        if ids not in self._fields:
            targets = [self.layout.object(i) for i in ids]
            self._fields[ids] = goal_distance_field(self.grid, targets, self.success_distance)
        return self._fields[ids]

    def _joined(self, width: int, cell: tuple[int, int], goal: np.ndarray) -> bool:
        if width not in self._parts:
            self._parts[width] = self.grid.passable_parts(width)
        parts = self._parts[width]
        label = int(parts[cell])
        return label > 0 and bool((parts[goal] == label).any())

    def passage_cells(self, start: np.ndarray, goal_ids: Sequence[int]) -> int:
        """The bottleneck width in cells (0: the start is not joined to the goal at all)."""
        field = self._field(tuple(goal_ids))
        r, c = (int(v) for v in self.grid.to_cell(np.asarray(start, float)[None])[0])
        goal = field == 0
        if not math.isfinite(float(field[r, c])):
            return 0
        lo, hi = 0, MAX_PASSAGE_CELLS  # joined at lo (0: trivially), find the largest
        while lo < hi:  # joined at width w implies joined at every smaller width
            mid = (lo + hi + 1) // 2
            if self._joined(mid, (r, c), goal):
                lo = mid
            else:
                hi = mid - 1
        return lo

    def measure(self, episode: Episode) -> Difficulty:
        """The episode's difficulty."""
        start = np.asarray(episode.start_position, dtype=np.float64)
        ids = tuple(episode.goal_object_ids)
        r, c = self.grid.to_cell(start[None])[0]
        geodesic = float(self._field(ids)[r, c])
        cells = self.passage_cells(start, ids)
        if self._sight is None:
            self._sight = SightChecker(self.layout, self.grid)
        return Difficulty(
            geodesic_m=round(geodesic, 4),
            passage_cells=cells,
            passage_m=round(cells * self.grid.cell + 2 * AGENT_RADIUS, 3),
            goal_in_sight=self._sight.in_sight(start, ids),
        )

    def fill(self, episode: Episode) -> Episode:
        """The episode with its difficulty, measured when it has none."""
        if episode.difficulty is not None:
            return episode
        return dataclasses.replace(episode, difficulty=self.measure(episode))


def with_difficulty(
    episode_set: EpisodeSet, layout: Layout, grid: NavGrid | None = None
) -> EpisodeSet:
    """The set with every episode's difficulty (those it has are kept)."""
    meter = DifficultyMeter(layout, grid, episode_set.success_distance)
    episodes = [meter.fill(e) for e in episode_set.episodes]
    return dataclasses.replace(episode_set, episodes=episodes)
