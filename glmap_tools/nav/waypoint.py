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

from glmap_tools.map.occupancy import OBSTACLE, DenseOccupancy
from glmap_tools.nav.config import NavConfig
from glmap_tools.nav.frontiers import Frontier
from glmap_tools.nav.value import ValueMap

WAYPOINT_KINDS = ("goal", "frontier", "explore", "none")


@dataclass(frozen=True)
class GoalMatch:
    """An instance that matches the goal.

    Attributes:
        unit_id: the instance id.
        score: s_u in [0, 1].
        observations: frames that observed it.
        cells: [K, 2] int (i, j) index-grid cells of the unit (its footprint).
    """

    unit_id: int
    score: float
    observations: int
    cells: np.ndarray  # [K, 2]


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


def _cells_to_window(cells: np.ndarray, occ: DenseOccupancy) -> np.ndarray:
    """[K, 2] (i, j) -> [K, 2] (row, col) in the occupancy window."""
    return np.stack([cells[:, 1] - occ.origin[1], cells[:, 0] - occ.origin[0]], axis=1)


def distance_to_cells(cells: np.ndarray, xy: tuple[float, float], cell_size: float) -> float:
    """Metres from (x, y) to the nearest point of any of the [K, 2] (i, j) cells."""
    if len(cells) == 0:
        return math.inf
    lo = cells * cell_size
    dx = np.maximum(np.maximum(lo[:, 0] - xy[0], xy[0] - (lo[:, 0] + cell_size)), 0.0)
    dy = np.maximum(np.maximum(lo[:, 1] - xy[1], xy[1] - (lo[:, 1] + cell_size)), 0.0)
    return float(np.hypot(dx, dy).min())


def goal_cells_near(
    match: GoalMatch, occ: DenseOccupancy, ok: np.ndarray, radius: float
) -> np.ndarray:
    """[K, 2] (row, col) of `ok` cells whose centre is within `radius` m of the unit's cells."""
    rc = _cells_to_window(match.cells, occ)
    pad = int(math.ceil(radius / occ.cell_size)) + 1
    h, w = ok.shape
    r0, c0 = max(0, int(rc[:, 0].min()) - pad), max(0, int(rc[:, 1].min()) - pad)
    r1, c1 = min(h, int(rc[:, 0].max()) + pad + 1), min(w, int(rc[:, 1].max()) + pad + 1)
    if r1 <= r0 or c1 <= c0:
        return np.zeros((0, 2), np.int64)
    unit = np.zeros((r1 - r0, c1 - c0), dtype=bool)
    inside = (rc[:, 0] >= r0) & (rc[:, 0] < r1) & (rc[:, 1] >= c0) & (rc[:, 1] < c1)
    unit[rc[inside, 0] - r0, rc[inside, 1] - c0] = True
    # Centre-to-centre distance minus half a cell: to the unit cell's near side.
    dist = (ndimage.distance_transform_edt(~unit) - 0.5) * occ.cell_size
    near = ok[r0:r1, c0:c1] & (dist <= radius)
    rows, cols = np.nonzero(near)
    return np.stack([rows + r0, cols + c0], axis=1)


SIGHT_TOLERANCE_CELLS = 2  # obstacle cells this close to the unit's cells do not block sight
WALL, ROOM_WALL = 1, 2  # levels of `nav.perceive.walls_of`: structure, a room's wall
# Room walls block from one cell off the unit (the simulator's rule stops one cell short of
# the footprint): a 10 cm wall the unit stands against is 2 cells, seen through at 2.
ROOM_WALL_TOLERANCE_CELLS = 1


