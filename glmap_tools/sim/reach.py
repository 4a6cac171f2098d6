"""Reaching a goal object: near its footprint and on its side of the walls.

Success and goal cells use the planar distance from the agent's centre to the nearest point
of the goal's footprint rectangle (its surface seen from above, 0 inside). A wall between
the two would let an agent "arrive" at a bed from the corridor behind the bedroom wall
(10 cm of wall, 0.35 m from the bed), so the straight segment from the agent to that nearest
footprint point must also cross no wall cell (`NavGrid.walls`: wall pieces below the
obstacle height; doorways are open). The segment is sampled every quarter cell and stops one
cell short of the footprint, whose edge may touch its own room's wall.
"""

from __future__ import annotations

import math

import numpy as np

from glmap_tools.sim.layout import SceneObject
from glmap_tools.sim.navgrid import NavGrid


def nearest_footprint_points(obj: SceneObject, points: np.ndarray) -> np.ndarray:
    """[N, 2] the nearest point of the object's footprint to each of [N, 2] points."""
    pts = np.atleast_2d(np.asarray(points, dtype=np.float64))
    rot = obj.rotation[:2, :2]
    half = np.asarray(obj.size[:2], dtype=np.float64) / 2
    local = np.clip((pts - obj.position[:2]) @ rot, -half, half)
    return local @ rot.T + obj.position[:2]


def clear_of_walls(grid: NavGrid, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """[N] bool: the segments starts[i] -> ends[i] ([N, 2] each) cross no wall cell.

    Sampling stops one cell short of each end. Without wall cells on the grid (a grid built
    by hand), every segment is clear.
    """
    a = np.atleast_2d(np.asarray(starts, dtype=np.float64))
    b = np.atleast_2d(np.asarray(ends, dtype=np.float64))
    if grid.walls is None or len(a) == 0:
        return np.ones(len(a), dtype=bool)
    delta = b - a
    length = np.linalg.norm(delta, axis=1)  # [N]
    direction = delta / np.maximum(length, 1e-12)[:, None]
    step = grid.cell / 4
    t = np.arange(max(1, math.ceil(float(length.max()) / step) + 1)) * step  # [K]
    valid = t[None, :] <= (length - grid.cell)[:, None]  # [N, K]
    pts = a[:, None, :] + direction[:, None, :] * t[None, :, None]  # [N, K, 2]
    col = np.floor((pts[..., 0] - grid.origin[0]) / grid.cell).astype(np.int64)
    row = np.floor((pts[..., 1] - grid.origin[1]) / grid.cell).astype(np.int64)
    h, w = grid.walls.shape
    hit = grid.walls[np.clip(row, 0, h - 1), np.clip(col, 0, w - 1)] & valid
    return ~hit.any(axis=1)


def clear_of_walls_reference(grid: NavGrid, start: np.ndarray, end: np.ndarray) -> bool:
    """Slow reference of `clear_of_walls` for one segment, point by point."""
    if grid.walls is None:
        return True
    length = float(np.linalg.norm(end - start))
    direction = (end - start) / max(length, 1e-12)
    h, w = grid.walls.shape
    k = 0
    while k * grid.cell / 4 <= length - grid.cell:
        p = start + direction * (k * grid.cell / 4)
        r, c = grid.cell_of(float(p[0]), float(p[1]))
        if grid.walls[min(max(r, 0), h - 1), min(max(c, 0), w - 1)]:
            return False
        k += 1
    return True


def reaches(grid: NavGrid, obj: SceneObject, points: np.ndarray, distance: float) -> np.ndarray:
    """[N] bool: points within `distance` of the footprint, with no wall in between."""
    pts = np.atleast_2d(np.asarray(points, dtype=np.float64))
    near = obj.distance_to(pts) <= distance
    out = np.zeros(len(pts), dtype=bool)
    if near.any():
        idx = np.nonzero(near)[0]
        out[idx] = clear_of_walls(grid, pts[idx], nearest_footprint_points(obj, pts[idx]))
    return out
