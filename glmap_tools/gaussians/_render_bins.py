"""Depth order and per-tile binning for the fast rasterizer (numba).

These kernels do not depend on the layout of the screen-parameter rows, only on the
valid flags, depths and tile rectangles, so they live apart from `_render_numba`.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from glmap_tools.gaussians._prefetch import prefetch_row

RADIX_BITS = 11  # depth sort: bits per radix pass
RADIX = 1 << RADIX_BITS
N_PASSES = 3  # 3 x 11 bits cover a 32-bit key
AHEAD = 16  # binning: Gaussians between a tile-range prefetch and its use


@njit(cache=True)
def depth_order_kernel(valid: np.ndarray, depth: np.ndarray) -> np.ndarray:
    """Indices of the valid Gaussians by increasing depth, ties in index order (stable).

    An LSD radix sort (11-bit digits, all three histograms from one read) on the bits of
    the depths rounded to float32 -- positive floats order like their bit patterns, and
    rounding is monotone, so only keys that round equal can be out of float64 order; each
    such run is then put in float64 order by a stable insertion sort. Passes where every
    key shares the digit are skipped.

    Args:
        valid: [N] bool.
        depth: [N] float64 camera z, > 0 where valid.

    Returns:
        [M] int32, M = valid.sum().
    """
    n = 0
    for i in range(valid.shape[0]):
        n += valid[i]
    index = np.empty(n, dtype=np.int32)
    keys = np.empty(n, dtype=np.uint32)
    counts = np.zeros((N_PASSES, RADIX + 1), dtype=np.int64)
    mask = np.uint32(RADIX - 1)
    j = 0
    for i in range(valid.shape[0]):
        if valid[i]:
            key = np.float32(depth[i]).view(np.uint32)
            index[j] = i
            keys[j] = key
            for p in range(N_PASSES):
                counts[p, np.int64((key >> np.uint32(p * RADIX_BITS)) & mask) + 1] += 1
            j += 1
    index_tmp = np.empty_like(index)
    keys_tmp = np.empty_like(keys)
    for p in range(N_PASSES):
        if n == 0 or counts[p].max() == n:
            continue
        sh = np.uint32(p * RADIX_BITS)
        cursor = counts[p]
        for b in range(RADIX):
            cursor[b + 1] += cursor[b]
        for j in range(n):
            d = np.int64((keys[j] >> sh) & mask)
            pos = cursor[d]
            cursor[d] = pos + 1
            index_tmp[pos] = index[j]
            keys_tmp[pos] = keys[j]
        index, index_tmp = index_tmp, index
        keys, keys_tmp = keys_tmp, keys
    # Runs of equal float32 keys: stable insertion sort by the float64 depth.
    j = 1
    while j < n:
        if keys[j] != keys[j - 1]:
            j += 1
            continue
        start = j - 1
        end = j + 1
        while end < n and keys[end] == keys[start]:
            end += 1
        for a in range(start + 1, end):
            g = index[a]
            z = depth[g]
            b = a
            while b > start and depth[index[b - 1]] > z:
                index[b] = index[b - 1]
                b -= 1
            index[b] = g
        j = end
    return index


@njit(parallel=True, cache=True)
def bin_kernel(
    order: np.ndarray,  # [M] int32, valid Gaussians in depth order
    tiles: np.ndarray,  # [N, 4] int16: first and last tile column, first and last tile row
    tiles_x: int,
    n_tiles: int,
    n_chunks: int,
) -> tuple[np.ndarray, np.ndarray]:
    """Per-tile Gaussian lists by counting sort; each list keeps the front-to-back order.

    `order` is cut into `n_chunks` consecutive chunks counted and filled in parallel; in
    each tile's list chunk c's entries come before chunk c + 1's, so the lists do not
    depend on `n_chunks`.

    Returns:
        offsets [n_tiles + 1] int64 and lists [offsets[-1]] int32 (Gaussian indices).
    """
    m = order.shape[0]
    cursor = np.zeros((n_chunks, n_tiles), dtype=np.int64)
    for c in prange(n_chunks):
        for j in range(m * c // n_chunks, m * (c + 1) // n_chunks):
            prefetch_row(tiles, order[min(j + AHEAD, m - 1)])
            g = order[j]
            for ty in range(tiles[g, 2], tiles[g, 3] + 1):
                for tx in range(tiles[g, 0], tiles[g, 1] + 1):
                    cursor[c, ty * tiles_x + tx] += 1
    offsets = np.empty(n_tiles + 1, dtype=np.int64)
    total = 0
    for t in range(n_tiles):
        offsets[t] = total
        for c in range(n_chunks):
            count = cursor[c, t]
            cursor[c, t] = total
            total += count
    offsets[n_tiles] = total
    lists = np.empty(total, dtype=np.int32)
    for c in prange(n_chunks):
        for j in range(m * c // n_chunks, m * (c + 1) // n_chunks):
            prefetch_row(tiles, order[min(j + AHEAD, m - 1)])
            g = order[j]
            for ty in range(tiles[g, 2], tiles[g, 3] + 1):
                for tx in range(tiles[g, 0], tiles[g, 1] + 1):
                    t = ty * tiles_x + tx
                    lists[cursor[c, t]] = g
                    cursor[c, t] += 1
    return offsets, lists