def in_clear_sight(
    match: GoalMatch,
    occ: DenseOccupancy,
    points_rc: np.ndarray,
    walls: np.ndarray | None = None,
    tolerance: int = SIGHT_TOLERANCE_CELLS,
) -> np.ndarray:
    """[K] bool: whether the straight line from each (row, col) cell centre to the nearest
    cell of the matched unit crosses no obstacle of `occ` (obstacle cells within
    `tolerance` cells of the unit's own cells, which the map draws around it, are
    ignored). The simulator's success rule asks the same of the footprint's nearest point,
    so a stop behind a door jamb, within reach but out of sight, fails.

    `walls` ([H, W] over `occ`'s window, nonzero on walls: `nav.perceive.walls_of`), when
    given, limits the blocking cells to obstacles that are structure: furniture (a chair's
    own seat in front of the unit that covers its back) does not hide what stands behind it
    from the success rule, walls do; a room's wall from `ROOM_WALL_TOLERANCE_CELLS` on."""
    points_rc = np.asarray(points_rc, dtype=np.int64).reshape(-1, 2)
    if len(points_rc) == 0:
        return np.zeros(0, dtype=bool)
    h, w = occ.state.shape
    rc = _cells_to_window(match.cells, occ)
    rc = rc[(rc[:, 0] >= 0) & (rc[:, 0] < h) & (rc[:, 1] >= 0) & (rc[:, 1] < w)]
    if len(rc) == 0:
        return np.zeros(len(points_rc), dtype=bool)
    unit = np.zeros((h, w), dtype=bool)
    unit[rc[:, 0], rc[:, 1]] = True
    near_unit = ndimage.binary_dilation(unit, iterations=tolerance)
    blocking = (occ.state == OBSTACLE) & ~near_unit
    if walls is not None:
        room = walls >= ROOM_WALL
        tol = min(tolerance, ROOM_WALL_TOLERANCE_CELLS)
        near_room = ndimage.binary_dilation(unit, iterations=tol) if tol else unit
        blocking = (occ.state == OBSTACLE) & ((walls > 0) & ~near_unit | room & ~near_room)
    # The nearest unit cell of each point (Euclidean, in cells).
    d2 = ((points_rc[:, None, :] - rc[None, :, :]) ** 2).sum(axis=2)
    ends = rc[np.argmin(d2, axis=1)]
    n = int(np.ceil(np.sqrt(d2.min(axis=1).max()) * 4)) + 2  # quarter-cell samples
    f = np.linspace(0.0, 1.0, n)[None, :, None]
    samples = points_rc[:, None, :] + f * (ends - points_rc)[:, None, :]
    cells = np.clip(np.rint(samples).astype(np.int64), 0, [h - 1, w - 1])
    return ~blocking[cells[..., 0], cells[..., 1]].any(axis=1)


def _cell_xy(occ: DenseOccupancy, rc: np.ndarray) -> np.ndarray:
    """[K, 2] (row, col) cells of `occ`'s window -> [K, 2] (x, y) of their centres, metres."""
    s = occ.cell_size
    return np.stack(
        [(rc[:, 1] + occ.origin[0] + 0.5) * s, (rc[:, 0] + occ.origin[1] + 0.5) * s], axis=1
    )


def _distances(
    occ: DenseOccupancy,
    rc: np.ndarray,
    agent_xy: tuple[float, float],
    distance: np.ndarray | None,
) -> np.ndarray:
    """[K] metres from the agent to the cells: geodesic over `distance`, else straight."""
    if distance is not None:
        return distance[rc[:, 0], rc[:, 1]]
    xy = _cell_xy(occ, rc)
    return np.hypot(xy[:, 0] - agent_xy[0], xy[:, 1] - agent_xy[1])


