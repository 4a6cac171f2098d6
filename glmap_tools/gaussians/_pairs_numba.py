"""Numba kernel of `merge`'s pair search between two sets (`any_mergeable`,
`mergeable_pairs`): every pair within a radius, as `cKDTree.sparse_distance_matrix` finds
them (squared distance, summed x, y, z, <= radius squared), by a dense grid of
radius-sized cells over both sets' bounding box.
"""

from __future__ import annotations

import numba
import numpy as np

MAX_CELLS = 1 << 21  # the grid's cells (4 bytes each); larger boxes go to cKDTree


@numba.njit(cache=True, nogil=True)
def pairs_within(  # pragma: no cover - numba
    a: np.ndarray, b: np.ndarray, radius: float
) -> tuple[bool, np.ndarray, np.ndarray]:
    """(done, [K] ia, [K] ib): every pair with ||a[ia] - b[ib]|| <= radius (float64 [N, 3] and
    [M, 3]; `radius` > 0), ordered by b's index; done False (and no pairs) when the grid
    would hold MAX_CELLS cells or more.

    The grid's cells are indexed from one cell below both sets' lower corner, one cell of
    margin above their upper one, so the 27 cells around any point's cell are in the grid.
    """
    origin = np.empty(3)
    dims = np.empty(3, np.int64)
    cells = 1.0
    for d in range(3):
        origin[d] = min(a[:, d].min(), b[:, d].min()) - radius
        hi = max(a[:, d].max(), b[:, d].max())
        extent = np.floor((hi - origin[d]) / radius) + 2.0
        cells *= extent
        dims[d] = np.int64(extent) if extent < MAX_CELLS else 0
    if not cells < MAX_CELLS:  # NaN too
        return False, np.empty(0, np.int64), np.empty(0, np.int64)
    ny, nz = dims[1], dims[2]
    head = np.full(dims[0] * ny * nz, -1, np.int32)
    nxt = np.empty(a.shape[0], np.int32)
    for i in range(a.shape[0]):
        cx = np.int64(np.floor((a[i, 0] - origin[0]) / radius))
        cy = np.int64(np.floor((a[i, 1] - origin[1]) / radius))
        cz = np.int64(np.floor((a[i, 2] - origin[2]) / radius))
        cell = (cx * ny + cy) * nz + cz
        nxt[i] = head[cell]
        head[cell] = i
    r2 = radius * radius
    found_a = np.empty(0, np.int64)
    found_b = np.empty(0, np.int64)
    for fill in (False, True):  # count, then write
        k = 0
        for j in range(b.shape[0]):
            cx = np.int64(np.floor((b[j, 0] - origin[0]) / radius))
            cy = np.int64(np.floor((b[j, 1] - origin[1]) / radius))
            cz = np.int64(np.floor((b[j, 2] - origin[2]) / radius))
            for dx in range(-1, 2):
                for dy in range(-1, 2):
                    for dz in range(-1, 2):
                        i = head[((cx + dx) * ny + cy + dy) * nz + cz + dz]
                        while i >= 0:
                            ex = a[i, 0] - b[j, 0]
                            ey = a[i, 1] - b[j, 1]
                            ez = a[i, 2] - b[j, 2]
                            if ex * ex + ey * ey + ez * ez <= r2:
                                if fill:
                                    found_a[k] = i
                                    found_b[k] = j
                                k += 1
                            i = nxt[i]
        if not fill:
            found_a = np.empty(k, np.int64)
            found_b = np.empty(k, np.int64)
    return True, found_a, found_b
