"""Numba kernel of `StructureLayer.compute_update`: one merge pass over the stored voxels of
the touched chunks and the frame's new ones, both in (chunk, voxel key) order.

A voxel the frame saw is the count-weighted combination of its stored Gaussian (first) and
the frame's Gaussians there (in the frame's order), computed as `merge.combine` computes
it, to the bit: its sums are numpy's `add.reduceat` over the members, i.e. the first
member plus numpy's pairwise sum of the rest. Stored voxels the frame did not see pass
through unchanged.
"""

from __future__ import annotations

import numba
import numpy as np

MAX_MEMBERS = 129  # numpy sums up to 128 (+1) in one block; a voxel holds at most 28 (stored + 27)


@numba.njit(cache=True, nogil=True, inline="always")
def _pairwise(v: np.ndarray, start: int, n: int) -> float:  # pragma: no cover - numba
    """numpy's pairwise sum of v[start : start + n] for n <= 128 (its order, to the bit)."""
    if n < 8:
        res = -0.0
        for i in range(n):
            res += v[start + i]
        return res
    r0, r1, r2, r3 = v[start], v[start + 1], v[start + 2], v[start + 3]
    r4, r5, r6, r7 = v[start + 4], v[start + 5], v[start + 6], v[start + 7]
    i = 8
    stop = n - n % 8
    while i < stop:
        b = start + i
        r0 += v[b]
        r1 += v[b + 1]
        r2 += v[b + 2]
        r3 += v[b + 3]
        r4 += v[b + 4]
        r5 += v[b + 5]
        r6 += v[b + 6]
        r7 += v[b + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += v[start + i]
        i += 1
    return res


@numba.njit(cache=True, nogil=True, inline="always")
def _reduce(v: np.ndarray, n: int) -> float:  # pragma: no cover - numba
    """np.add.reduceat's sum of one segment v[:n]: v[0] + pairwise(v[1:n])."""
    if n == 1:
        return v[0]
    return v[0] + _pairwise(v, 1, n - 1)


@numba.njit(cache=True, nogil=True, inline="always")
def _key_less(a: np.ndarray, i: int, b: np.ndarray, j: int) -> bool:  # pragma: no cover
    """Row a[i] < row b[j], lexicographically ([N, 5] rows: chunk i, chunk j, key)."""
    for c in range(5):
        if a[i, c] != b[j, c]:
            return a[i, c] < b[j, c]
    return False


@numba.njit(cache=True, nogil=True, inline="always")
def _key_equal(a: np.ndarray, i: int, b: np.ndarray, j: int) -> bool:  # pragma: no cover
    for c in range(5):  # noqa: SIM110 (a loop numba compiles, not a generator)
        if a[i, c] != b[j, c]:
            return False
    return True


@numba.njit(cache=True, nogil=True, inline="always")
def _combine_into(  # pragma: no cover - numba
    members: np.ndarray,
    m: int,
    w: np.ndarray,
    v: np.ndarray,
    mu: np.ndarray,
    dev: np.ndarray,
    means: np.ndarray,
    covs: np.ndarray,
    colors: np.ndarray,
    opacities: np.ndarray,
    counts: np.ndarray,
    eps: float,
    o: int,
    out_means: np.ndarray,
    out_covs: np.ndarray,
    out_colors: np.ndarray,
    out_opacities: np.ndarray,
    out_counts: np.ndarray,
) -> None:
    """Write `merge.combine` of rows members[:m] (of the stacked stored and new arrays);
    w, v, mu, dev: scratch."""
    if m == 1:  # the same operations, in registers
        r = members[0]
        n = np.float64(counts[r])
        m0 = (np.float64(means[r, 0]) * n) / n
        m1 = (np.float64(means[r, 1]) * n) / n
        m2 = (np.float64(means[r, 2]) * n) / n
        d0 = np.float64(means[r, 0]) - m0
        d1 = np.float64(means[r, 1]) - m1
        d2 = np.float64(means[r, 2]) - m2
        out_means[o, 0] = np.float32(m0)
        out_means[o, 1] = np.float32(m1)
        out_means[o, 2] = np.float32(m2)
        for a in range(3):
            da = d0 if a == 0 else (d1 if a == 1 else d2)
            for b in range(3):
                db = d0 if b == 0 else (d1 if b == 1 else d2)
                e = eps if a == b else 0.0
                c = (((np.float64(covs[r, a, b]) - e) + da * db) * n) / n
                out_covs[o, a, b] = np.float32(c + e)
        for d in range(3):
            c = (np.float64(colors[r, d]) * n) / n
            out_colors[o, d] = np.float32(min(max(c, 0.0), 1.0))
        out_opacities[o] = np.float32((np.float64(opacities[r]) * n) / n)
        out_counts[o] = np.uint32(n)
        return
    for t in range(m):
        w[t] = np.float64(counts[members[t]])
    total = _reduce(w, m)
    for d in range(3):
        for t in range(m):
            v[t] = np.float64(means[members[t], d]) * w[t]
        mu[d] = _reduce(v, m) / total
        out_means[o, d] = np.float32(mu[d])
    for t in range(m):
        for d in range(3):
            dev[t, d] = np.float64(means[members[t], d]) - mu[d]
    for a in range(3):
        for b in range(3):
            e = eps if a == b else 0.0
            for t in range(m):
                v[t] = ((np.float64(covs[members[t], a, b]) - e) + dev[t, a] * dev[t, b]) * w[t]
            out_covs[o, a, b] = np.float32(_reduce(v, m) / total + e)
    for d in range(3):
        for t in range(m):
            v[t] = np.float64(colors[members[t], d]) * w[t]
        mean_colour = _reduce(v, m) / total
        out_colors[o, d] = np.float32(min(max(mean_colour, 0.0), 1.0))
    for t in range(m):
        v[t] = np.float64(opacities[members[t]]) * w[t]
    out_opacities[o] = np.float32(_reduce(v, m) / total)
    out_counts[o] = np.uint32(total)


@numba.njit(cache=True, nogil=True)
def merge_voxels(  # pragma: no cover - numba
    old_rows: np.ndarray,
    new_rows: np.ndarray,
    new_order: np.ndarray,
    means: np.ndarray,
    covs: np.ndarray,
    colors: np.ndarray,
    opacities: np.ndarray,
    counts: np.ndarray,
    eps: float,
    out_means: np.ndarray,
    out_covs: np.ndarray,
    out_colors: np.ndarray,
    out_opacities: np.ndarray,
    out_counts: np.ndarray,
    out_source: np.ndarray,
) -> int:
    """Merge the stored voxels (rows 0..K-1 of the stacked arrays, `old_rows` their [K, 5]
    (chunk, key) rows, in order) with the new ones (rows K.., `new_rows` [M, 5], visited in
    `new_order`, a stable sort). A voxel the frame saw combines its stored rows, then its new
    ones. Returns the number of output rows (in order, `out_source` the stacked row each
    was keyed by), -1 when the stored rows are out of order, -2 when a voxel gathers more
    than MAX_MEMBERS Gaussians."""
    k = old_rows.shape[0]
    for i in range(1, k):
        if _key_less(old_rows, i, old_rows, i - 1):
            return -1
    members = np.empty(MAX_MEMBERS, np.int64)
    w = np.empty(MAX_MEMBERS)
    v = np.empty(MAX_MEMBERS)
    mu = np.empty(3)
    dev = np.empty((MAX_MEMBERS, 3))
    i = 0
    j = 0
    o = 0
    m_new = new_order.shape[0]
    while i < k or j < m_new:
        if j == m_new or (i < k and _key_less(old_rows, i, new_rows, new_order[j])):
            for a in range(3):
                out_means[o, a] = means[i, a]
                out_colors[o, a] = colors[i, a]
                for b in range(3):
                    out_covs[o, a, b] = covs[i, a, b]
            out_opacities[o] = opacities[i]
            out_counts[o] = counts[i]
            out_source[o] = i
            i += 1
            o += 1
            continue
        first = new_order[j]
        m = 0
        while i < k and _key_equal(old_rows, i, new_rows, first):
            if m == MAX_MEMBERS:
                return -2
            members[m] = i
            m += 1
            i += 1
        while j < m_new and _key_equal(new_rows, new_order[j], new_rows, first):
            if m == MAX_MEMBERS:
                return -2
            members[m] = k + new_order[j]
            m += 1
            j += 1
        out_source[o] = members[0]
        _combine_into(
            members, m, w, v, mu, dev, means, covs, colors, opacities, counts, eps, o,
            out_means, out_covs, out_colors, out_opacities, out_counts,
        )  # fmt: skip
        o += 1
    return o
