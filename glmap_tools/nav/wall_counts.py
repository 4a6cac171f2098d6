"""Structure means counted per map cell and height band, kept from one step to the next.

Every step, `nav.perceive.walls_of` asks which cells of the occupancy window lie within one
cell of a structure mean in the obstacle band and in the room-wall band
(`nav.grid.structure_walls_in_bands`). Reading every mean each step cost ~2 ms on a
house-sized map (170k means in ~1000 chunks), while a frame replaces ~15 chunks. So the
means are counted per (band, cell) in a grid over the map's cells, and each step counts
only the chunks `StructureLayer.apply` replaced since the last (found by identity: chunks
are immutable). A window's walls are its cells with a count, grown by one cell within the
window: the same cells as `structure_walls_in_bands`.
"""

from __future__ import annotations

import threading
import weakref
from collections.abc import Sequence

import numpy as np

from glmap_tools.map.occupancy import DenseOccupancy
from glmap_tools.map.structure import ChunkKey, StructureChunk, StructureLayer
from glmap_tools.nav.grid import structure_walls_in_bands

GROW = 64  # cells of margin when the grid grows
MAX_CELLS = 1 << 21  # cells of the grid, a band (8 MB; ~72 m square at 5 cm): wider maps read
# every mean each step instead


class WallCounts:
    """Per-(band, cell) counts of a structure layer's means, for one floor, bands and cell.

    Args:
        floor_z: the floor height the bands are measured from.
        bands: (low, high) heights above the floor, both inclusive.
        cell_size: the occupancy cell (m).
    """

    def __init__(self, floor_z: float, bands: Sequence[tuple[float, float]], cell_size: float):
        self.key = _key(floor_z, bands, cell_size)
        self.limits = np.array(self.key[1], dtype=np.float64).reshape(len(bands), 2)
        self.too_wide = False  # the means span more than MAX_CELLS cells
        self.counts = np.zeros((len(bands), 0, 0), np.int32)
        self.row0 = self.col0 = 0  # the map cell (y index, x index) of counts[:, 0, 0]
        self.chunks: dict[ChunkKey, StructureChunk] = {}  # what the counts hold

    def update(self, layer: StructureLayer) -> bool:
        """Count the chunks that changed since the last update (their old means out, their
        new ones in, in one pass); False when a chunk the counts hold has left the layer
        (the caller starts afresh). Means too wide to count set `too_wide` instead."""
        from glmap_tools.nav._walls_numba import count_means

        gone: list[np.ndarray] = []
        came: list[np.ndarray] = []
        for key, chunk in layer.chunks.items():
            held = self.chunks.get(key)
            if held is chunk:
                continue
            if held is not None:
                gone.append(held.gaussians.means)
            came.append(chunk.gaussians.means)
            self.chunks[key] = chunk
        if came:
            means = np.concatenate(gone + came)
            signs = np.ones(len(means), np.int32)
            signs[: sum(len(m) for m in gone)] = -1
            if len(means):
                if not self._cover(means):
                    self.too_wide = True
                    return True
                floor_z, _, cell = self.key
                count_means(means, signs, floor_z, self.limits, cell, self.row0, self.col0,
                            self.counts)  # fmt: skip
        return len(self.chunks) == len(layer.chunks)

    def _cover(self, means: np.ndarray) -> bool:
        """Grow the grid (with a margin) to hold every cell of the means; False (the grid
        left as it was) when it would pass MAX_CELLS."""
        from glmap_tools.nav._walls_numba import cell_extent

        r0, r1, c0, c1 = cell_extent(means, self.key[2])
        rows, cols = (r0, r1), (c0, c1)
        n_bands, h, w = self.counts.shape
        if h and (self.row0 <= rows[0] and rows[1] < self.row0 + h
                  and self.col0 <= cols[0] and cols[1] < self.col0 + w):  # fmt: skip
            return True
        if h:
            rows = (min(rows[0], self.row0), max(rows[1], self.row0 + h - 1))
            cols = (min(cols[0], self.col0), max(cols[1], self.col0 + w - 1))
        row0, col0 = rows[0] - GROW, cols[0] - GROW
        shape = (n_bands, rows[1] + GROW + 1 - row0, cols[1] + GROW + 1 - col0)
        if shape[1] * shape[2] > MAX_CELLS:
            return False
        grown = np.zeros(shape, np.int32)
        grown[
            :, self.row0 - row0 : self.row0 - row0 + h, self.col0 - col0 : self.col0 - col0 + w
        ] = self.counts
        self.counts, self.row0, self.col0 = grown, row0, col0
        return True

    def walls(self, occ: DenseOccupancy) -> np.ndarray:
        """[B, H, W] bool over `occ`'s window: cells within one cell (8-neighbourhood) of a
        counted cell of each band, within the window."""
        from glmap_tools.nav._walls_numba import grow_counted

        h, w = occ.state.shape
        out = np.zeros((len(self.limits), h, w), dtype=bool)
        col0, row0 = int(occ.origin[0]), int(occ.origin[1])
        grow_counted(self.counts, self.row0 - row0, self.col0 - col0, out)  # grid -> window
        return out


_KEPT: weakref.WeakKeyDictionary[StructureLayer, WallCounts] = weakref.WeakKeyDictionary()
_LOCK = threading.Lock()


def structure_walls_kept(
    layer: StructureLayer,
    floor_z: float,
    bands: Sequence[tuple[float, float]],
    occ: DenseOccupancy,
) -> list[np.ndarray]:
    """`nav.grid.structure_walls_in_bands(layer.means(), floor_z, bands, occ)`, from counts
    kept with the layer (started afresh when the floor, bands or cell size change; every
    mean read again while they span more than MAX_CELLS cells)."""
    with _LOCK:
        counts = _KEPT.get(layer)
        if counts is None or counts.key != _key(floor_z, bands, occ.cell_size):
            counts = _start(layer, floor_z, bands, occ.cell_size)
        elif not counts.too_wide and not counts.update(layer):
            counts = _start(layer, floor_z, bands, occ.cell_size)  # a chunk left the layer
        # (A layer only grows: counts too wide stay so until the floor or bands change.)
        if counts.too_wide:
            return structure_walls_in_bands(layer.means(), floor_z, bands, occ)
        return list(counts.walls(occ))


def _start(
    layer: StructureLayer, floor_z: float, bands: Sequence[tuple[float, float]], cell: float
) -> WallCounts:
    """New counts of every chunk of the layer, kept with it."""
    counts = WallCounts(floor_z, bands, cell)
    counts.update(layer)
    _KEPT[layer] = counts
    return counts


def _key(
    floor_z: float, bands: Sequence[tuple[float, float]], cell_size: float
) -> tuple[float, tuple[tuple[float, float], ...], float]:
    """What the counts depend on besides the layer."""
    return float(floor_z), tuple((float(lo), float(hi)) for lo, hi in bands), float(cell_size)
