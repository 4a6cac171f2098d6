"""Candidate pairs of Gaussians by a sorted sweep over cells (numba), no hashing.

The means' cells (side = candidate radius) get mixed-radix keys, z fastest, so the 13
"forward" neighbour cells of a cell form five key intervals: (x, y, z+1), (x, y+1, z-1..z+1)
and (x+1, y-1..y+1, z-1..z+1). With the Gaussians in key order (a stable radix sort) and
one cursor per interval that only moves forward, every pair within one cell of each other is
met once, reading memory in order. The pairs, their D and the mergeable test are those of
the grid search in `_estimator_clusters`; only the order in which they are found differs,
and `sort_pairs` orders them by (D, i, j) afterwards.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from glmap_tools.gaussians._estimator_clusters import pair_distance

RADIX_BITS = 11
MAX_KEY = 1 << 62  # cells x * y * z must stay below this for the mixed-radix keys


@numba.njit(cache=True)
def cell_keys(cells: np.ndarray) -> tuple[np.ndarray, int, int]:
    """(keys [G] int64, y extent, z extent): key = (x * Y + y) * Z + z of each cell.

    Returns keys of -1 when the extents would overflow MAX_KEY (the caller falls back).
    """
    g = cells.shape[0]
    hi = np.zeros(3, dtype=np.int64)
    for i in range(g):
        for a in range(3):
            hi[a] = max(hi[a], cells[i, a])
    ny, nz = hi[1] + 2, hi[2] + 2  # room for y + 1 and z + 1
    keys = np.empty(g, dtype=np.int64)
    if (hi[0] + 2) * ny > MAX_KEY // nz:
        keys[:] = -1
        return keys, ny, nz
    for i in range(g):
        keys[i] = (cells[i, 0] * ny + cells[i, 1]) * nz + cells[i, 2]
    return keys, ny, nz


@numba.njit(cache=True)
def radix_order(keys: np.ndarray) -> np.ndarray:
    """Stable order of non-negative int64 keys: LSD radix sort, passes with one digit skipped."""
    n = keys.shape[0]
    order = np.arange(n)
    tmp = np.empty(n, dtype=np.int64)
    top = 0
    for i in range(n):
        top = max(top, keys[i])
    radix = 1 << RADIX_BITS
    mask = radix - 1
    shift = 0
    while (top >> shift) > 0:
        counts = np.zeros(radix + 1, dtype=np.int64)
        for i in range(n):
            counts[((keys[i] >> shift) & mask) + 1] += 1
        if counts.max() < n:  # not every key shares this digit
            for b in range(radix):
                counts[b + 1] += counts[b]
            for i in range(n):
                o = order[i]
                d = (keys[o] >> shift) & mask
                tmp[counts[d]] = o
                counts[d] += 1
            order, tmp = tmp, order
        shift += RADIX_BITS
    return order


@numba.njit(cache=True)
def _key_runs(keys: np.ndarray, order: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """(run keys, run starts, run count): run r holds order[start[r]:start[r + 1]]."""
    g = keys.shape[0]
    run_key = np.empty(g, dtype=np.int64)
    start = np.empty(g + 1, dtype=np.int64)
    n_runs = 0
    for s in range(g):
        k = keys[order[s]]
        if n_runs == 0 or k != run_key[n_runs - 1]:
            run_key[n_runs] = k
            start[n_runs] = s
            n_runs += 1
    start[n_runs] = g
    return run_key, start, n_runs


@numba.njit(cache=True)
def sweep_pairs(
    keys: np.ndarray,
    ny: int,
    nz: int,
    means: np.ndarray,
    covs: np.ndarray,
    colors: np.ndarray,
    kappa: np.ndarray,
    params: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """All mergeable pairs (i < j, ||mu_i - mu_j|| <= radius, D < threshold), by (i, j).

    Args:
        keys: [G] cell keys from `cell_keys` (all >= 0).
        params: [5] (radius, voxel, tau, lambda_cov, lambda_color).

    Returns:
        (i [K], j [K], D [K]).
    """
    g = keys.shape[0]
    order = radix_order(keys)
    run_key, start, n_runs = _key_runs(keys, order)
    near = np.empty((g, 3))  # the means in key order, read in order by the sweep
    for s in range(g):
        for a in range(3):
            near[s, a] = means[order[s], a]
    # Interval m of a run with key k: [k + lo_off[m], k + hi_off[m]]; m = 0 is the run itself.
    yz = ny * nz
    lo_off = np.array([0, 1, nz - 1, yz - nz - 1, yz - 1, yz + nz - 1])
    hi_off = np.array([0, 1, nz + 1, yz - nz + 1, yz + 1, yz + nz + 1])
    radius, voxel, tau, lc, lk = params[0], params[1], params[2], params[3], params[4]
    room = 4 * g + 16
    out_i = np.empty(room, dtype=np.int64)
    out_j = np.empty(room, dtype=np.int64)
    out_d = np.empty(room)
    found = 0
    for _attempt in range(2):  # the second pass only if the first ran out of room
        cursor = np.zeros(6, dtype=np.int64)
        found = 0
        for r in range(n_runs):
            k = run_key[r]
            for m in range(6):
                lo, hi = k + lo_off[m], k + hi_off[m]
                c = cursor[m]
                while c < n_runs and run_key[c] < lo:
                    c += 1
                cursor[m] = c
                while c < n_runs and run_key[c] <= hi:
                    for s in range(start[r], start[r + 1]):
                        for t in range(s + 1 if c == r else start[c], start[c + 1]):
                            ex = near[s, 0] - near[t, 0]
                            ey = near[s, 1] - near[t, 1]
                            ez = near[s, 2] - near[t, 2]
                            if not math.sqrt(ex**2 + ey**2 + ez**2) <= radius:
                                continue
                            i, j = order[s], order[t]
                            a, b = (i, j) if i < j else (j, i)
                            d = pair_distance(means, covs, colors, a, b, lc, lk)
                            if not d < 2.0 * voxel * (1.0 + tau * (kappa[a] + kappa[b])):
                                continue
                            if found < room:
                                out_i[found], out_j[found], out_d[found] = a, b, d
                            found += 1
                    c += 1
        if found <= room:
            break
        room = found
        out_i = np.empty(room, dtype=np.int64)
        out_j = np.empty(room, dtype=np.int64)
        out_d = np.empty(room)
    # In (i, j) order, as the grid search finds them: `sort_pairs` sorts each D bucket by
    # insertion, which is quick on runs of equal D (duplicate Gaussians) only when these
    # already come in (i, j) order.
    by_index = radix_order(out_i[:found] * g + out_j[:found])
    return out_i[by_index], out_j[by_index], out_d[by_index]
