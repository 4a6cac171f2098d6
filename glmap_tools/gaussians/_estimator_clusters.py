"""Numba kernels of the merge inside one fit: mergeable pairs, their order, the clusters.

Candidate pairs come from a block grid over the means with cell = candidate radius; each
Gaussian searches its own cell and the 13 "forward" neighbour cells, so every pair is met
once. Pairs are ordered by (D, i, j) with a bucket sort. Clusters grow by an ordered,
size-capped union-find on the members' moment sums (`_estimator_union`), and each cluster's
Gaussian is summed over the set union of its members' 27-neighbourhoods.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from glmap_tools.gaussians._estimator_grid import SLOTS, neighbour_tables, slot_of
from glmap_tools.gaussians._estimator_numba import N_MOMENTS
from glmap_tools.gaussians._estimator_voxels import CELL_MARGIN
from glmap_tools.gaussians._int64 import ZERO

PAIRS_PER_GAUSSIAN = 16  # output room per Gaussian before a chunk is redone with more
CROWDED_BUCKET = 32  # pairs in a D bucket past which it is sorted by stable sorts
MAX_FLOAT = np.finfo(np.float64).max


@numba.njit(cache=True)
def mean_cells(means: np.ndarray, radius: float) -> np.ndarray:
    """[G, 3] int64 cells of side `radius` of the (relative, >= 0) means."""
    g = means.shape[0]
    cells = np.empty((g, 3), dtype=np.int64)
    for i in range(g):
        for a in range(3):
            cells[i, a] = np.int64(math.floor(means[i, a] / radius)) + CELL_MARGIN
    return cells


@numba.njit(cache=True)
def cell_lists(cells: np.ndarray, block: np.ndarray, n_blocks: int) -> tuple:
    """Per block slot, the ascending linked list of the Gaussians in that cell.

    Returns:
        (head [B * 64], next [G]), -1 terminated.
    """
    g = cells.shape[0]
    head = np.full(n_blocks * SLOTS, -1, dtype=np.int64)
    nxt = np.empty(g, dtype=np.int64)
    for i in range(g - 1, -1, -1):
        flat = block[i] * SLOTS + slot_of(cells[i, 0], cells[i, 1], cells[i, 2])
        nxt[i] = head[flat]
        head[flat] = i
    return head, nxt


@numba.njit(cache=True)
def pair_distance(
    means: np.ndarray, covs: np.ndarray, colors: np.ndarray, i: int, j: int, lc: float, lk: float
) -> float:
    """D(G_i, G_j) on covariance rows (xx xy xz yy yz zz), in `merge.pair_distance` order."""
    dx = means[i, 0] - means[j, 0]
    dy = means[i, 1] - means[j, 1]
    dz = means[i, 2] - means[j, 2]
    d_mu = math.sqrt(dx**2 + dy**2 + dz**2)
    s00 = covs[i, 0] - covs[j, 0]
    s11 = covs[i, 3] - covs[j, 3]
    s22 = covs[i, 5] - covs[j, 5]
    s01 = covs[i, 1] - covs[j, 1]
    s02 = covs[i, 2] - covs[j, 2]
    s12 = covs[i, 4] - covs[j, 4]
    d_cov = math.sqrt(s00**2 + s11**2 + s22**2 + 2.0 * (s01**2 + s02**2 + s12**2))
    cr = colors[i, 0] - colors[j, 0]
    cg = colors[i, 1] - colors[j, 1]
    cb = colors[i, 2] - colors[j, 2]
    d_col = math.sqrt(cr**2 + cg**2 + cb**2)
    return d_mu + lc * d_cov + lk * d_col


@numba.njit(cache=True)
def _pairs_of_range(
    lo: int,
    hi: int,
    cells: np.ndarray,
    block: np.ndarray,
    block_nbrs: np.ndarray,
    head: np.ndarray,
    nxt: np.ndarray,
    means: np.ndarray,
    covs: np.ndarray,
    colors: np.ndarray,
    kappa: np.ndarray,
    params: np.ndarray,
    out_i: np.ndarray,
    out_j: np.ndarray,
    out_d: np.ndarray,
    start: int,
    room: int,
) -> int:
    """Mergeable pairs met by Gaussians lo..hi-1, written from `start` (at most `room`).

    Returns the number found (which may exceed `room`; those are not written).
    """
    radius, voxel, tau, lc, lk = params[0], params[1], params[2], params[3], params[4]
    codes, slots = neighbour_tables()
    found = 0
    for i in range(lo, hi):
        slot = slot_of(cells[i, 0], cells[i, 1], cells[i, 2])
        for code in range(13, 27):  # own cell (13) and the 13 forward neighbours
            nb = block_nbrs[block[i], codes[slot, code]]
            if nb < 0:
                continue
            j = head[nb * SLOTS + slots[slot, code]]
            while j >= 0:
                if code != 13 or j > i:
                    ex = means[i, 0] - means[j, 0]
                    ey = means[i, 1] - means[j, 1]
                    ez = means[i, 2] - means[j, 2]
                    if math.sqrt(ex**2 + ey**2 + ez**2) <= radius:
                        a, b = (i, j) if i < j else (j, i)
                        d = pair_distance(means, covs, colors, a, b, lc, lk)
                        if d < 2.0 * voxel * (1.0 + tau * (kappa[a] + kappa[b])):
                            if found < room:
                                out_i[start + found] = a
                                out_j[start + found] = b
                                out_d[start + found] = d
                            found += 1
                j = nxt[j]
    return found


@numba.njit(cache=True, parallel=True)
def _pairs_parallel(
    n_chunks: int,
    cells: np.ndarray,
    block: np.ndarray,
    block_nbrs: np.ndarray,
    head: np.ndarray,
    nxt: np.ndarray,
    means: np.ndarray,
    covs: np.ndarray,
    colors: np.ndarray,
    kappa: np.ndarray,
    params: np.ndarray,
    buf_i: np.ndarray,
    buf_j: np.ndarray,
    buf_d: np.ndarray,
    room: int,
    found: np.ndarray,
) -> None:
    g = means.shape[0]
    for c in numba.prange(n_chunks):  # nothing else here: array code would spawn parfors
        found[c] = _pairs_of_range(
            c * g // n_chunks, (c + 1) * g // n_chunks, cells, block, block_nbrs, head, nxt,
            means, covs, colors, kappa, params, buf_i, buf_j, buf_d, c * room, room,
        )  # fmt: skip


@numba.njit(cache=True)
def pairs_by_chunk(
    n_chunks: int,
    cells: np.ndarray,
    block: np.ndarray,
    block_nbrs: np.ndarray,
    head: np.ndarray,
    nxt: np.ndarray,
    means: np.ndarray,
    covs: np.ndarray,
    colors: np.ndarray,
    kappa: np.ndarray,
    params: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """All mergeable pairs (i < j, ||mu_i - mu_j|| <= radius, D < threshold), unordered.

    Args:
        params: [5] (radius, voxel, tau, lambda_cov, lambda_color).

    Returns:
        (i [K], j [K], D [K]).
    """
    g = means.shape[0]
    room = PAIRS_PER_GAUSSIAN * ((g + n_chunks - 1) // n_chunks)
    buf_i = np.empty(n_chunks * room, dtype=np.int64)
    buf_j = np.empty(n_chunks * room, dtype=np.int64)
    buf_d = np.empty(n_chunks * room)
    found = np.zeros(n_chunks, dtype=np.int64)
    if n_chunks == 1:  # no thread team at all: small inputs
        found[0] = _pairs_of_range(
            ZERO, g, cells, block, block_nbrs, head, nxt, means, covs, colors, kappa,
            params, buf_i, buf_j, buf_d, ZERO, room,
        )  # fmt: skip
    else:
        _pairs_parallel(
            n_chunks, cells, block, block_nbrs, head, nxt, means, covs, colors, kappa, params,
            buf_i, buf_j, buf_d, room, found,
        )  # fmt: skip
    total = found.sum()
    out_i = np.empty(total, dtype=np.int64)
    out_j = np.empty(total, dtype=np.int64)
    out_d = np.empty(total)
    offset = ZERO
    for c in range(n_chunks):
        lo, hi = c * g // n_chunks, (c + 1) * g // n_chunks
        if found[c] <= room:
            out_i[offset : offset + found[c]] = buf_i[c * room : c * room + found[c]]
            out_j[offset : offset + found[c]] = buf_j[c * room : c * room + found[c]]
            out_d[offset : offset + found[c]] = buf_d[c * room : c * room + found[c]]
        else:  # this chunk overflowed its room: redo it straight into the output
            _pairs_of_range(
                lo, hi, cells, block, block_nbrs, head, nxt, means, covs, colors, kappa,
                params, out_i, out_j, out_d, offset, found[c],
            )  # fmt: skip
        offset += found[c]
    return out_i, out_j, out_d


@numba.njit(cache=True)
def _before(d: float, i: int, j: int, d_other: float, i_other: int, j_other: int) -> bool:
    """(d, i, j) < (d_other, i_other, j_other)."""
    return d < d_other or (d == d_other and (i < i_other or (i == i_other and j < j_other)))


@numba.njit(cache=True)
def sort_pairs(pi: np.ndarray, pj: np.ndarray, d: np.ndarray) -> np.ndarray:
    """[K, 2] pairs sorted by (D, i, j), whatever their order: a bucket sort on D, then
    insertion sort per bucket. A crowded bucket of one D (the D = 0 of duplicate Gaussians)
    sorts the packed (i, j); one of several D, stable sorts by (i, j) and then by D."""
    k = d.shape[0]
    out = np.empty((k, 2), dtype=np.int64)
    if k == 0:
        return out
    d_max = d.max()
    n_buckets = k
    scale = n_buckets / d_max if d_max > 0 else 0.0
    scale = min(scale, MAX_FLOAT)  # a subnormal d_max: one bucket, never 0 * inf
    bucket = np.empty(k, dtype=np.int64)
    start = np.zeros(n_buckets + 1, dtype=np.int64)
    for p in range(k):
        b = min(n_buckets - 1, np.int64(d[p] * scale))
        bucket[p] = b
        start[b + 1] += 1
    for b in range(n_buckets):
        start[b + 1] += start[b]
    fill = start[:-1].copy()
    sd = np.empty(k)
    for p in range(k):
        q = fill[bucket[p]]
        fill[bucket[p]] += 1
        sd[q], out[q, 0], out[q, 1] = d[p], pi[p], pj[p]
    g = max(pi.max(), pj.max()) + 1
    for b in range(n_buckets):
        lo, hi = start[b], start[b + 1]
        if hi - lo > CROWDED_BUCKET:
            if _all_equal(sd, lo, hi):  # one D (the duplicates' 0): the order is (i, j)'s
                by_pair = out[lo:hi, 0] * g + out[lo:hi, 1]
                by_pair.sort()
                for a in range(hi - lo):
                    out[lo + a, 0], out[lo + a, 1] = by_pair[a] // g, by_pair[a] % g
                continue
            by_index = np.argsort(out[lo:hi, 0] * g + out[lo:hi, 1], kind="mergesort")
            by_d = by_index[np.argsort(sd[lo:hi][by_index], kind="mergesort")]
            di, oi, oj = sd[lo:hi][by_d], out[lo:hi, 0][by_d], out[lo:hi, 1][by_d]
            for a in range(hi - lo):
                sd[lo + a], out[lo + a, 0], out[lo + a, 1] = di[a], oi[a], oj[a]
            continue
        for a in range(lo + 1, hi):
            dq, iq, jq = sd[a], out[a, 0], out[a, 1]
            c = a - 1
            while c >= lo and _before(dq, iq, jq, sd[c], out[c, 0], out[c, 1]):
                sd[c + 1], out[c + 1, 0], out[c + 1, 1] = sd[c], out[c, 0], out[c, 1]
                c -= 1
            sd[c + 1], out[c + 1, 0], out[c + 1, 1] = dq, iq, jq
    return out


@numba.njit(cache=True)
def _all_equal(values: np.ndarray, lo: int, hi: int) -> bool:
    """values[lo:hi] all equal (a range of >= 1)."""
    first = values[lo]
    same = True
    for a in range(lo + 1, hi):
        same &= values[a] == first
    return same


@numba.njit(cache=True)
def trace_rows(sums: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """[G, 5] additive rows (n, sx, sy, sz, sxx + syy + szz) of the moment rows sums[rows]."""
    out = np.empty((rows.shape[0], 5))
    for i in range(rows.shape[0]):
        r = rows[i]
        out[i, 0], out[i, 1], out[i, 2], out[i, 3] = sums[r, 0], sums[r, 1], sums[r, 2], sums[r, 3]
        out[i, 4] = sums[r, 4] + sums[r, 7] + sums[r, 9]
    return out


@numba.njit(cache=True)
def _clusters_range(
    lo: int,
    hi: int,
    start: np.ndarray,
    members: np.ndarray,
    emitted: np.ndarray,
    neighbours: np.ndarray,
    first: np.ndarray,
    n_neighbours: np.ndarray,
    sums: np.ndarray,
    moments: np.ndarray,
    out: np.ndarray,
) -> None:
    stamp = np.full(moments.shape[0], -1, dtype=np.int32)
    for c in range(lo, hi):
        if start[c + 1] - start[c] == 1:
            out[c] = sums[emitted[members[start[c]]]]
            continue
        # The first member's neighbourhood is its `sums` row (summed in the same order from
        # zero, so the same bits); the others add the neighbours not seen yet.
        v = emitted[members[start[c]]]
        for q in range(first[v], first[v] + n_neighbours[v]):
            stamp[neighbours[q]] = c
        a0, a1, a2, a3, a4 = sums[v, 0], sums[v, 1], sums[v, 2], sums[v, 3], sums[v, 4]
        a5, a6, a7, a8, a9 = sums[v, 5], sums[v, 6], sums[v, 7], sums[v, 8], sums[v, 9]
        a10, a11, a12 = sums[v, 10], sums[v, 11], sums[v, 12]
        for k in range(start[c] + 1, start[c + 1]):
            v = emitted[members[k]]
            for q in range(first[v], first[v] + n_neighbours[v]):
                u = neighbours[q]
                if stamp[u] == c:
                    continue
                stamp[u] = c
                m = moments[u]
                a0, a1, a2, a3 = a0 + m[0], a1 + m[1], a2 + m[2], a3 + m[3]
                a4, a5, a6, a7 = a4 + m[4], a5 + m[5], a6 + m[6], a7 + m[7]
                a8, a9, a10 = a8 + m[8], a9 + m[9], a10 + m[10]
                a11, a12 = a11 + m[11], a12 + m[12]
        o = out[c]
        o[0], o[1], o[2], o[3], o[4], o[5], o[6] = a0, a1, a2, a3, a4, a5, a6
        o[7], o[8], o[9], o[10], o[11], o[12] = a7, a8, a9, a10, a11, a12


@numba.njit(cache=True, parallel=True)
def _clusters_parallel(
    n_chunks: int,
    start: np.ndarray,
    members: np.ndarray,
    emitted: np.ndarray,
    neighbours: np.ndarray,
    first: np.ndarray,
    n_neighbours: np.ndarray,
    sums: np.ndarray,
    moments: np.ndarray,
    out: np.ndarray,
) -> None:
    n_clusters = out.shape[0]
    for chunk in numba.prange(n_chunks):
        _clusters_range(
            chunk * n_clusters // n_chunks, (chunk + 1) * n_clusters // n_chunks, start,
            members, emitted, neighbours, first, n_neighbours, sums, moments, out,
        )  # fmt: skip


@numba.njit(cache=True)
def cluster_moments(
    labels: np.ndarray,
    emitted: np.ndarray,
    neighbours: np.ndarray,
    first: np.ndarray,
    n_neighbours: np.ndarray,
    sums: np.ndarray,
    moments: np.ndarray,
    n_chunks: int,
) -> np.ndarray:
    """[C, 13] moment rows of each cluster over the set union of its members' neighbourhoods.

    Args:
        labels: [G] smallest member of each Gaussian's cluster; clusters are output in
            increasing label order.
        emitted: [G] voxel of each Gaussian.
        neighbours: occupied neighbour voxels of each voxel v, in
            neighbours[first[v] : first[v] + n_neighbours[v]].
        first: [V] where v's list starts.
        n_neighbours: [V] its length.
        sums: [V, 13] each voxel's neighbourhood moments (used for singletons).
        moments: [V, 13] each voxel's own moments.
        n_chunks: parallel work items.
    """
    g = labels.shape[0]
    rank = np.full(g, -1, dtype=np.int64)
    n_clusters = ZERO
    for e in range(g):
        if labels[e] == e:
            rank[e] = n_clusters
            n_clusters += 1
    start = np.zeros(n_clusters + 1, dtype=np.int64)
    for e in range(g):
        start[rank[labels[e]] + 1] += 1
    for c in range(n_clusters):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    members = np.empty(g, dtype=np.int64)
    for e in range(g):
        c = rank[labels[e]]
        members[fill[c]] = e
        fill[c] += 1
    out = np.empty((n_clusters, N_MOMENTS))
    if n_chunks == 1:
        _clusters_range(
            ZERO, n_clusters, start, members, emitted, neighbours, first, n_neighbours, sums,
            moments, out,
        )  # fmt: skip
    else:
        _clusters_parallel(
            n_chunks, start, members, emitted, neighbours, first, n_neighbours, sums, moments,
            out,
        )  # fmt: skip
    return out
