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


def _near_cells(rc: np.ndarray, shape: tuple[int, int], steps: int) -> np.ndarray:
    """[H, W] bool: the cells within `steps` 4-neighbour moves of the cells `rc` [K, 2]
    (inside the grid), as `ndimage.binary_dilation(cells, iterations=steps)` for steps >= 1.
    They all lie in the cells' bounding box grown by `steps`: the dilation runs on that box,
    not on the whole window."""
    out = np.zeros(shape, dtype=bool)
    if steps < 1:
        out[rc[:, 0], rc[:, 1]] = True
        return out
    lo = np.maximum(rc.min(axis=0) - steps, 0)
    hi = np.minimum(rc.max(axis=0) + steps + 1, shape)
    box = np.zeros(tuple(hi - lo), dtype=bool)
    box[rc[:, 0] - lo[0], rc[:, 1] - lo[1]] = True
    out[lo[0] : hi[0], lo[1] : hi[1]] = ndimage.binary_dilation(box, iterations=steps)
    return out


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
    near_unit = _near_cells(rc, (h, w), tolerance)
    blocking = (occ.state == OBSTACLE) & ~near_unit
    if walls is not None:
        room = walls >= ROOM_WALL
        tol = min(tolerance, ROOM_WALL_TOLERANCE_CELLS)
        near_room = near_unit if tol == tolerance else _near_cells(rc, (h, w), tol)
        blocking = (occ.state == OBSTACLE) & ((walls > 0) & ~near_unit | room & ~near_room)
    # The nearest unit cell of each point (Euclidean, in cells).
    d2 = ((points_rc[:, None, :] - rc[None, :, :]) ** 2).sum(axis=2)
    ends = rc[np.argmin(d2, axis=1)]
    n = int(np.ceil(np.sqrt(d2.min(axis=1).max()) * 4)) + 2  # quarter-cell samples
    f = np.linspace(0.0, 1.0, n)[None, :, None]
    samples = points_rc[:, None, :] + f * (ends - points_rc)[:, None, :]
    cells = np.clip(np.rint(samples).astype(np.int64), 0, [h - 1, w - 1])
    return ~blocking[cells[..., 0], cells[..., 1]].any(axis=1)


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
