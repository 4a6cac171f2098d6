"""Dense windows of the map for planning: cropping, obstacle inflation, traversable cells.

Index convention (as `DenseOccupancy`): `state[row, col]` is the cell (i0 + col, j0 + row),
i.e. row = y cell, column = x cell; world (x, y) of a cell centre = ((i + 0.5) s, (j + 0.5) s).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from glmap_tools.map.occupancy import FREE, OBSTACLE, UNKNOWN, DenseOccupancy
from glmap_tools.nav.errors import OutsideMapError


@dataclass(frozen=True)
class Window:
    """A rectangle of grid cells: origin (i0, j0) = cell of [0, 0], shape (height, width)."""

    i0: int
    j0: int
    height: int
    width: int

    @classmethod
    def of(cls, occ: DenseOccupancy) -> Window:
        """The window a dense occupancy covers."""
        return cls(occ.origin[0], occ.origin[1], occ.state.shape[0], occ.state.shape[1])

    @property
    def origin(self) -> tuple[int, int]:
        return (self.i0, self.j0)

    @property
    def shape(self) -> tuple[int, int]:
        return (self.height, self.width)

    def xy_of(self, rc: np.ndarray, cell_size: float) -> np.ndarray:
        """[K, 2] world (x, y) of the cell centres of [K, 2] (row, col)."""
        rc = np.asarray(rc, dtype=np.float64).reshape(-1, 2)
        return np.stack(
            [(rc[:, 1] + self.i0 + 0.5) * cell_size, (rc[:, 0] + self.j0 + 0.5) * cell_size],
            axis=1,
        )


def reframe(occ: DenseOccupancy, window: Window) -> DenseOccupancy:
    """The occupancy over `window`: cropped where it is smaller, UNKNOWN where it is larger."""
    state = np.full(window.shape, UNKNOWN, dtype=np.int8)
    src = Window.of(occ)
    r0, c0 = src.j0 - window.j0, src.i0 - window.i0
    rs0, cs0 = max(0, -r0), max(0, -c0)
    rs1, cs1 = min(src.height, window.height - r0), min(src.width, window.width - c0)
    if rs1 > rs0 and cs1 > cs0:
        state[r0 + rs0 : r0 + rs1, c0 + cs0 : c0 + cs1] = occ.state[rs0:rs1, cs0:cs1]
    return DenseOccupancy(state, window.origin, occ.cell_size)


def known_window(occ: DenseOccupancy, margin_cells: int, *points_xy: tuple[float, float]) -> Window:
    """The bounding box of the known (non-UNKNOWN) cells and `points_xy`, plus a margin."""
    rows, cols = np.nonzero(occ.state != UNKNOWN)
    r_lo, r_hi, c_lo, c_hi = math.inf, -math.inf, math.inf, -math.inf
    if len(rows):
        r_lo, r_hi = rows.min() + occ.origin[1], rows.max() + occ.origin[1]
        c_lo, c_hi = cols.min() + occ.origin[0], cols.max() + occ.origin[0]
    for x, y in points_xy:
        i, j = math.floor(x / occ.cell_size), math.floor(y / occ.cell_size)
        r_lo, r_hi, c_lo, c_hi = min(r_lo, j), max(r_hi, j), min(c_lo, i), max(c_hi, i)
    if not math.isfinite(r_lo):
        return Window.of(occ)
    i0, j0 = int(c_lo) - margin_cells, int(r_lo) - margin_cells
    return Window(i0, j0, int(r_hi) - j0 + 1 + margin_cells, int(c_hi) - i0 + 1 + margin_cells)


def disk_offsets(radius_cells: float) -> np.ndarray:
    """[K, 2] (drow, dcol) of the cells whose centre is within `radius_cells` of the origin."""
    k = int(math.floor(radius_cells))
    dr, dc = np.mgrid[-k : k + 1, -k : k + 1]
    inside = dr**2 + dc**2 <= radius_cells**2 + 1e-9
    return np.stack([dr[inside], dc[inside]], axis=1)


def inflate(mask: np.ndarray, radius_cells: float) -> np.ndarray:
    """[H, W] bool: cells whose centre lies within `radius_cells` of a True cell's centre.

    A disk dilation done as one 1D maximum filter per disk row (fast); `inflate_reference`
    is the plain binary dilation it is tested against.
    """
    mask = np.asarray(mask, dtype=bool)
    if radius_cells < 1 or not mask.any():
        return mask.copy()
    k = int(math.floor(radius_cells))
    out = np.zeros_like(mask)
    h = mask.shape[0]
    for dr in range(-k, k + 1):
        half = int(math.floor(math.sqrt(max(radius_cells**2 - dr**2, 0.0)) + 1e-9))
        run = ndimage.maximum_filter1d(mask.view(np.uint8), 2 * half + 1, axis=1, mode="constant")
        run = run.astype(bool)
        # out[r] |= run[r - dr]
        if dr >= 0:
            out[dr:] |= run[: h - dr]
        else:
            out[:dr] |= run[-dr:]
    return out


def distance_to_zero(mask: np.ndarray) -> np.ndarray:
    """[H, W] float64 cells from each True cell's centre to the nearest False one's (0 on
    False cells): `ndimage.distance_transform_edt(mask)` to the bit, 4x faster on a
    house-sized window. OpenCV's exact transform (its precise mask) gives each distance in
    float32; its square, rounded, is the integer squared distance, whose float64 root is
    scipy's value (exact while H^2 + W^2 < 2^22, i.e. windows up to ~1400 cells a side;
    larger ones go to scipy). The mask needs a False cell."""
    mask = np.asarray(mask, dtype=bool)
    h, w = mask.shape
    if h * h + w * w >= 1 << 22:
        return np.asarray(ndimage.distance_transform_edt(mask), dtype=np.float64)
    import cv2

    cells = np.ascontiguousarray(mask).view(np.uint8)
    d = cv2.distanceTransform(cells, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    out = np.square(d, dtype=np.float64)
    return np.sqrt(np.rint(out, out=out), out=out)


def inflate_reference(mask: np.ndarray, radius_cells: float) -> np.ndarray:
    """Slow reference of `inflate`: binary dilation with the disk structuring element."""
    offsets = disk_offsets(radius_cells)
    k = int(np.abs(offsets).max()) if len(offsets) else 0
    structure = np.zeros((2 * k + 1, 2 * k + 1), dtype=bool)
    structure[offsets[:, 0] + k, offsets[:, 1] + k] = True
    return ndimage.binary_dilation(np.asarray(mask, dtype=bool), structure=structure)


def blocked(occ: DenseOccupancy, agent_radius: float) -> np.ndarray:
    """[H, W] bool: obstacle cells inflated by the agent radius."""
    return inflate(occ.state == OBSTACLE, agent_radius / occ.cell_size)


def traversable(occ: DenseOccupancy, agent_radius: float) -> np.ndarray:
    """[H, W] bool: seen-free cells where the agent centre fits (obstacles inflated).

    Args:
        occ: dense occupancy window.
        agent_radius: metres.
    """
    return (occ.state == FREE) & ~blocked(occ, agent_radius)


def plannable(occ: DenseOccupancy, agent_radius: float, optimistic: bool = True) -> np.ndarray:
    """[H, W] bool: cells a plan may cross: traversable, plus unknown ones when optimistic."""
    ok = occ.state == FREE
    if optimistic:
        ok |= occ.state == UNKNOWN
    return ok & ~blocked(occ, agent_radius)


def agent_rc(
    occ: DenseOccupancy, agent_xy: tuple[float, float], what: str = "agent"
) -> tuple[int, int]:
    """(row, col) of a position inside the window, or OutsideMapError."""
    rc = occ.world_to_index(float(agent_xy[0]), float(agent_xy[1]))
    h, w = occ.state.shape
    if not (0 <= rc[0] < h and 0 <= rc[1] < w):
        x0, y0 = occ.index_to_world(0, 0)
        x1, y1 = occ.index_to_world(h - 1, w - 1)
        raise OutsideMapError(
            f"{what} position ({agent_xy[0]:.2f}, {agent_xy[1]:.2f}) is outside the map window "
            f"x {x0:.2f}..{x1:.2f}, y {y0:.2f}..{y1:.2f} m; pass a position the map has seen "
            "(or a larger window)."
        )
    return rc


def clear_footprint(ok: np.ndarray, rc: tuple[int, int], radius_cells: float) -> np.ndarray:
    """`ok` with the cells under the agent's footprint set True (it stands there)."""
    out = ok.copy()
    offs = disk_offsets(radius_cells) + np.array(rc)
    h, w = ok.shape
    keep = (offs[:, 0] >= 0) & (offs[:, 0] < h) & (offs[:, 1] >= 0) & (offs[:, 1] < w)
    out[offs[keep, 0], offs[keep, 1]] = True
    return out


