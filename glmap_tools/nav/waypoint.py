"""The waypoint rule: a frontier chosen by the value map H, or the matched goal unit.

Paper 3.2: "the next waypoint is selected as the frontier closest to the location of the
maximum value grid". Once an instance matches the goal (score >= stop_threshold, observed
in >= min_observations frames) the waypoint becomes the nearest navigable cell within
`stop_distance` (< success radius) of that unit's cells.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from glmap_tools.map.occupancy import DenseOccupancy
from glmap_tools.nav.config import NavConfig
from glmap_tools.nav.footprint import (
    ROOM_WALL,
    ROOM_WALL_TOLERANCE_CELLS,
    GoalMatch,
    cells_xy,
    distance_to_cells,
    distances_to_cells,
    goal_cells_near,
    in_clear_sight,
    path_distances,
)
from glmap_tools.nav.frontiers import Frontier
from glmap_tools.nav.value import ValueMap

WAYPOINT_KINDS = ("goal", "frontier", "explore", "none")


@dataclass(frozen=True)
class Waypoint:
    """Where the agent heads next.

    Attributes:
        xy: (x, y) metres, or None for kind 'none'.
        kind: 'goal' (a matched unit) | 'frontier' | 'explore' (no frontier left: the best
            value) | 'none' (nothing left to do).
        unit_id: the matched unit for kind 'goal'.
        score: the unit score (goal) or the value H at the waypoint.
        reason: one sentence saying why this waypoint was chosen.
    """

    xy: tuple[float, float] | None
    kind: str
    unit_id: int | None
    score: float
    reason: str


def _goal_waypoint(
    match: GoalMatch,
    traversable: np.ndarray,
    agent_xy: tuple[float, float],
    config: NavConfig,
    occ: DenseOccupancy,
    distance: np.ndarray | None,
    walls: np.ndarray | None,
) -> Waypoint | None:
    """Where to go for a matched unit, by one rule for the stop and the approach cells.

    A point is *within stop* when `distance_to_cells` from it to the unit's cells is at most
    `stop_distance` (and, with `stop_in_sight`, the line to them crosses no wall). The agent
    stops where it is within stop; else it heads for the nearest reachable navigable cell
    whose centre is within stop with a cell to spare (landing off a cell's centre stays
    within stop). With no such cell, the success rule itself decides: the agent stops where
    a stop would count (within `success_radius`, in sight) rather than give the unit up;
    else it heads for the reachable cell nearest the unit, when that is closer than here.
    None when there is nothing to head for yet (keep exploring)."""
    here = distance_to_cells(match.cells, agent_xy, occ.cell_size)
    ap = _approach_cells(match, traversable, agent_xy, config, occ, distance, walls)
    matched = f"instance {match.unit_id} matches the goal (score {match.score:.2f})"
    if here <= config.stop_distance and (ap.seen_here or not ap.sight_rule):
        reason = f"{matched} and is {here:.2f} m away: within the stop distance."
        xy = np.array(agent_xy, dtype=float)
    elif ap.cand.any():
        note = (
            " (it was within reach but out of sight here)" if here <= config.stop_distance else ""
        )
        k = int(np.argmin(np.where(ap.cand, ap.d, np.inf)))
        xy = cells_xy(occ, ap.near[k][None])[0]
        reason = (
            f"{matched}; heading to the nearest navigable cell within "
            f"{config.stop_distance:.2f} m of it"
            + (" in clear sight of it" if config.stop_in_sight else "")
            + f"{note}."
        )
    else:
        return _no_approach_cell(match, ap, here, agent_xy, config, occ, matched)
    return Waypoint((float(xy[0]), float(xy[1])), "goal", match.unit_id, match.score, reason)


@dataclass(frozen=True)
class _Approach:
    """The reachable navigable cells near a matched unit and which of them are within stop.

    near: [K, 2] window (row, col) cells; d: their path distances from the agent; unit_d:
    their distances to the unit's cells; seen: in sight of it; cand: within stop (and in
    sight when the sight rule applies); seen_here: the agent sees the unit; sight_rule:
    whether sight decides (`_goal_waypoint`)."""

    near: np.ndarray
    d: np.ndarray
    unit_d: np.ndarray
    seen: np.ndarray
    cand: np.ndarray
    seen_here: bool
    sight_rule: bool


def _approach_cells(
    match: GoalMatch,
    traversable: np.ndarray,
    agent_xy: tuple[float, float],
    config: NavConfig,
    occ: DenseOccupancy,
    distance: np.ndarray | None,
    walls: np.ndarray | None,
) -> _Approach:
    """The cells `_goal_waypoint` may head for, and whether the sight rule applies."""
    s = occ.cell_size
    sight = config.stop_in_sight
    agent_rc = np.array(occ.world_to_index(*agent_xy))[None]
    seen_here = bool(in_clear_sight(match, occ, agent_rc, walls)[0]) if sight else True
    # Reachable navigable cells near the unit (a cell to spare on the EDT's rounding).
    near = goal_cells_near(match, occ, traversable, config.success_radius + s)
    d = path_distances(occ, near, agent_xy, distance)
    near, d = near[np.isfinite(d)], d[np.isfinite(d)]
    unit_d = distances_to_cells(match.cells, cells_xy(occ, near), s)
    seen = in_clear_sight(match, occ, near, walls) if sight else np.ones(len(near), bool)
    cand = unit_d <= config.stop_distance - s
    # The sight rule applies when some reachable cell within stop is in sight. With none,
    # the structure may be furniture a detector missed (a TV stand's pixels join the
    # structure, and a stop in front of it is one), so only room walls block: a unit behind
    # one is not stopped for from this side (tune s00-004 stopped 0.62 m from a lamp in the
    # next room); the agent heads for a reachable cell nearer it in sight, or explores on.
    # With no room wall on the line, the old rule (distance alone) applies.
    sight_rule = sight and bool((cand & seen).any())
    if sight and not sight_rule and walls is not None:
        room = walls >= ROOM_WALL
        tol = ROOM_WALL_TOLERANCE_CELLS
        seen_here = bool(in_clear_sight(match, occ, agent_rc, room, tol)[0])
        seen = in_clear_sight(match, occ, near, room, tol)
        sight_rule = not (seen_here and seen[cand].all())
    if sight_rule:
        cand &= seen
    # The plan counts the agent arrived within half a step of its waypoint: cells whose
    # whole arrival disc is within stop (and in sight) come first, so that where the agent
    # arrives, it stops for the unit (tune s02-004 stopped 0.77 m away, out of sight).
    sure = cand & _arrival_within_stop(near, unit_d, seen if sight_rule else None, occ, config)
    if sure.any():
        cand = sure
    return _Approach(near, d, unit_d, seen, cand, seen_here, sight_rule)


def _no_approach_cell(
    match: GoalMatch,
    ap: _Approach,
    here: float,
    agent_xy: tuple[float, float],
    config: NavConfig,
    occ: DenseOccupancy,
    matched: str,
) -> Waypoint | None:
    """No reachable cell within stop: the success rule decides, never a give-up.

    Cells under the agent's own footprint count as free (it stands there) but are no place
    to step to: they lie in an obstacle's margin."""
    s = occ.cell_size
    xy_near = cells_xy(occ, ap.near)
    off_foot = np.hypot(xy_near[:, 0] - agent_xy[0], xy_near[:, 1] - agent_xy[1]) > (
        config.agent_radius + s
    )
    closer = (ap.unit_d < here - s) & ap.seen & off_foot
    if here <= config.success_radius and ap.seen_here and not closer.any():
        reason = (
            f"{matched} and is {here:.2f} m away in sight: no navigable cell within "
            f"{config.stop_distance:.2f} m of it can be reached, and a stop here is "
            f"within the success radius ({config.success_radius:.2f} m)."
        )
        xy = np.array(agent_xy, dtype=float)
    elif closer.any():
        k = int(np.argmin(np.where(closer, ap.unit_d + 1e-3 * ap.d, np.inf)))
        xy = cells_xy(occ, ap.near[k][None])[0]
        reason = (
            f"{matched}; no navigable cell within {config.stop_distance:.2f} m of it can "
            f"be reached: heading to the reachable cell nearest it ({ap.unit_d[k]:.2f} m)."
        )
    else:
        return None
    return Waypoint((float(xy[0]), float(xy[1])), "goal", match.unit_id, match.score, reason)


