"""Candidate pairs of Gaussians by a sorted sweep over cells (numba), no hashing.

The means' cells (side = candidate radius) get mixed-radix keys, z fastest, so the 13
"forward" neighbour cells of a cell form five key intervals: (x, y, z+1), (x, y+1, z-1..z+1)
and (x+1, y-1..y+1, z-1..z+1). With the Gaussians in key order (a stable radix sort) and
one cursor per interval that only moves forward, every pair within one cell of each other is
met once, reading memory in order. The means and D's other inputs are copied into key order
first. The pairs within the radius are gathered into a buffer without a branch on the test
(`sqrt(d2) <= radius` as `d2 <=` the largest such d2), and D and the mergeable test then run
over the buffer, again without a branch. The pairs, their D and the mergeable test are those
of the grid search in `_estimator_clusters` (same bits); only the order in which they are
found differs, and `sort_pairs` orders them by (D, i, j) afterwards.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from glmap_tools.gaussians._estimator_candidates import pack_in_key_order
from glmap_tools.gaussians._int64 import ZERO

RADIX_BITS = 11
MAX_KEY = 1 << 62  # cells x * y * z must stay below this for the mixed-radix keys
PAIR_BUFFER = 4096  # pairs within the radius gathered before D is computed for them
SENTINEL = (1 << 63) - 1  # the run key after the last run


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
    """(run keys, run starts, run count): run r holds order[start[r]:start[r + 1]]; the key
    after the last run is a sentinel larger than any key."""
    g = keys.shape[0]
    run_key = np.empty(g + 1, dtype=np.int64)
    start = np.empty(g + 1, dtype=np.int64)
    n_runs = 0
    for s in range(g):
        k = keys[order[s]]
        if n_runs == 0 or k != run_key[n_runs - 1]:
            run_key[n_runs] = k
            start[n_runs] = s
            n_runs += 1
    start[n_runs] = g
    run_key[n_runs] = SENTINEL
    return run_key, start, n_runs


@numba.njit(cache=True)
def sqrt_bound(radius: float) -> float:
    """The largest x >= 0 with sqrt(x) <= radius in float64: `sqrt(x) <= radius` is `x <= it`."""
    x = radius * radius
    while math.sqrt(x) > radius:
        x = np.nextafter(x, -np.inf)
    while math.sqrt(np.nextafter(x, np.inf)) <= radius:
        x = np.nextafter(x, np.inf)
    return x


@numba.njit(cache=True)
def _mergeable(
    near: np.ndarray,
    rest: np.ndarray,
    buf: np.ndarray,
    n_buf: int,
    params: np.ndarray,
    out_i: np.ndarray,
    out_j: np.ndarray,
    out_d: np.ndarray,
    found: int,
) -> int:
    """Append the mergeable ones of the n_buf near pairs buf[:n_buf] (key positions s, t
    packed as s << 32 | t) to out_* from `found` (room for all n_buf assumed); returns the
    new count."""
    voxel, tau, lc, lk = params[1], params[2], params[3], params[4]
    for q in range(n_buf):  # no branches: every pair is written, the count moves if it merges
        s, t = buf[q] >> 32, buf[q] & 0xFFFFFFFF
        ex = near[0, s] - near[0, t]
        ey = near[1, s] - near[1, t]
        ez = near[2, s] - near[2, t]
        s00 = rest[s, 0] - rest[t, 0]
        s11 = rest[s, 3] - rest[t, 3]
        s22 = rest[s, 5] - rest[t, 5]
        s01 = rest[s, 1] - rest[t, 1]
        s02 = rest[s, 2] - rest[t, 2]
        s12 = rest[s, 4] - rest[t, 4]
        cr = rest[s, 6] - rest[t, 6]
        cg = rest[s, 7] - rest[t, 7]
        cb = rest[s, 8] - rest[t, 8]
        # D and the threshold term by term as `_estimator_clusters.pair_distance` (same bits)
        d = (
            math.sqrt(ex**2 + ey**2 + ez**2)
            + lc * math.sqrt(s00**2 + s11**2 + s22**2 + 2.0 * (s01**2 + s02**2 + s12**2))
            + lk * math.sqrt(cr**2 + cg**2 + cb**2)
        )
        i, j = np.int64(rest[s, 10]), np.int64(rest[t, 10])
        out_i[found], out_j[found], out_d[found] = min(i, j), max(i, j), d
        found += d < 2.0 * voxel * (1.0 + tau * (rest[s, 9] + rest[t, 9]))
    return found


@numba.njit(cache=True)
def _near_pairs(
    r: int,
    r_end: int,
    run_key: np.ndarray,
    start: np.ndarray,
    near: np.ndarray,
    offsets: np.ndarray,
    cursors: np.ndarray,
    near_sq: float,
    buf: np.ndarray,
) -> tuple[int, int]:
    """Gather the pairs within the radius met by runs r, r + 1, ... r_end - 1 into `buf`,
    until the next run might not fit; returns (that run, pairs gathered).

    Run r (key k) meets itself and the runs with keys in [k + offsets[0, m],
    k + offsets[1, m]] for m = 1..5, which the key order holds at contiguous positions;
    cursors[0, m] (first run with key >= the low end) and cursors[1, m] (first run past
    the high end) only move forward (run_key ends with a sentinel). The run's own tail and
    the run of key k + 1 (m = 1) are one range of positions.
    """
    xs, ys, zs = near[0], near[1], near[2]
    t_lo = np.empty(6, dtype=np.int64)
    t_hi = np.empty(6, dtype=np.int64)
    n_buf = 0
    while r < r_end:
        k = run_key[r]
        width = 0
        for m in range(1, 6):
            c = cursors[0, m]
            while run_key[c] < k + offsets[0, m]:
                c += 1
            cursors[0, m] = c
            t_lo[m] = start[c]
            c = max(c, cursors[1, m])
            while run_key[c] <= k + offsets[1, m]:
                c += 1
            cursors[1, m] = c
            t_hi[m] = start[c]
            width += t_hi[m] - t_lo[m]
        s0, s1 = start[r], start[r + 1]
        if n_buf + (s1 - s0) * (s1 - s0 + width) > buf.shape[0]:
            break
        for s in range(s0, s1):
            sx, sy, sz = xs[s], ys[s], zs[s]
            t_lo[1] = s + 1  # the own run's tail, then the run of key k + 1
            packed = s << 32
            for m in range(1, 6):
                # no branch on the test: every pair is written, the count moves if it is near
                for t in range(t_lo[m], t_hi[m]):
                    ex, ey, ez = sx - xs[t], sy - ys[t], sz - zs[t]
                    buf[n_buf] = packed | t
                    n_buf += ex**2 + ey**2 + ez**2 <= near_sq
        r += 1
    return r, n_buf


@numba.njit(cache=True)
def _grow(values: np.ndarray, size: int) -> np.ndarray:
    out = np.empty(size, dtype=values.dtype)
    out[: values.shape[0]] = values
    return out


@numba.njit(cache=True)
def _sweep_runs(
    r0: int,
    r1: int,
    run_key: np.ndarray,
    start: np.ndarray,
    near: np.ndarray,
    rest: np.ndarray,
    offsets: np.ndarray,
    params: np.ndarray,
    buffer: int,
    room: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """The mergeable pairs met by runs r0..r1-1: (i, j, D, count), outputs of >= count rows.

    `room` is the outputs' first size (they grow when more pairs merge).
    """
    n_runs = run_key.shape[0] - 1
    cursors = np.zeros((2, 6), dtype=np.int64)
    if r0 < n_runs:  # where the forward-only cursors stand at run r0
        k = run_key[r0]
        for m in range(1, 6):
            cursors[0, m] = np.searchsorted(run_key, k + offsets[0, m], side="left")
            cursors[1, m] = np.searchsorted(run_key, k + offsets[1, m], side="right")
    near_sq = sqrt_bound(params[0])
    buf = np.empty(max(buffer, 1), dtype=np.int64)
    out_i = np.empty(room, dtype=np.int64)
    out_j = np.empty(room, dtype=np.int64)
    out_d = np.empty(room)
    found = ZERO
    r = r0
    while r < r1:  # the buffer fills, the pairs in it that merge are kept, and so on
        r_next, n_buf = _near_pairs(r, r1, run_key, start, near, offsets, cursors, near_sq, buf)
        if r_next == r and n_buf == 0:  # one run has more pairs to test than the buffer holds
            buf = np.empty(2 * buf.shape[0], dtype=np.int64)
            continue
        if found + n_buf > out_i.shape[0]:
            room = max(2 * out_i.shape[0], found + n_buf)
            out_i, out_j, out_d = _grow(out_i, room), _grow(out_j, room), _grow(out_d, room)
        found = _mergeable(near, rest, buf, n_buf, params, out_i, out_j, out_d, found)
        r = r_next
    return out_i, out_j, out_d, found


@numba.njit(cache=True, parallel=True)
def _sweep_parallel(
    bounds: np.ndarray,
    run_key: np.ndarray,
    start: np.ndarray,
    near: np.ndarray,
    rest: np.ndarray,
    offsets: np.ndarray,
    params: np.ndarray,
    buffer: int,
    room: int,
    all_i: np.ndarray,
    all_j: np.ndarray,
    all_d: np.ndarray,
    found: np.ndarray,
) -> None:
    """Chunk c (runs bounds[c]..bounds[c + 1]-1) writes its pairs at c * room, if they fit."""
    for c in numba.prange(bounds.shape[0] - 1):  # nothing else here: array code spawns parfors
        _sweep_chunk(np.int64(c), bounds, run_key, start, near, rest, offsets, params, buffer,
                     room, all_i, all_j, all_d, found)  # fmt: skip


@numba.njit(cache=True)
def _sweep_chunk(
    c: np.int64,  # int64 in both of the parfor's typings (one types c uint64): one compile
    bounds: np.ndarray,
    run_key: np.ndarray,
    start: np.ndarray,
    near: np.ndarray,
    rest: np.ndarray,
    offsets: np.ndarray,
    params: np.ndarray,
    buffer: int,
    room: int,
    all_i: np.ndarray,
    all_j: np.ndarray,
    all_d: np.ndarray,
    found: np.ndarray,
) -> None:
    pi, pj, d, n = _sweep_runs(
        bounds[c], bounds[c + 1], run_key, start, near, rest, offsets, params, buffer, room
    )
    found[c] = n
    if n <= room:  # else the caller runs this chunk again
        base = c * room
        for q in range(n):
            all_i[base + q], all_j[base + q], all_d[base + q] = pi[q], pj[q], d[q]


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
    buffer: int = PAIR_BUFFER,
    n_chunks: int = 1,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """All mergeable pairs (i < j, ||mu_i - mu_j|| <= radius, D < threshold), unordered.

    Args:
        keys: [G] cell keys from `cell_keys` (all >= 0).
        params: [5] (radius, voxel, tau, lambda_cov, lambda_color).
        buffer: pairs within the radius gathered before their D is computed (grows when
            one run meets more).
        n_chunks: > 1 splits the runs into that many chunks of about equal Gaussian counts
            over the thread team; the output does not depend on it.

    Returns:
        (i [K], j [K], D [K]).
    """
    order = radix_order(keys)
    near, rest = pack_in_key_order(order, means, covs, colors, kappa)
    return sweep_packed(keys, order, ny, nz, near, rest, params, buffer, n_chunks)


@numba.njit(cache=True)
def sweep_packed(
    keys: np.ndarray,
    order: np.ndarray,
    ny: int,
    nz: int,
    near: np.ndarray,
    rest: np.ndarray,
    params: np.ndarray,
    buffer: int = PAIR_BUFFER,
    n_chunks: int = 1,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`sweep_pairs` on the Gaussians already in key order.

    Args:
        keys: [G] cell keys from `cell_keys` (all >= 0).
        order: [G] `radix_order(keys)`.
        near: [3, G] means in key order (x, y, z rows).
        rest: [G, 11] covariance row, colour, kappa and index in key order
            (`pack_in_key_order`).
    """
    g = keys.shape[0]
    run_key, start, n_runs = _key_runs(keys, order)
    run_key, start = run_key[: n_runs + 1], start[: n_runs + 1]
    yz = ny * nz
    offsets = np.array(
        [
            [0, 1, nz - 1, yz - nz - 1, yz - 1, yz + nz - 1],
            [0, 1, nz + 1, yz - nz + 1, yz + 1, yz + nz + 1],
        ]
    )
    if n_chunks <= 1:
        out_i, out_j, out_d, found = _sweep_runs(
            ZERO, n_runs, run_key, start, near, rest, offsets, params, buffer, g + 16
        )
    else:
        bounds = np.empty(n_chunks + 1, dtype=np.int64)  # runs of about g / n_chunks Gaussians
        for c in range(n_chunks + 1):
            bounds[c] = np.searchsorted(start, c * g // n_chunks, side="left")
        bounds[n_chunks] = n_runs
        room = g // n_chunks + 16
        all_i = np.empty(n_chunks * room, dtype=np.int64)
        all_j = np.empty(n_chunks * room, dtype=np.int64)
        all_d = np.empty(n_chunks * room)
        counts = np.zeros(n_chunks, dtype=np.int64)
        _sweep_parallel(
            bounds, run_key, start, near, rest, offsets, params, buffer, room, all_i, all_j,
            all_d, counts,
        )  # fmt: skip
        found = counts.sum()
        out_i = np.empty(found, dtype=np.int64)
        out_j = np.empty(found, dtype=np.int64)
        out_d = np.empty(found)
        at = 0
        for c in range(n_chunks):
            n = counts[c]
            if n <= room:
                out_i[at : at + n] = all_i[c * room : c * room + n]
                out_j[at : at + n] = all_j[c * room : c * room + n]
                out_d[at : at + n] = all_d[c * room : c * room + n]
            else:  # more than its room merged: run it again here
                pi, pj, d, _ = _sweep_runs(
                    bounds[c], bounds[c + 1], run_key, start, near, rest, offsets, params,
                    buffer, n,
                )  # fmt: skip
                out_i[at : at + n], out_j[at : at + n], out_d[at : at + n] = pi[:n], pj[:n], d[:n]
            at += n
    return out_i[:found], out_j[:found], out_d[:found]
