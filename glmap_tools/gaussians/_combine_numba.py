"""Numba kernels of `merge.combine`: count-weighted Gaussians of groups, to the bit as the
numpy formula computes them.

numpy sums a group's rows with `add.reduceat`: the first row plus numpy's pairwise sum of
the rest (eight accumulators from eight terms on, blocks of up to 128). `_reduce` sums in
that order, so a group of up to MAX_MEMBERS rows gives the same bits as the numpy path.
`_reduce` and `_pairwise` are inlined where they are called (numba IR): called, each sum paid
a call with an array argument, ~50 ns: a combine of one member took 0.7 us, inlined 0.35 us.
"""

from __future__ import annotations

import numba
import numpy as np

MAX_MEMBERS = 129  # numpy sums up to 128 terms (+ the first) in one block


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


@numba.njit(cache=True, nogil=True)
def combine_scratch() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:  # pragma: no cover
    """Work arrays of `combine_into`: (w, v, mu, dev)."""
    return np.empty(MAX_MEMBERS), np.empty(MAX_MEMBERS), np.empty(3), np.empty((MAX_MEMBERS, 3))


@numba.njit(cache=True, nogil=True)
def combine_into(  # pragma: no cover - numba
    members: np.ndarray, m: int, scratch: tuple, g: tuple, eps: float, out: tuple, o: int
) -> None:
    """Write `merge.combine` of rows members[:m] of the Gaussians g (means, covs, colors,
    opacities, counts) into row o of out (the same five arrays); scratch: `combine_scratch`."""
    w, v, mu, dev = scratch
    means, covs, colors, opacities, counts = g
    out_means, out_covs, out_colors, out_opacities, out_counts = out
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
def combine_groups(  # pragma: no cover - numba
    order: np.ndarray, starts: np.ndarray, g: tuple, eps: float, out: tuple
) -> None:
    """Group k is rows order[starts[k] : starts[k + 1]] (at most MAX_MEMBERS, in order) of the
    Gaussians g; its combination goes to row k of out (see `combine_into`)."""
    scratch = combine_scratch()
    for k in range(starts.shape[0] - 1):
        members = order[starts[k] : starts[k + 1]]
        combine_into(members, members.shape[0], scratch, g, eps, out, k)


@numba.njit(cache=True, nogil=True, inline="always")
def combine_two_into(g: tuple, eps: float, out: tuple, o: int) -> None:  # pragma: no cover
    """`combine_into` of rows 0 and 1 of g (a re-observed voxel: its stored Gaussian and one
    new), written out with the same expressions in registers: `_reduce` of two terms is
    v[0] + (-0.0 + v[1])."""
    means, covs, colors, opacities, counts = g
    out_means, out_covs, out_colors, out_opacities, out_counts = out
    w0 = np.float64(counts[0])
    w1 = np.float64(counts[1])
    total = w0 + (-0.0 + w1)
    mu0 = np.empty(3)
    for d in range(3):
        mu0[d] = (np.float64(means[0, d]) * w0 + (-0.0 + np.float64(means[1, d]) * w1)) / total
        out_means[o, d] = np.float32(mu0[d])
    for a in range(3):
        da0 = np.float64(means[0, a]) - mu0[a]
        da1 = np.float64(means[1, a]) - mu0[a]
        for b in range(3):
            e = eps if a == b else 0.0
            db0 = np.float64(means[0, b]) - mu0[b]
            db1 = np.float64(means[1, b]) - mu0[b]
            v0 = ((np.float64(covs[0, a, b]) - e) + da0 * db0) * w0
            v1 = ((np.float64(covs[1, a, b]) - e) + da1 * db1) * w1
            out_covs[o, a, b] = np.float32((v0 + (-0.0 + v1)) / total + e)
    for d in range(3):
        c = (np.float64(colors[0, d]) * w0 + (-0.0 + np.float64(colors[1, d]) * w1)) / total
        out_colors[o, d] = np.float32(min(max(c, 0.0), 1.0))
    v0 = np.float64(opacities[0]) * w0
    out_opacities[o] = np.float32((v0 + (-0.0 + np.float64(opacities[1]) * w1)) / total)
    out_counts[o] = np.uint32(total)