def _arrival_within_stop(
    near: np.ndarray,
    unit_d: np.ndarray,
    seen: np.ndarray | None,
    occ: DenseOccupancy,
    config: NavConfig,
) -> np.ndarray:
    """[K] bool over the `near` cells: no point within half a step of the cell is beyond
    `stop_distance` of the unit, and (with `seen`) no near cell there is out of sight."""
    s = occ.cell_size
    arrive = config.forward_step / 2
    ok = unit_d <= config.stop_distance - s / 2 - arrive
    if seen is None or seen.all():
        return ok
    # The dilation runs on the near cells' bounding box: the unseen ones lie in it, and the
    # disc reaches no near cell from outside it.
    lo, hi = near.min(axis=0), near.max(axis=0) + 1
    unseen = np.zeros(tuple(hi - lo), dtype=bool)
    unseen[near[~seen, 0] - lo[0], near[~seen, 1] - lo[1]] = True
    k = int(np.ceil(arrive / s))
    disc = np.hypot(*np.mgrid[-k : k + 1, -k : k + 1]) <= arrive / s + 0.5
    beside = ndimage.binary_dilation(unseen, structure=disc)
    return ok & ~beside[near[:, 0] - lo[0], near[:, 1] - lo[1]]


def _usable_frontiers(
    fronts: Sequence[Frontier],
    occ: DenseOccupancy,
    avoid: Sequence[tuple[float, float]],
    config: NavConfig,
) -> list[tuple[Frontier, np.ndarray]]:
    """(frontier, [K, 2] xy of its cells farther than `stop_distance` from every given-up
    waypoint) of the reachable frontiers with any such cell."""
    usable: list[tuple[Frontier, np.ndarray]] = []
    for f in fronts:
        if not math.isfinite(f.distance):
            continue
        xy = cells_xy(occ, f.cells)
        keep = np.ones(len(xy), dtype=bool)
        for a in avoid:
            keep &= np.hypot(xy[:, 0] - a[0], xy[:, 1] - a[1]) > config.stop_distance
        if keep.any():
            usable.append((f, xy[keep]))
    return usable


