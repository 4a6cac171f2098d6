"""A matched unit's footprint: distances and lines of sight from points to its cells.

The stop rule and the approach cells of the waypoint rule (`nav.waypoint`) read a matched
instance through these: how far a point is from its cells, which navigable cells lie near
them, and whether a line to them crosses a wall.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from glmap_tools.map.occupancy import OBSTACLE, DenseOccupancy


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
    from glmap_tools.nav._sight_numba import clear_sight

    points_rc = np.asarray(points_rc, dtype=np.int64).reshape(-1, 2)
    if len(points_rc) == 0:
        return np.zeros(0, dtype=bool)
    h, w = occ.state.shape
    rc = _cells_to_window(match.cells, occ).astype(np.int64)
    rc = rc[(rc[:, 0] >= 0) & (rc[:, 0] < h) & (rc[:, 1] >= 0) & (rc[:, 1] < w)]
    if len(rc) == 0:
        return np.zeros(len(points_rc), dtype=bool)
    levels = _NO_WALLS if walls is None else np.ascontiguousarray(walls, dtype=np.int8)
    return clear_sight(
        rc,
        np.ascontiguousarray(points_rc),
        np.ascontiguousarray(occ.state, dtype=np.int8),
        levels,
        walls is not None,
        int(tolerance),
        min(int(tolerance), ROOM_WALL_TOLERANCE_CELLS),
        OBSTACLE,
        ROOM_WALL,
    )


_NO_WALLS = np.zeros((0, 0), np.int8)


def cells_xy(occ: DenseOccupancy, rc: np.ndarray) -> np.ndarray:
    """[K, 2] (row, col) cells of `occ`'s window -> [K, 2] (x, y) of their centres, metres."""
    s = occ.cell_size
    return np.stack(
        [(rc[:, 1] + occ.origin[0] + 0.5) * s, (rc[:, 0] + occ.origin[1] + 0.5) * s], axis=1
    )


def path_distances(
    occ: DenseOccupancy,
    rc: np.ndarray,
    agent_xy: tuple[float, float],
    distance: np.ndarray | None,
) -> np.ndarray:
    """[K] metres from the agent to the cells: geodesic over `distance`, else straight."""
    if distance is not None:
        return distance[rc[:, 0], rc[:, 1]]
    xy = cells_xy(occ, rc)
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
