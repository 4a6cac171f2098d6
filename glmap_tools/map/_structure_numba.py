"""Numba kernels of `StructureLayer.compute_update`: the frame's (chunk, voxel key) rows and
their order, then one merge pass per touched chunk over its stored voxels and the frame's.

A voxel the frame saw is the count-weighted combination of its stored Gaussian (first) and
the frame's Gaussians there (in the frame's order), computed as `merge.combine` computes
it, to the bit (`_combine_numba.combine_into`: numpy's `add.reduceat` sums). Stored voxels
the frame did not see pass through unchanged. Each chunk's arrays are written once, at
their final size: a counting pass first, then the merge.
"""

from __future__ import annotations

import numba
import numpy as np

from glmap_tools.gaussians._combine_numba import (
    MAX_MEMBERS,
    combine_into,
    combine_scratch,
    combine_two_into,
)
from glmap_tools.gaussians._int64 import ZERO

KEY_LIMIT = 1 << 62  # a mixed-radix row key must stay below this (int64)


@numba.njit(cache=True, nogil=True)
def frame_rows(means: np.ndarray, voxel: float, chunk: int) -> np.ndarray:  # pragma: no cover
    """[M, 5] int64 rows (chunk i, chunk j, key x, y, z) of the Gaussians' means [M, 3]:
    key = floor(mean / voxel) in float64, chunk = key // chunk (floor) for x and y."""
    rows = np.empty((means.shape[0], 5), np.int64)
    for r in range(means.shape[0]):
        for a in range(3):
            rows[r, 2 + a] = np.int64(np.floor(np.float64(means[r, a]) / voxel))
        rows[r, 0] = rows[r, 2] // chunk
        rows[r, 1] = rows[r, 3] // chunk
    return rows


@numba.njit(cache=True, nogil=True)
def row_order(rows: np.ndarray) -> np.ndarray:  # pragma: no cover - numba
    """`np.lexsort(rows.T[::-1])` of [K, C] int64 rows (lexicographic, stable), as one
    stable argsort of a mixed-radix key over the rows' ranges; an empty array for K > 0
    when that key would reach KEY_LIMIT (the caller sorts another way)."""
    k, width = rows.shape
    if k == 0:
        return np.zeros(0, np.int64)
    lo = rows[0].copy()
    hi = rows[0].copy()
    for r in range(1, k):
        for c in range(width):
            lo[c] = min(lo[c], rows[r, c])
            hi[c] = max(hi[c], rows[r, c])
    span = hi - lo + 1
    limit = np.int64(KEY_LIMIT)
    product = np.int64(1)
    for c in range(width):
        if span[c] <= 0 or product > (limit - 1) // span[c]:  # span past int64, or the key
            return np.zeros(0, np.int64)
        product *= span[c]
    key = np.zeros(k, np.int64)
    for r in range(k):
        v = np.int64(0)
        for c in range(width):
            v = v * span[c] + (rows[r, c] - lo[c])
        key[r] = v
    return np.argsort(key, kind="mergesort")


@numba.njit(cache=True, nogil=True)
def chunk_runs(rows: np.ndarray, order: np.ndarray) -> np.ndarray:  # pragma: no cover
    """Where each chunk's run starts in `order` (rows in (chunk, key) order), then len(order)."""
    starts = np.empty(order.shape[0] + 1, np.int64)
    n = 0
    for p in range(order.shape[0]):
        r = order[p]
        if p == 0 or rows[r, 0] != rows[order[p - 1], 0] or rows[r, 1] != rows[order[p - 1], 1]:
            starts[n] = p
            n += 1
    starts[n] = order.shape[0]
    return starts[: n + 1].copy()


@numba.njit(cache=True, nogil=True, inline="always")
def _compare(keys: np.ndarray, i: int, rows: np.ndarray, r: int) -> int:  # pragma: no cover
    """-1, 0 or 1 as keys[i] ([K, 3]) is below, equal to or above rows[r, 2:5]."""
    for c in range(3):
        if keys[i, c] != rows[r, 2 + c]:
            return -1 if keys[i, c] < rows[r, 2 + c] else 1
    return 0


@numba.njit(cache=True, nogil=True, inline="always")
def _same_key(rows: np.ndarray, r: int, s: int) -> bool:  # pragma: no cover - numba
    return rows[r, 2] == rows[s, 2] and rows[r, 3] == rows[s, 3] and rows[r, 4] == rows[s, 4]