def _frontier_waypoint(
    usable: list[tuple[Frontier, np.ndarray]],
    value: ValueMap | None,
    peak: tuple[float, float] | None,
) -> Waypoint | None:
    """The usable frontier cell closest to the value-map maximum `peak` (the paper's rule)
    among the frontiers an Eq. 7 map reaches (H > 0 on a cell of theirs); with no peak, or
    a peak whose map reaches no frontier, the nearest frontier's cell closest to its target.

    H is 0 beyond the kernel's reach (`TRUNCATE` sigma) of every scored unit: a frontier
    there is "closest to the peak" by metres the map says nothing about (house-tune
    s01-000: frontiers 5-10 m from a TV drew the agent back and forth across the house)."""
    if not usable:
        return None
    reached = usable
    if value is not None and value.sigma > 0:  # Eq. 7's map; the egocentric one is not smoothed
        reached = [(f, xy) for f, xy in usable if (value.values_at(xy) > 0).any()]
    if peak is not None and reached:
        best = None
        for f, xy in reached:
            d = np.hypot(xy[:, 0] - peak[0], xy[:, 1] - peak[1])
            k = int(np.argmin(d))
            key = (float(d[k]), f.distance)
            if best is None or key < best[0]:
                best = (key, (float(xy[k, 0]), float(xy[k, 1])))
        assert best is not None
        (gap, _), xy_best = best
        return Waypoint(
            xy_best,
            "frontier",
            None,
            value.value_at(*xy_best) if value is not None else 0.0,
            f"frontier closest ({gap:.2f} m) to the value-map maximum at "
            f"({peak[0]:.2f}, {peak[1]:.2f}).",
        )
    why = "." if value is None else "; the value map is empty."
    if peak is not None:
        why = f"; the value map (maximum at ({peak[0]:.2f}, {peak[1]:.2f})) reaches none."
    f, xy = min(usable, key=lambda fx: (fx[0].distance, -fx[0].size))
    k = int(np.argmin(np.hypot(xy[:, 0] - f.target[0], xy[:, 1] - f.target[1])))
    return Waypoint(
        (float(xy[k, 0]), float(xy[k, 1])),
        "frontier",
        None,
        0.0,
        f"nearest frontier ({f.distance:.2f} m, {f.size} cells){why}",
    )


