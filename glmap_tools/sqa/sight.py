"""One sees what one faces: is a facing object in line of sight from an anchor's stand band?

"I am standing next to the dining table, facing the blue sofa", with two dining tables in
the map: the one in the next room, behind a wall from the sofa, cannot be it. For an
(anchor, facing) pair the anchor's stand band (the 0.3-1.0 m band beyond each face,
weighted by its front-side probability, `glmap_tools.sqa.stand.front_faces`) is checked
for a straight line to the facing object's centre that crosses no obstacle cell of the
occupancy (the anchor's and the facing object's own cells, grown by OWN_MARGIN, aside;
unknown cells do not block). `situate` drops the pairs whose facing object is seen from
less than SEEN_MIN of the band, unless every pair is, before breaking ties by distance.

Furniture blocks the 2D occupancy as a wall does, so this is a filter, not a weight: a
coffee table between sofa and television hides the television from some band cells, never
from all of them (weighting pairs by the seen share was measured worse, see
docs/evaluation.md).
"""

from __future__ import annotations

import math
import weakref
from typing import TYPE_CHECKING, Any

import numpy as np

from glmap_tools.map.occupancy import FREE, OBSTACLE
from glmap_tools.sqa.stand import BAND, fit_footprint, front_faces

if TYPE_CHECKING:
    from glmap_tools.map.glmap import GLMap
    from glmap_tools.map.occupancy import DenseOccupancy

# Imports inside functions stay there: language.embed, scipy, numba load on first use.

SEEN_MIN = 0.05  # share of the stand band: below it, a wall stands between the pair
OWN_MARGIN = 2  # cells: an object's own cells, grown by this, never hide it


class _Floor:
    """The dense occupancy, standable cells and the index-grid cells of units."""

    def __init__(self, glmap: GLMap) -> None:
        from glmap_tools.nav import NavConfig, traversable

        self.glmap = glmap
        self.occ: DenseOccupancy = glmap.occupancy.to_dense()
        self.ok = traversable(self.occ, NavConfig().agent_radius)
        self.s = self.occ.cell_size

    def window(self, centre: np.ndarray, radius: float) -> tuple[np.ndarray, ...]:
        """World centres [N, 2], seen-free and standable flags [N] of the cells near centre."""
        occ, s = self.occ, self.s
        h, w = occ.state.shape
        c0 = max(int(math.floor((centre[0] - radius) / s)) - occ.origin[0], 0)
        c1 = min(int(math.ceil((centre[0] + radius) / s)) - occ.origin[0] + 1, w)
        r0 = max(int(math.floor((centre[1] - radius) / s)) - occ.origin[1], 0)
        r1 = min(int(math.ceil((centre[1] + radius) / s)) - occ.origin[1] + 1, h)
        if c1 <= c0 or r1 <= r0:
            return np.zeros((0, 2)), np.zeros(0, bool), np.zeros(0, bool)
        rows, cols = np.mgrid[r0:r1, c0:c1]
        rows, cols = rows.ravel(), cols.ravel()
        xy = np.stack([(cols + occ.origin[0] + 0.5) * s, (rows + occ.origin[1] + 0.5) * s], 1)
        return xy, occ.state[rows, cols] == FREE, self.ok[rows, cols]

    def own_mask(self, unit_ids: list[int]) -> np.ndarray:
        """[H, W] bool: the units' grid cells grown by OWN_MARGIN (they never hide f)."""
        from scipy.ndimage import binary_dilation

        occ = self.occ
        h, w = occ.state.shape
        mask = np.zeros((h, w), bool)
        for uid in unit_ids:
            cells: np.ndarray = np.array(sorted(self.glmap.grid.cells_of_unit(uid)), np.int64)
            if len(cells) == 0:
                continue
            r, c = cells[:, 1] - occ.origin[1], cells[:, 0] - occ.origin[0]
            inside = (r >= 0) & (r < h) & (c >= 0) & (c < w)
            mask[r[inside], c[inside]] = True
        return binary_dilation(mask, iterations=OWN_MARGIN) if mask.any() else mask

    def line_of_sight(self, starts: np.ndarray, target: np.ndarray, own: np.ndarray) -> np.ndarray:
        """[N] bool: the segment from each start to `target` crosses no obstacle cell
        outside `own` (unknown cells do not block)."""
        if len(starts) == 0:
            return np.zeros(0, bool)
        occ = self.occ
        steps = int(np.ceil(np.max(np.hypot(*(starts - target).T)) / (0.5 * self.s))) + 1
        t = np.linspace(0.0, 1.0, steps)
        pts = starts[:, None, :] + (target - starts)[:, None, :] * t[None, :, None]  # [N, T, 2]
        r = np.floor(pts[..., 1] / self.s).astype(np.int64) - occ.origin[1]
        c = np.floor(pts[..., 0] / self.s).astype(np.int64) - occ.origin[0]
        inside = (r >= 0) & (r < occ.state.shape[0]) & (c >= 0) & (c < occ.state.shape[1])
        r, c = np.where(inside, r, 0), np.where(inside, c, 0)
        blocked = inside & (occ.state[r, c] == OBSTACLE) & ~own[r, c]
        return ~blocked.any(axis=1)


