"""Numba kernels of the fast Gaussian Estimator: per-voxel moments and Gaussians.

Moment rows hold, relative to an origin, (n, sx, sy, sz, sxx, sxy, sxz, syy, syz, szz,
r, g, b) in float64; a Gaussian is read off the sum of the rows of its points' voxels.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from glmap_tools.gaussians._estimator_grid import SLOTS, neighbour_tables
from glmap_tools.gaussians._int64 import ZERO

N_MOMENTS = 13
NEWTON_STEPS = 6  # for the smallest eigenvalue; past this the closed form takes over
LANES = 64  # Gaussians whose Newton iterations run in lockstep


@numba.njit(cache=True)
def voxel_moments(
    points: np.ndarray,
    colors: np.ndarray,
    point_voxel: np.ndarray,
    n_voxels: int,
    origin: np.ndarray,
) -> np.ndarray:
    """[V, 13] moment rows of the points of each voxel, relative to `origin`."""
    out = np.zeros((n_voxels, N_MOMENTS))
    ox, oy, oz = origin[0], origin[1], origin[2]
    for i in range(points.shape[0]):
        v = point_voxel[i]
        x = points[i, 0] - ox
        y = points[i, 1] - oy
        z = points[i, 2] - oz
        out[v, 0] += 1.0
        out[v, 1] += x
        out[v, 2] += y
        out[v, 3] += z
        out[v, 4] += x * x
        out[v, 5] += x * y
        out[v, 6] += x * z
        out[v, 7] += y * y
        out[v, 8] += y * z
        out[v, 9] += z * z
        out[v, 10] += colors[i, 0]
        out[v, 11] += colors[i, 1]
        out[v, 12] += colors[i, 2]
    return out


@numba.njit(cache=True)
def _moments_of_voxels(
    part: np.int64,
    points: np.ndarray,
    colors: np.ndarray,
    point_voxel: np.ndarray,
    split: int,
    half: int,
    origin: np.ndarray,
    out: np.ndarray,
) -> None:
    """Part 0 sums the rows of voxels < split over every point, part 1 those of the others
    over the points from `half` on; each zeroes its rows first. (`voxel_moments` keeps its
    own loop: through this one, with its range test, it took 1.5x as long.)"""
    lo, hi = (ZERO, np.int64(split)) if part == 0 else (np.int64(split), np.int64(out.shape[0]))
    for v in range(lo, hi):
        for m in range(N_MOMENTS):
            out[v, m] = 0.0
    ox, oy, oz = origin[0], origin[1], origin[2]
    for i in range(ZERO if part == 0 else np.int64(half), points.shape[0]):
        v = point_voxel[i]
        if v < lo or v >= hi:
            continue
        x = points[i, 0] - ox
        y = points[i, 1] - oy
        z = points[i, 2] - oz
        out[v, 0] += 1.0
        out[v, 1] += x
        out[v, 2] += y
        out[v, 3] += z
        out[v, 4] += x * x
        out[v, 5] += x * y
        out[v, 6] += x * z
        out[v, 7] += y * y
        out[v, 8] += y * z
        out[v, 9] += z * z
        out[v, 10] += colors[i, 0]
        out[v, 11] += colors[i, 1]
        out[v, 12] += colors[i, 2]


@numba.njit(cache=True, parallel=True)
def _moments_parallel(
    points: np.ndarray,
    colors: np.ndarray,
    point_voxel: np.ndarray,
    split: int,
    half: int,
    origin: np.ndarray,
    out: np.ndarray,
) -> None:
    for part in numba.prange(2):  # nothing else here: array code would spawn parfors
        _moments_of_voxels(np.int64(part), points, colors, point_voxel, split, half, origin, out)


@numba.njit(cache=True)
def voxel_moments_split(
    points: np.ndarray,
    colors: np.ndarray,
    point_voxel: np.ndarray,
    n_voxels: int,
    origin: np.ndarray,
    split: int,
) -> np.ndarray:
    """`voxel_moments` on two threads, the same bits, when the voxels from `split` on hold
    points of the second half (from n // 2) only, as `voxelize_halves` numbers them: each
    voxel's points are summed in input order by one thread."""
    out = np.empty((n_voxels, N_MOMENTS))
    _moments_parallel(points, colors, point_voxel, split, points.shape[0] // 2, origin, out)
    return out


@numba.njit(cache=True)
def _neighbourhood_range(
    lo: int,
    hi: int,
    voxel_block: np.ndarray,
    voxel_slot: np.ndarray,
    slot_voxel: np.ndarray,
    block_nbrs: np.ndarray,
    moments: np.ndarray,
    neighbours: np.ndarray,
    first: np.ndarray,
    n_neighbours: np.ndarray,
    sums: np.ndarray,
) -> None:
    codes, slots = neighbour_tables()
    # The occupied neighbours first, in offset order (no branch on occupancy: every entry is
    # written, the count moves if it is occupied), then, in a second loop (quicker than one
    # loop doing both), the sum of their rows.
    # The lists lie one after the other from 27 * lo (this range's share of `neighbours`), so
    # the memory written is the occupied neighbours' only (about half of 27 per voxel).
    at = 27 * lo
    for v in range(lo, hi):
        b, s = voxel_block[v], voxel_slot[v]
        first[v] = at
        for k in range(27):
            nb = block_nbrs[b, codes[s, k]]
            u = -1 if nb < 0 else slot_voxel[nb * SLOTS + slots[s, k]]
            neighbours[at] = u
            at += u >= 0
        n_neighbours[v] = at - first[v]
    for v in range(lo, hi):
        # 13 scalar accumulators stay in registers (an array would go through memory)
        a0 = a1 = a2 = a3 = a4 = a5 = a6 = a7 = a8 = a9 = a10 = a11 = a12 = 0.0
        f = first[v]
        for q in range(f, f + n_neighbours[v]):
            m = moments[neighbours[q]]
            a0, a1, a2, a3 = a0 + m[0], a1 + m[1], a2 + m[2], a3 + m[3]
            a4, a5, a6, a7 = a4 + m[4], a5 + m[5], a6 + m[6], a7 + m[7]
            a8, a9, a10, a11, a12 = a8 + m[8], a9 + m[9], a10 + m[10], a11 + m[11], a12 + m[12]
        o = sums[v]
        o[0], o[1], o[2], o[3], o[4], o[5], o[6] = a0, a1, a2, a3, a4, a5, a6
        o[7], o[8], o[9], o[10], o[11], o[12] = a7, a8, a9, a10, a11, a12


@numba.njit(cache=True, parallel=True)
def _neighbourhood_parallel(
    n_chunks: int,
    voxel_block: np.ndarray,
    voxel_slot: np.ndarray,
    slot_voxel: np.ndarray,
    block_nbrs: np.ndarray,
    moments: np.ndarray,
    neighbours: np.ndarray,
    first: np.ndarray,
    n_neighbours: np.ndarray,
    sums: np.ndarray,
) -> None:
    v_count = moments.shape[0]
    for c in numba.prange(n_chunks):  # nothing else here: array code would spawn parfors
        _neighbourhood_range(
            c * v_count // n_chunks, (c + 1) * v_count // n_chunks, voxel_block, voxel_slot,
            slot_voxel, block_nbrs, moments, neighbours, first, n_neighbours, sums,
        )  # fmt: skip


@numba.njit(cache=True)
def neighbourhood_moments(
    voxel_block: np.ndarray,
    voxel_slot: np.ndarray,
    slot_voxel: np.ndarray,
    block_nbrs: np.ndarray,
    moments: np.ndarray,
    n_chunks: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Each voxel's occupied 27-neighbours and the sum of their moment rows.

    `n_chunks` > 1 splits the voxels over the thread team; 1 runs on this thread alone.

    Returns:
        (neighbours [27 V] int32: voxel v's occupied neighbours in offset order in
         neighbours[first[v] : first[v] + n[v]], the rest unspecified; first [V] int64;
         n [V] int32; sums [V, 13]).
    """
    v_count = moments.shape[0]
    neighbours = np.empty(27 * v_count, dtype=np.int32)
    first = np.empty(v_count, dtype=np.int64)
    n_neighbours = np.empty(v_count, dtype=np.int32)
    sums = np.empty((v_count, N_MOMENTS))
    if n_chunks == 1:
        _neighbourhood_range(
            ZERO, v_count, voxel_block, voxel_slot, slot_voxel, block_nbrs, moments,
            neighbours, first, n_neighbours, sums,
        )  # fmt: skip
    else:
        _neighbourhood_parallel(
            n_chunks, voxel_block, voxel_slot, slot_voxel, block_nbrs, moments, neighbours,
            first, n_neighbours, sums,
        )  # fmt: skip
    return neighbours, first, n_neighbours, sums


@numba.njit(cache=True)
def _min_eigenvalue_trig(a: float, b: float, c: float, d: float, e: float, f: float) -> float:
    """Smallest eigenvalue of [[a, b, c], [b, d, e], [c, e, f]] by the trigonometric formula."""
    p1 = b * b + c * c + e * e
    if p1 == 0.0:
        return min(a, min(d, f))
    q = (a + d + f) / 3.0
    p2 = (a - q) ** 2 + (d - q) ** 2 + (f - q) ** 2 + 2.0 * p1
    p = math.sqrt(p2 / 6.0)
    b00, b11, b22 = (a - q) / p, (d - q) / p, (f - q) / p
    b01, b02, b12 = b / p, c / p, e / p
    det = (
        b00 * (b11 * b22 - b12 * b12)
        - b01 * (b01 * b22 - b12 * b02)
        + b02 * (b01 * b12 - b11 * b02)
    )
    r = min(1.0, max(-1.0, det / 2.0))
    phi = math.acos(r) / 3.0
    return q + 2.0 * p * math.cos(phi + 2.0 * math.pi / 3.0)


@numba.njit(cache=True)
def min_eigenvalue(a: float, b: float, c: float, d: float, e: float, f: float) -> float:
    """Smallest eigenvalue of the symmetric positive [[a, b, c], [b, d, e], [c, e, f]].

    Newton on the characteristic cubic from 0 climbs monotonically to the smallest root
    (the cubic is concave and increasing there); it converges in a few steps when that
    root stands apart, as on surfaces. Otherwise the trigonometric formula is used.
    """
    tr = a + d + f
    c2 = a * d - b * b + a * f - c * c + d * f - e * e
    det = a * (d * f - e * e) - b * (b * f - e * c) + c * (b * e - d * c)
    lam = 0.0
    for _ in range(NEWTON_STEPS):
        slope = (3.0 * lam - 2.0 * tr) * lam + c2
        if slope <= 0.0:
            break
        step = (((lam - tr) * lam + c2) * lam - det) / slope
        lam -= step
        if -step <= 1e-14 * tr:
            return lam
    return _min_eigenvalue_trig(a, b, c, d, e, f)


@numba.njit(cache=True, error_model="numpy")
def curvatures_into(covs: np.ndarray, lo: int, hi: int, kappa: np.ndarray) -> None:
    """kappa[i] = max(lambda_min, 0) / trace of covariance rows covs[i] (xx xy xz yy yz zz),
    for lo <= i < hi, with the bits of `min_eigenvalue`.

    Newton runs on LANES Gaussians in lockstep, each lane frozen once it converges or stops
    (no branch, so the lanes overlap instead of waiting on one another's divisions); the lanes
    that did not converge take the trigonometric formula after NEWTON_STEPS.
    """
    tr = np.empty(LANES)
    c2 = np.empty(LANES)
    det = np.empty(LANES)
    lam = np.empty(LANES)
    live = np.empty(LANES, dtype=np.bool_)
    done = np.empty(LANES, dtype=np.bool_)
    for i0 in range(lo, hi, LANES):
        m = min(LANES, hi - i0)
        for q in range(m):
            a, b, c = covs[i0 + q, 0], covs[i0 + q, 1], covs[i0 + q, 2]
            d, e, f = covs[i0 + q, 3], covs[i0 + q, 4], covs[i0 + q, 5]
            tr[q] = a + d + f
            c2[q] = a * d - b * b + a * f - c * c + d * f - e * e
            det[q] = a * (d * f - e * e) - b * (b * f - e * c) + c * (b * e - d * c)
            lam[q] = 0.0
            live[q] = True
            done[q] = False
        for _ in range(NEWTON_STEPS):
            for q in range(m):
                x = lam[q]
                slope = (3.0 * x - 2.0 * tr[q]) * x + c2[q]
                step = (((x - tr[q]) * x + c2[q]) * x - det[q]) / slope
                go = live[q] & (slope > 0.0)  # a NaN slope ends in the formula either way
                lam[q] = x - step if go else x
                converged = go & (-step <= 1e-14 * tr[q])
                done[q] |= converged
                live[q] = go & (not converged)
        for q in range(m):
            x = lam[q]
            if not done[q]:
                c = covs[i0 + q]
                x = _min_eigenvalue_trig(c[0], c[1], c[2], c[3], c[4], c[5])
            kappa[i0 + q] = max(x, 0.0) / tr[q]


@numba.njit(cache=True)
def curvatures(covs: np.ndarray) -> np.ndarray:
    """[G] kappa = lambda_min / trace of covariance rows [G, 6] (xx xy xz yy yz zz)."""
    out = np.empty(covs.shape[0])
    curvatures_into(covs, ZERO, covs.shape[0], out)
    return out


@numba.njit(cache=True)
def _candidates_range(
    lo: int,
    hi: int,
    sums: np.ndarray,
    rows: np.ndarray,
    epsilon: float,
    means: np.ndarray,
    covs: np.ndarray,
    colors: np.ndarray,
    kappa: np.ndarray,
) -> None:
    for i in range(lo, hi):
        s = sums[rows[i]]
        n = s[0]
        mx, my, mz = s[1] / n, s[2] / n, s[3] / n
        cxx = s[4] / n - mx * mx + epsilon
        cxy = s[5] / n - mx * my
        cxz = s[6] / n - mx * mz
        cyy = s[7] / n - my * my + epsilon
        cyz = s[8] / n - my * mz
        czz = s[9] / n - mz * mz + epsilon
        means[i, 0], means[i, 1], means[i, 2] = mx, my, mz
        covs[i, 0], covs[i, 1], covs[i, 2] = cxx, cxy, cxz
        covs[i, 3], covs[i, 4], covs[i, 5] = cyy, cyz, czz
        colors[i, 0], colors[i, 1], colors[i, 2] = s[10] / n, s[11] / n, s[12] / n
    curvatures_into(covs, lo, hi, kappa)


@numba.njit(cache=True, parallel=True)
def _candidates_parallel(
    n_chunks: int,
    sums: np.ndarray,
    rows: np.ndarray,
    epsilon: float,
    means: np.ndarray,
    covs: np.ndarray,
    colors: np.ndarray,
    kappa: np.ndarray,
) -> None:
    g = rows.shape[0]
    for c in numba.prange(n_chunks):
        _candidates_range(
            c * g // n_chunks, (c + 1) * g // n_chunks, sums, rows, epsilon, means, covs,
            colors, kappa,
        )  # fmt: skip


@numba.njit(cache=True)
def candidate_gaussians(
    sums: np.ndarray, rows: np.ndarray, epsilon: float, n_chunks: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Float64 Gaussians of the moment rows sums[rows].

    Returns:
        (means [G, 3] relative to the moments' origin, covariances [G, 6] as
         (xx, xy, xz, yy, yz, zz) with +eps, colours [G, 3], curvature kappa [G]).
    """
    g = rows.shape[0]
    means = np.empty((g, 3))
    covs = np.empty((g, 6))
    colors = np.empty((g, 3))
    kappa = np.empty(g)
    if n_chunks == 1:
        _candidates_range(ZERO, g, sums, rows, epsilon, means, covs, colors, kappa)
    else:
        _candidates_parallel(n_chunks, sums, rows, epsilon, means, covs, colors, kappa)
    return means, covs, colors, kappa


@numba.njit(cache=True)
def output_gaussians(
    sums: np.ndarray, rows: np.ndarray, epsilon: float, origin: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Float32 Gaussians of the moment rows sums[rows].

    Returns:
        (means [G, 3] in the world, covariances [G, 3, 3] with +eps, colours [G, 3],
         uint32 counts [G]).
    """
    g = rows.shape[0]
    means = np.empty((g, 3), dtype=np.float32)
    covs = np.empty((g, 3, 3), dtype=np.float32)
    colors = np.empty((g, 3), dtype=np.float32)
    counts = np.empty(g, dtype=np.uint32)
    for i in range(g):
        s = sums[rows[i]]
        n = s[0]
        mx, my, mz = s[1] / n, s[2] / n, s[3] / n
        cov = (
            s[4] / n - mx * mx + epsilon,
            s[5] / n - mx * my,
            s[6] / n - mx * mz,
            s[7] / n - my * my + epsilon,
            s[8] / n - my * mz,
            s[9] / n - mz * mz + epsilon,
        )
        means[i, 0], means[i, 1], means[i, 2] = mx + origin[0], my + origin[1], mz + origin[2]
        covs[i, 0, 0], covs[i, 0, 1], covs[i, 0, 2] = cov[0], cov[1], cov[2]
        covs[i, 1, 0], covs[i, 1, 1], covs[i, 1, 2] = cov[1], cov[3], cov[4]
        covs[i, 2, 0], covs[i, 2, 1], covs[i, 2, 2] = cov[2], cov[4], cov[5]
        for c in range(3):
            colors[i, c] = min(1.0, max(0.0, s[10 + c] / n))
        counts[i] = np.uint32(n)
    return means, covs, colors, counts
