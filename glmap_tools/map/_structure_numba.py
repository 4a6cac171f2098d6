"""Numba kernel of `StructureLayer.compute_update`: one merge pass over the stored voxels of
the touched chunks and the frame's new ones, both in (chunk, voxel key) order.

A voxel the frame saw is the count-weighted combination of its stored Gaussian (first) and
the frame's Gaussians there (in the frame's order), computed as `merge.combine` computes
it, to the bit: its sums are numpy's `add.reduceat` over the members, i.e. the first
member plus numpy's pairwise sum of the rest (`_combine_numba`'s sums, inlined into this
kernel: numba's cache of it holds them, so it is recompiled when this file changes, not
when that one does). Stored voxels the frame did not see pass through unchanged.
"""

from __future__ import annotations

import numba
import numpy as np

from glmap_tools.gaussians._combine_numba import MAX_MEMBERS, combine_into, combine_scratch
from glmap_tools.gaussians._int64 import ZERO


@numba.njit(cache=True, nogil=True)
def _key_less(a: np.ndarray, i: int, b: np.ndarray, j: int) -> bool:  # pragma: no cover
    """Row a[i] < row b[j], lexicographically ([N, 5] rows: chunk i, chunk j, key)."""
    for c in range(5):
        if a[i, c] != b[j, c]:
            return a[i, c] < b[j, c]
    return False


@numba.njit(cache=True, nogil=True)
def _key_equal(a: np.ndarray, i: int, b: np.ndarray, j: int) -> bool:  # pragma: no cover
    for c in range(5):  # noqa: SIM110 (a loop numba compiles, not a generator)
        if a[i, c] != b[j, c]:
            return False
    return True


@numba.njit(cache=True, nogil=True)
def merge_voxels(  # pragma: no cover - numba
    old_rows: np.ndarray,
    new_rows: np.ndarray,
    new_order: np.ndarray,
    g: tuple,
    eps: float,
    out: tuple,
    out_rows: np.ndarray,
    chunk_starts: np.ndarray,
) -> tuple[int, int]:
    """Merge the stored voxels (rows 0..K-1 of the stacked arrays, `old_rows` their [K, 5]
    (chunk, key) rows, in order) with the new ones (rows K.., `new_rows` [M, 5], visited in
    `new_order`, a stable sort). A voxel the frame saw combines its stored rows, then its new
    ones. g: the stacked Gaussians (means, covs, colors, opacities, counts); out: the same
    five arrays for the result, `out_rows` [K + M, 5] their (chunk, key) rows.

    Returns:
        (n, c): n output rows, in order, and c chunks, chunk k starting at output row
        chunk_starts[k]; n is -1 when the stored rows are out of order, -2 when a voxel
        gathers more than MAX_MEMBERS Gaussians.
    """
    k = old_rows.shape[0]
    for i in range(1, k):
        if _key_less(old_rows, i, old_rows, i - 1):
            return -1, 0
    members = np.empty(MAX_MEMBERS, np.int64)
    scratch = combine_scratch()
    means, covs, colors, opacities, counts = g
    out_means, out_covs, out_colors, out_opacities, out_counts = out
    i = ZERO
    j = ZERO
    o = ZERO
    c = ZERO
    m_new = new_order.shape[0]
    while i < k or j < m_new:
        stored = j == m_new or (i < k and _key_less(old_rows, i, new_rows, new_order[j]))
        key_rows, r = (old_rows, i) if stored else (new_rows, new_order[j])
        for a in range(5):
            out_rows[o, a] = key_rows[r, a]
        if o == 0 or out_rows[o, 0] != out_rows[o - 1, 0] or out_rows[o, 1] != out_rows[o - 1, 1]:
            chunk_starts[c] = o
            c += 1
        if stored:
            for a in range(3):
                out_means[o, a] = means[i, a]
                out_colors[o, a] = colors[i, a]
                for b in range(3):
                    out_covs[o, a, b] = covs[i, a, b]
            out_opacities[o] = opacities[i]
            out_counts[o] = counts[i]
            i += 1
            o += 1
            continue
        first = new_order[j]
        m = 0
        while i < k and _key_equal(old_rows, i, new_rows, first):
            if m == MAX_MEMBERS:
                return -2, 0
            members[m] = i
            m += 1
            i += 1
        while j < m_new and _key_equal(new_rows, new_order[j], new_rows, first):
            if m == MAX_MEMBERS:
                return -2, 0
            members[m] = k + new_order[j]
            m += 1
            j += 1
        combine_into(members, m, scratch, g, eps, out, o)
        o += 1
    return o, c