def _centre(glmap: GLMap, unit_id: int) -> np.ndarray:
    return np.asarray(glmap.instances[unit_id].gaussians.means[:, :2].mean(axis=0), np.float64)


class SightCheck:
    """Is a facing object seen from where one stands at an anchor? (one occupancy read)"""

    def __init__(self, glmap: GLMap) -> None:
        self.glmap = glmap
        self.floor = _Floor(glmap)

    def seen_share(self, anchor_id: int, facing_id: int) -> float | None:
        """Share of the anchor's stand band (front-side weighted) with a free line of sight
        to the facing object's centre; None when the anchor has no footprint or band."""
        g = self.glmap
        if anchor_id not in g.instances or facing_id not in g.instances:
            return None
        fp = fit_footprint(np.asarray(g.instances[anchor_id].gaussians.means)[:, :2])
        if fp is None:
            return None
        xy, free, ok = self.floor.window(fp.centre, float(np.hypot(*fp.half)) + BAND[1] + 0.1)
        if len(xy) == 0:
            return None
        w, bands = front_faces(fp, xy, free, ok)
        if w.sum() <= 0:
            return None
        band_any = np.any(bands, axis=0)
        los = np.zeros(len(xy), bool)
        own = self.floor.own_mask([anchor_id, facing_id])
        los[band_any] = self.floor.line_of_sight(xy[band_any], _centre(g, facing_id), own)
        seen = np.array([los[b].mean() if b.any() else 0.0 for b in bands])
        return float((w / w.sum() * seen).sum())


WALL_BAND = (0.3, 2.1)  # m above the floor: structure here is wall (floor below, ceiling above)


_WALLS: weakref.WeakKeyDictionary[Any, tuple[int, Walls]] = weakref.WeakKeyDictionary()


def walls_of(glmap: GLMap) -> Walls:
    """The map's `Walls`, kept until its structure layer changes."""
    size = len(glmap.structure)
    kept = _WALLS.get(glmap)
    if kept is None or kept[0] != size:
        kept = (size, Walls(glmap))
        _WALLS[glmap] = kept
    return kept[1]


class Walls:
    """The walls of a map, from its structure layer: every cell under a structure Gaussian
    between WALL_BAND heights above the floor. Objects are masked out of the structure, so
    furniture never blocks here, and a wall behind furniture still shows above it."""

    def __init__(self, glmap: GLMap) -> None:
        from scipy.ndimage import binary_closing

        self.s = float(glmap.grid.cell_size)
        self.mask = np.zeros((0, 0), bool)
        self.origin = (0, 0)
        if not len(glmap.structure):
            return
        means = np.asarray(glmap.structure.gaussians().means)
        z = means[:, 2] - float(glmap.floor_z or 0.0)
        pts = means[(z >= WALL_BAND[0]) & (z <= WALL_BAND[1]), :2]
        if len(pts) == 0:
            return
        ij = np.floor(pts / self.s).astype(np.int64)
        lo = ij.min(axis=0) - 1
        shape = tuple(int(v) for v in ij.max(axis=0) - lo + 2)
        mask = np.zeros(shape[::-1], bool)  # [rows = y, cols = x]
        mask[ij[:, 1] - lo[1], ij[:, 0] - lo[0]] = True
        self.mask = binary_closing(mask, iterations=1)  # one-cell gaps between samples
        self.origin = (int(lo[0]), int(lo[1]))

    def blocked(self, start: tuple[float, float], ends: np.ndarray) -> np.ndarray:
        """[N] bool: the segment from `start` to each end crosses a wall cell (the last
        cell before the end aside: an object against a wall ends at it)."""
        ends = np.asarray(ends, dtype=np.float64).reshape(-1, 2)
        if len(ends) == 0 or self.mask.size == 0:
            return np.zeros(len(ends), bool)
        a = np.asarray(start, dtype=np.float64)
        length = np.hypot(*(ends - a).T)
        steps = int(np.ceil(length.max() / (0.5 * self.s))) + 2
        t = np.linspace(0.0, 1.0, steps)[None, :] * np.maximum(length - self.s, 0.0)[:, None]
        unit = (ends - a) / np.maximum(length, 1e-9)[:, None]
        pts = a[None, None, :] + unit[:, None, :] * t[..., None]  # [N, T, 2]
        c = np.floor(pts[..., 0] / self.s).astype(np.int64) - self.origin[0]
        r = np.floor(pts[..., 1] / self.s).astype(np.int64) - self.origin[1]
        inside = (r >= 0) & (r < self.mask.shape[0]) & (c >= 0) & (c < self.mask.shape[1])
        hit = inside & self.mask[np.where(inside, r, 0), np.where(inside, c, 0)]
        return hit.any(axis=1)