def structure_walls(
    means: np.ndarray, floor_z: float, band: tuple[float, float], occ: DenseOccupancy
) -> np.ndarray:
    """[H, W] bool over `occ`'s window: cells within one cell of a structure Gaussian mean
    ([N, 3], `GLMap.structure`: the pixels no object mask covers) whose height above the
    floor lies in the obstacle `band`. Walls, not furniture: the cells an obstacle of the
    occupancy must also be to block the sight line of `NavConfig.stop_in_sight`. One cell
    of slack covers holes the structure layer's pixel stride leaves in a wall."""
    return structure_walls_in_bands(means, floor_z, [band], occ)[0]


def structure_walls_in_bands(
    means: np.ndarray,
    floor_z: float,
    bands: Sequence[tuple[float, float]],
    occ: DenseOccupancy,
) -> list[np.ndarray]:
    """`structure_walls` for each of `bands`, each mean read once (`_walls_numba`; a
    navigation's steps keep the counts instead: `nav.wall_counts`)."""
    from glmap_tools.nav._walls_numba import count_means, grow_counted  # numba: on first use

    h, w = occ.state.shape
    out = np.zeros((len(bands), h, w), dtype=bool)
    if len(means):
        limits = np.array(bands, dtype=np.float64).reshape(len(bands), 2)
        counts = np.zeros((len(bands), h, w), np.int32)
        col0, row0 = int(occ.origin[0]), int(occ.origin[1])
        ones = np.ones(len(means), np.int32)
        count_means(means, ones, float(floor_z), limits, float(occ.cell_size), row0, col0, counts)
        grow_counted(counts, 0, 0, out)
    return list(out)
