"""Numba kernels of the walls (`nav.grid.structure_walls_in_bands`, `nav.wall_counts`): the
window's cells within one cell of a structure Gaussian mean whose height above the floor
lies in a band, for each band. One pass counts the means per (band, cell), a second grows
the counted cells by one cell within the window (writing the 3 x 3 cells of every mean was
twice as slow). Heights, divisions and floors in float64 as numpy computes them: the same
cells.
"""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def count_means(  # pragma: no cover - numba
    means: np.ndarray,
    signs: np.ndarray,
    floor_z: float,
    bands: np.ndarray,
    cell_size: float,
    row0: int,
    col0: int,
    counts: np.ndarray,
) -> None:
    """Add signs[i] ([N] int32) to counts[b] ([B, H, W] int32, map cell (row0, col0) at
    [:, 0, 0]) at the cell of each mean i (x -> column, y -> row) that lies in the grid and
    whose height above `floor_z` lies in bands[b] ([B, 2] (low, high), both inclusive).

    Args:
        means: [N, 3] float32 structure Gaussian means.
    """
    _, h, w = counts.shape
    for i in range(means.shape[0]):
        height = np.float64(means[i, 2]) - floor_z
        row = math.floor(np.float64(means[i, 1]) / cell_size) - row0
        col = math.floor(np.float64(means[i, 0]) / cell_size) - col0
        if row < 0 or row >= h or col < 0 or col >= w:
            continue
        for b in range(bands.shape[0]):
            if height >= bands[b, 0] and height <= bands[b, 1]:
                counts[b, row, col] += signs[i]


@numba.njit(cache=True, nogil=True)
def grow_counted(  # pragma: no cover - numba
    counts: np.ndarray, row_shift: int, col_shift: int, out: np.ndarray
) -> None:
    """Set out[b] ([B, H, W] bool window, False on entry) True on the 3 x 3 cells, within the
    window, around each window cell whose counts[b] (window cell (r, c) at counts[b, r -
    row_shift, c - col_shift]) is positive."""
    n_bands, h, w = out.shape
    gh, gw = counts.shape[1], counts.shape[2]
    for b in range(n_bands):
        for r in range(max(row_shift, 0), min(gh + row_shift, h)):
            for c in range(max(col_shift, 0), min(gw + col_shift, w)):
                if counts[b, r - row_shift, c - col_shift] > 0:
                    for rr in range(max(r - 1, 0), min(r + 2, h)):
                        for cc in range(max(c - 1, 0), min(c + 2, w)):
                            out[b, rr, cc] = True


@numba.njit(cache=True, nogil=True)
def cell_extent(
    means: np.ndarray, cell_size: float
) -> tuple[int, int, int, int]:  # pragma: no cover
    """(first row, last row, first column, last column) of the means' cells, as `count_means`
    places them (x -> column, y -> row); means: [N >= 1, 3]."""
    r0 = r1 = math.floor(np.float64(means[0, 1]) / cell_size)
    c0 = c1 = math.floor(np.float64(means[0, 0]) / cell_size)
    for i in range(1, means.shape[0]):
        row = math.floor(np.float64(means[i, 1]) / cell_size)
        col = math.floor(np.float64(means[i, 0]) / cell_size)
        r0, r1 = min(r0, row), max(r1, row)
        c0, c1 = min(c0, col), max(c1, col)
    return r0, r1, c0, c1
