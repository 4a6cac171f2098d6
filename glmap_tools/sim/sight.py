"""Line of sight on the floor plan: can an agent standing at a point see a goal object?

Seen from above, sight lines run straight over a grid of blockers: wall pieces that reach
below the camera (`CAMERA_HEIGHT`; the wall above a door does not block) and tall objects
(top at least `TALL_OBJECT` metres, base below the camera: wardrobes, fridges, bookcases,
floor lamps, large plants). Lower furniture does not block: the camera looks over a sofa.
A goal is in sight from a point when a straight line from it reaches any point of a goal
footprint's outline without crossing a blocker; the goal objects themselves never block,
nor do the objects they stand on (books on a bookcase are seen with the bookcase).
Thin gaps between blocker cells can let a line through, so `in_sight` errs towards "seen",
which keeps starts the benchmark calls out of sight truly out of sight.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from glmap_tools.sim.architecture import wall_pieces
from glmap_tools.sim.layout import Layout, SceneObject
from glmap_tools.sim.navgrid import NavGrid, _ccw, _fill_rect

CAMERA_HEIGHT = 0.88  # metres, the default camera of the environments
TALL_OBJECT = 1.2  # metres: objects whose top is at least this high block sight
OUTLINE_STEP = 0.1  # metres between the sampled points of a footprint outline
WALL_ID = -1


def blocker_grid(layout: Layout, grid: NavGrid) -> np.ndarray:
    """[H, W] int32 on the nav grid's cells: 0 clear, -1 wall, else the blocking object id."""
    h, w = grid.shape
    xs = grid.origin[0] + (np.arange(w) + 0.5) * grid.cell
    ys = grid.origin[1] + (np.arange(h) + 0.5) * grid.cell
    walls = np.zeros((h, w), dtype=bool)
    for piece in wall_pieces(layout):
        if piece.z0 < CAMERA_HEIGHT:
            _fill_rect(walls, xs, ys, _ccw(piece.corners), True)
    out = np.where(walls, WALL_ID, 0).astype(np.int32)
    for obj in layout.objects:
        if obj.position[2] < CAMERA_HEIGHT and obj.top >= TALL_OBJECT:
            mask = np.zeros((h, w), dtype=bool)
            _fill_rect(mask, xs, ys, _ccw(obj.footprint()), True)
            out[mask & (out == 0)] = obj.id
    return out


def outline_points(obj: SceneObject, step: float = OUTLINE_STEP) -> np.ndarray:
    """[K, 2] points along the footprint's outline, at most `step` metres apart."""
    corners = obj.footprint()
    points = []
    for i in range(4):
        a, b = corners[i], corners[(i + 1) % 4]
        n = max(1, math.ceil(float(np.linalg.norm(b - a)) / step))
        t = np.arange(n)[:, None] / n
        points.append(a + t * (b - a))
    return np.concatenate(points)


class SightChecker:
    """Answers "is any goal object in sight from here?" for one layout (see the module doc).

    Args:
        layout: the scene.
        grid: its navigation grid (the blocker grid shares its cells).
    """

    def __init__(self, layout: Layout, grid: NavGrid) -> None:
        self.layout = layout
        self.grid = grid
        self.blockers = blocker_grid(layout, grid)
        self._outlines: dict[int, np.ndarray] = {}

    def _targets(self, goal_ids: Sequence[int]) -> np.ndarray:
        pts = []
        for i in goal_ids:
            if i not in self._outlines:
                self._outlines[i] = outline_points(self.layout.object(i))
            pts.append(self._outlines[i])
        return np.concatenate(pts)

    def see_through(self, goal_ids: Sequence[int]) -> np.ndarray:
        """[M] ids that do not block sight to these goals: the goals and their supports."""
        ids = set(goal_ids)
        for i in goal_ids:
            support = self.layout.object(i).supported_by
            while support is not None and support not in ids:
                ids.add(support)
                support = self.layout.object(support).supported_by
        return np.array(sorted(ids), dtype=np.int64)

    def in_sight(self, xy: np.ndarray, goal_ids: Sequence[int]) -> bool:
        """Whether a straight line from `xy` [2] reaches a goal outline unblocked.

        Samples every line at a quarter cell and stops one cell short of the outline (an
        object against a wall touches the wall's cells).
        """
        start = np.asarray(xy, dtype=np.float64)
        targets = self._targets(goal_ids)  # [P, 2]
        delta = targets - start
        length = np.linalg.norm(delta, axis=1)  # [P]
        direction = delta / np.maximum(length, 1e-9)[:, None]
        step = self.grid.cell / 4
        t = np.arange(math.ceil(float(length.max()) / step) + 1) * step  # [K]
        valid = t[None, :] <= (length - self.grid.cell)[:, None]  # [P, K]
        pts = start[None, None, :] + direction[:, None, :] * t[None, :, None]  # [P, K, 2]
        col = np.floor((pts[..., 0] - self.grid.origin[0]) / self.grid.cell).astype(np.int64)
        row = np.floor((pts[..., 1] - self.grid.origin[1]) / self.grid.cell).astype(np.int64)
        h, w = self.blockers.shape
        row, col = np.clip(row, 0, h - 1), np.clip(col, 0, w - 1)
        hit = self.blockers[row, col]
        blocked = (hit != 0) & ~np.isin(hit, self.see_through(goal_ids)) & valid
        return bool((~blocked.any(axis=1)).any())

    def in_sight_reference(self, xy: np.ndarray, goal_ids: Sequence[int]) -> bool:
        """Slow reference of `in_sight`: one point at a time, plain loops."""
        start = np.asarray(xy, dtype=np.float64)
        step = self.grid.cell / 4
        h, w = self.blockers.shape
        clear_ids = {int(i) for i in self.see_through(goal_ids)}
        for target in self._targets(goal_ids):
            length = float(np.linalg.norm(target - start))
            direction = (target - start) / max(length, 1e-9)
            k, clear = 0, True
            while k * step <= length - self.grid.cell:
                p = start + direction * (k * step)
                r, c = self.grid.cell_of(float(p[0]), float(p[1]))
                v = int(self.blockers[min(max(r, 0), h - 1), min(max(c, 0), w - 1)])
                if v != 0 and v not in clear_ids:
                    clear = False
                    break
                k += 1
            if clear:
                return True
        return False