@numba.njit(cache=True, nogil=True)
def merge_chunk(  # pragma: no cover - numba
    keys: np.ndarray, stored: tuple, rows: np.ndarray, order: np.ndarray, new: tuple, eps: float
) -> tuple:
    """One chunk's update: its stored voxels (`keys` [K, 3] in order, `stored` the five arrays
    of their Gaussians: means, covs, colors, opacities, counts) merged with the frame's
    Gaussians `new` at rows[order] (this chunk's rows, in (key, frame) order).

    Returns:
        (status, keys, means, covs, colors, opacities, counts) of the updated chunk, in key
        order; status is -1 (and the arrays empty) when the stored keys are out of order,
        -2 when a voxel gathers more than MAX_MEMBERS Gaussians, else 0.
    """
    k = keys.shape[0]
    m = order.shape[0]
    for i in range(1, k):
        for c in range(3):
            if keys[i, c] != keys[i - 1, c]:
                if keys[i, c] < keys[i - 1, c]:
                    return _failed(-1)
                break
    # Counting pass: the output rows, and whether a voxel is crowded.
    size = ZERO
    i = ZERO
    j = ZERO
    while i < k or j < m:
        if j == m or (i < k and _compare(keys, i, rows, order[j]) < 0):
            i += 1
            size += 1
            continue
        first = order[j]
        members = 0
        while i < k and _compare(keys, i, rows, first) == 0:
            members += 1
            i += 1
        while j < m and _same_key(rows, order[j], first):
            members += 1
            j += 1
        if members > MAX_MEMBERS:
            return _failed(-2)
        size += 1
    out_keys = np.empty((size, 3), np.int64)
    out = _gaussian_arrays(size)
    # A voxel's members are gathered into one small set, so `combine_into` reads one set.
    group = _gaussian_arrays(MAX_MEMBERS)
    in_order = np.arange(MAX_MEMBERS)
    scratch = combine_scratch()
    i = ZERO
    j = ZERO
    o = ZERO
    while i < k or j < m:
        if j == m or (i < k and _compare(keys, i, rows, order[j]) < 0):
            for a in range(3):
                out_keys[o, a] = keys[i, a]
            _copy_row(stored, i, out, o)
            i += 1
            o += 1
            continue
        first = order[j]
        for a in range(3):
            out_keys[o, a] = rows[first, 2 + a]
        t = 0
        while i < k and _compare(keys, i, rows, first) == 0:
            _copy_row(stored, i, group, t)
            t += 1
            i += 1
        while j < m and _same_key(rows, order[j], first):
            _copy_row(new, order[j], group, t)
            t += 1
            j += 1
        if t == 2:  # the common case: the stored Gaussian and one new
            combine_two_into(group, eps, out, o)
        else:
            combine_into(in_order, t, scratch, group, eps, out, o)
        o += 1
    return 0, out_keys, out[0], out[1], out[2], out[3], out[4]


@numba.njit(cache=True, nogil=True, inline="always")
def _copy_row(src: tuple, i: int, dst: tuple, o: int) -> None:  # pragma: no cover - numba
    """Row i of the Gaussians src (means, covs, colors, opacities, counts) into row o of dst."""
    s_means, s_covs, s_colors, s_opacities, s_counts = src
    d_means, d_covs, d_colors, d_opacities, d_counts = dst
    for a in range(3):
        d_means[o, a] = s_means[i, a]
        d_colors[o, a] = s_colors[i, a]
        for b in range(3):
            d_covs[o, a, b] = s_covs[i, a, b]
    d_opacities[o] = s_opacities[i]
    d_counts[o] = s_counts[i]


@numba.njit(cache=True, nogil=True)
def _failed(status: int) -> tuple:  # pragma: no cover - numba
    """`merge_chunk`'s answer when it cannot merge: the status and empty arrays."""
    means, covs, colors, opacities, counts = _gaussian_arrays(0)
    return status, np.empty((0, 3), np.int64), means, covs, colors, opacities, counts


@numba.njit(cache=True, nogil=True, inline="always")
def _gaussian_arrays(n: int) -> tuple:  # pragma: no cover - numba
    """Uninitialised (means, covs, colors, opacities, counts) of n Gaussians
    (`GaussianSet.allocate`'s arrays)."""
    return (
        np.empty((n, 3), np.float32),
        np.empty((n, 3, 3), np.float32),
        np.empty((n, 3), np.float32),
        np.empty(n, np.float32),
        np.empty(n, np.uint32),
    )
