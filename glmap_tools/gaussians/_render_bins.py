"""Depth order, gather and per-tile binning for the fast rasterizer (numba).

These kernels do not depend on the layout of the screen-parameter rows, only on the
valid flags, depths and footprint rectangles, so they live apart from `_render_numba`.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

RADIX_BITS = 11  # depth sort: bits per radix pass
RADIX = 1 << RADIX_BITS


@njit(cache=True)
def depth_order_kernel(valid: np.ndarray, depth: np.ndarray) -> np.ndarray:
    """Indices of the valid Gaussians by increasing depth, ties in index order (stable).

    An LSD radix sort on the bits of the float64 depths (all positive, so their bit patterns
    order like the numbers), 11 bits a pass; passes where every key shares the digit are
    skipped.

    Args:
        valid: [N] bool.
        depth: [N] float64 camera z, > 0 where valid.
    """
    n = 0
    for i in range(valid.shape[0]):
        n += valid[i]
    index = np.empty(n, dtype=np.int64)
    keys = np.empty(n, dtype=np.uint64)
    bits = depth.view(np.uint64)
    j = 0
    for i in range(valid.shape[0]):
        if valid[i]:
            index[j] = i
            keys[j] = bits[i]
            j += 1
    index_tmp = np.empty_like(index)
    keys_tmp = np.empty_like(keys)
    counts = np.empty(RADIX + 1, dtype=np.int64)
    mask = np.uint64(RADIX - 1)
    for shift in range(0, 64, RADIX_BITS):
        sh = np.uint64(shift)
        counts[:] = 0
        for j in range(n):
            counts[np.int64((keys[j] >> sh) & mask) + 1] += 1
        if n == 0 or counts.max() == n:
            continue
        for b in range(RADIX):
            counts[b + 1] += counts[b]
        for j in range(n):
            d = np.int64((keys[j] >> sh) & mask)
            pos = counts[d]
            counts[d] = pos + 1
            index_tmp[pos] = index[j]
            keys_tmp[pos] = keys[j]
        index, index_tmp = index_tmp, index
        keys, keys_tmp = keys_tmp, keys
    return index


@njit(parallel=True, cache=True)
def gather_kernel(
    order: np.ndarray,  # [M] int64
    params: np.ndarray,  # [N, N_PARAMS] float64
    rects: np.ndarray,  # [N, 4] int32
) -> tuple[np.ndarray, np.ndarray]:
    """Rows `order` of params and rects, contiguous (depth order)."""
    m = order.shape[0]
    out_params = np.empty((m, params.shape[1]), dtype=params.dtype)
    out_rects = np.empty((m, 4), dtype=rects.dtype)
    for j in prange(m):
        g = order[j]
        for k in range(params.shape[1]):
            out_params[j, k] = params[g, k]
        for k in range(4):
            out_rects[j, k] = rects[g, k]
    return out_params, out_rects


@njit(cache=True)
def bin_kernel(
    rects: np.ndarray,  # [M, 4] int32, in depth order
    tile_w: int,
    tile_h: int,
    tiles_x: int,
    n_tiles: int,
) -> tuple[np.ndarray, np.ndarray]:
    """Per-tile Gaussian lists by counting sort; each list keeps the front-to-back order.

    Returns:
        offsets [n_tiles + 1] int64 and lists [offsets[-1]] int32 (rows of `rects`).
    """
    offsets = np.zeros(n_tiles + 1, dtype=np.int64)
    for g in range(rects.shape[0]):
        for ty in range(rects[g, 2] // tile_h, rects[g, 3] // tile_h + 1):
            for tx in range(rects[g, 0] // tile_w, rects[g, 1] // tile_w + 1):
                offsets[ty * tiles_x + tx + 1] += 1
    for t in range(n_tiles):
        offsets[t + 1] += offsets[t]
    lists = np.empty(offsets[n_tiles], dtype=np.int32)
    cursor = offsets[:n_tiles].copy()
    for g in range(rects.shape[0]):
        for ty in range(rects[g, 2] // tile_h, rects[g, 3] // tile_h + 1):
            for tx in range(rects[g, 0] // tile_w, rects[g, 1] // tile_w + 1):
                t = ty * tiles_x + tx
                lists[cursor[t]] = g
                cursor[t] += 1
    return offsets, lists
