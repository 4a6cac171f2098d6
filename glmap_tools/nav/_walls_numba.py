"""Numba kernel of `nav.grid.structure_walls_in_bands`: the window's cells within one cell of
a structure Gaussian mean whose height above the floor lies in a band, for each band. A
step's walls read every mean of the structure layer (170k on a house-sized map): one pass
marks each mean's cell, a second grows the marks by one cell (writing the 3 x 3 cells of
every mean was twice as slow). Heights, divisions and floors in float64 as numpy computes
them: the same cells.
"""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def mark_walls(  # pragma: no cover - numba
    means: np.ndarray,
    floor_z: float,
    bands: np.ndarray,
    cell_size: float,
    origin_col: int,
    origin_row: int,
    out: np.ndarray,
) -> None:
    """Set out[b] ([B, H, W] bool, False on entry) True on the 3 x 3 cells around the cell of
    each mean (x -> column, y -> row, less the window's origin) that lies in the window and
    whose height above `floor_z` lies in bands[b] ([B, 2] (low, high), both inclusive).

    Args:
        means: [N, 3] float32 structure Gaussian means.
    """
    n_bands, h, w = out.shape
    cells = np.zeros((n_bands, h, w), dtype=np.bool_)
    for i in range(means.shape[0]):
        height = np.float64(means[i, 2]) - floor_z
        row = -1
        col = -1
        placed = False
        for b in range(n_bands):
            if not (height >= bands[b, 0] and height <= bands[b, 1]):
                continue
            if not placed:
                row = math.floor(np.float64(means[i, 1]) / cell_size) - origin_row
                col = math.floor(np.float64(means[i, 0]) / cell_size) - origin_col
                placed = True
            if row < 0 or row >= h or col < 0 or col >= w:
                break
            cells[b, row, col] = True
    for b in range(n_bands):  # each marked cell and its 8 neighbours, within the window
        for r in range(h):
            for c in range(w):
                if cells[b, r, c]:
                    for rr in range(max(r - 1, 0), min(r + 2, h)):
                        for cc in range(max(c - 1, 0), min(c + 2, w)):
                            out[b, rr, cc] = True