def distances_to_cells(cells: np.ndarray, points_xy: np.ndarray, cell_size: float) -> np.ndarray:
    """[N] metres from each of [N, 2] (x, y) points to the nearest point of the [K, 2] (i, j)
    cells: `distance_to_cells` for many points (inf with no cells)."""
    pts = np.asarray(points_xy, dtype=np.float64).reshape(-1, 2)
    if len(cells) == 0:
        return np.full(len(pts), np.inf)
    lo = cells * cell_size  # [K, 2]
    out = np.empty(len(pts))
    for a in range(0, len(pts), 256):  # [256, K] at a time
        p = pts[a : a + 256, None, :]
        dx = np.maximum(
            np.maximum(lo[None, :, 0] - p[..., 0], p[..., 0] - lo[None, :, 0] - cell_size), 0
        )
        dy = np.maximum(
            np.maximum(lo[None, :, 1] - p[..., 1], p[..., 1] - lo[None, :, 1] - cell_size), 0
        )
        out[a : a + 256] = np.hypot(dx, dy).min(axis=1)
    return out


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
    s = occ.cell_size
    here = distance_to_cells(match.cells, agent_xy, s)
    sight = config.stop_in_sight
    agent_rc = np.array(occ.world_to_index(*agent_xy))[None]
    seen_here = bool(in_clear_sight(match, occ, agent_rc, walls)[0]) if sight else True
    # Reachable navigable cells near the unit (a cell to spare on the EDT's rounding).
    near = goal_cells_near(match, occ, traversable, config.success_radius + s)
    d = _distances(occ, near, agent_xy, distance)
    near, d = near[np.isfinite(d)], d[np.isfinite(d)]
    unit_d = distances_to_cells(match.cells, _cell_xy(occ, near), s)
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
    matched = f"instance {match.unit_id} matches the goal (score {match.score:.2f})"
    if here <= config.stop_distance and (seen_here or not sight_rule):
        reason = f"{matched} and is {here:.2f} m away: within the stop distance."
        xy = np.array(agent_xy, dtype=float)
    elif cand.any():
        note = (
            " (it was within reach but out of sight here)" if here <= config.stop_distance else ""
        )
        k = int(np.argmin(np.where(cand, d, np.inf)))
        xy = _cell_xy(occ, near[k][None])[0]
        reason = (
            f"{matched}; heading to the nearest navigable cell within "
            f"{config.stop_distance:.2f} m of it"
            + (" in clear sight of it" if sight else "")
            + f"{note}."
        )
    else:
        # No reachable cell within stop: the success rule decides, never a give-up.
        # Cells under the agent's own footprint count as free (it stands there) but are no
        # place to step to: they lie in an obstacle's margin.
        xy_near = _cell_xy(occ, near)
        off_foot = np.hypot(xy_near[:, 0] - agent_xy[0], xy_near[:, 1] - agent_xy[1]) > (
            config.agent_radius + s
        )
        closer = (unit_d < here - s) & seen & off_foot
        if here <= config.success_radius and seen_here and not closer.any():
            reason = (
                f"{matched} and is {here:.2f} m away in sight: no navigable cell within "
                f"{config.stop_distance:.2f} m of it can be reached, and a stop here is "
                f"within the success radius ({config.success_radius:.2f} m)."
            )
            xy = np.array(agent_xy, dtype=float)
        elif closer.any():
            k = int(np.argmin(np.where(closer, unit_d + 1e-3 * d, np.inf)))
            xy = _cell_xy(occ, near[k][None])[0]
            reason = (
                f"{matched}; no navigable cell within {config.stop_distance:.2f} m of it can "
                f"be reached: heading to the reachable cell nearest it ({unit_d[k]:.2f} m)."
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
    unseen = np.zeros(occ.state.shape, dtype=bool)
    unseen[near[~seen, 0], near[~seen, 1]] = True
    k = int(np.ceil(arrive / s))
    disc = np.hypot(*np.mgrid[-k : k + 1, -k : k + 1]) <= arrive / s + 0.5
    beside = ndimage.binary_dilation(unseen, structure=disc)
    return ok & ~beside[near[:, 0], near[:, 1]]


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
        xy = _cell_xy(occ, f.cells)
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
    """The usable frontier cell closest to the value-map maximum `peak` (the paper's rule),
    or, with no peak, the nearest frontier's cell closest to its target."""
    if not usable:
        return None
    if peak is not None:
        best = None
        for f, xy in usable:
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
    xy = _cell_xy(occ, cells)
    d = np.hypot(xy[:, 0] - peak[0], xy[:, 1] - peak[1])
    reach = _distances(occ, cells, agent_xy, distance)
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