def _explore_waypoint(
    value: ValueMap,
    peak: tuple[float, float],
    traversable: np.ndarray,
    agent_xy: tuple[float, float],
    config: NavConfig,
    occ: DenseOccupancy,
    distance: np.ndarray | None,
    avoid: Sequence[tuple[float, float]],
) -> Waypoint | None:
    """No frontier left: the reachable navigable cell nearest the value-map maximum, unless
    it was given up."""
    cells = np.argwhere(traversable)
    if not len(cells):
        return None
    xy = cells_xy(occ, cells)
    d = np.hypot(xy[:, 0] - peak[0], xy[:, 1] - peak[1])
    reach = path_distances(occ, cells, agent_xy, distance)
    d = np.where(np.isfinite(reach), d, np.inf)
    k = int(np.argmin(d))
    if not math.isfinite(float(d[k])) or any(
        math.hypot(xy[k, 0] - a[0], xy[k, 1] - a[1]) <= config.stop_distance for a in avoid
    ):
        return None
    return Waypoint(
        (float(xy[k, 0]), float(xy[k, 1])),
        "explore",
        None,
        value.value_at(float(xy[k, 0]), float(xy[k, 1])),
        "no frontier left and no match: the navigable cell nearest the value-map maximum.",
    )


def choose_waypoint(
    value: ValueMap | None,
    fronts: Sequence[Frontier],
    traversable: np.ndarray,
    agent_xy: tuple[float, float],
    goal_match: GoalMatch | None,
    config: NavConfig,
    *,
    occ: DenseOccupancy,
    distance: np.ndarray | None = None,
    avoid: Sequence[tuple[float, float]] = (),
    walls: np.ndarray | None = None,
) -> Waypoint:
    """Pick the next waypoint (see the module docstring): the matched goal, else the
    frontier by the value map, else the navigable cell nearest the value-map maximum.

    Args:
        value: the value map H, or None (frontier-only exploration: the nearest frontier).
        fronts: reachable frontiers (from `frontiers`).
        traversable: [H, W] bool cells the agent may stand on, over `occ`'s window.
        agent_xy: (x, y) metres.
        goal_match: the matched instance, if any.
        config: stop distance and radii.
        occ: the occupancy window `traversable` and `distance` are over.
        distance: [H, W] geodesic metres from the agent; frontiers or goal cells it cannot
            reach are skipped (next best is taken); None = straight-line distances.
        avoid: (x, y) of waypoints given up earlier (stuck, or reached without effect);
            frontiers within `config.stop_distance` of one are skipped.
        walls: [H, W] bool, the obstacle cells that block sight (`stop_in_sight`); None =
            every obstacle cell.
    """
    if goal_match is not None:
        goal = _goal_waypoint(goal_match, traversable, agent_xy, config, occ, distance, walls)
        if goal is not None:
            return goal
        # The match has no reachable cell near it yet: keep exploring (next best).
    peak = value.argmax_xy() if value is not None else None
    frontier = _frontier_waypoint(_usable_frontiers(fronts, occ, avoid, config), value, peak)
    if frontier is not None:
        return frontier
    if peak is not None and value is not None:
        explore = _explore_waypoint(
            value, peak, traversable, agent_xy, config, occ, distance, avoid
        )
        if explore is not None:
            return explore
    return Waypoint(None, "none", None, 0.0, "no frontier left, no match and no value to follow.")
