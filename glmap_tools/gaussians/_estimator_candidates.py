"""Candidate Gaussians of a fit, written straight into the sweep's key order (numba).

The fit's merge needs the candidates only as the sweep's inputs, so they are computed in
the order of their mean cells' keys, in the sweep's layout, instead of being computed in
Gaussian order and copied into key order afterwards. The arithmetic is that of
`_estimator_numba.candidate_gaussians` (the same bits). `pack_in_key_order` puts Gaussians
already computed (those `remerge` works on) into the same layout.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from glmap_tools.gaussians._estimator_numba import curvatures_into
from glmap_tools.gaussians._estimator_voxels import CELL_MARGIN
from glmap_tools.gaussians._int64 import ZERO


@numba.njit(cache=True)
def candidate_cells(sums: np.ndarray, rows: np.ndarray, radius: float) -> np.ndarray:
    """[G, 3] int64 cells of side `radius` of the means of the moment rows sums[rows]
    (those of `_estimator_clusters.mean_cells` on the candidates' means)."""
    g = rows.shape[0]
    cells = np.empty((g, 3), dtype=np.int64)
    for i in range(g):
        r = rows[i]
        n = sums[r, 0]
        for a in range(3):
            cells[i, a] = np.int64(math.floor((sums[r, 1 + a] / n) / radius)) + CELL_MARGIN
    return cells


@numba.njit(cache=True)
def pack_in_key_order(
    order: np.ndarray, means: np.ndarray, covs: np.ndarray, colors: np.ndarray, kappa: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The means [3, G] (x, y and z rows) and the rest of D's inputs [G, 11] (covariance row,
    colour, kappa, index), in key order, so the sweep reads memory in order."""
    g = order.shape[0]
    near = np.empty((3, g))
    rest = np.empty((g, 11))
    for s in range(g):
        o = order[s]
        for a in range(3):
            near[a, s] = means[o, a]
            rest[s, 6 + a] = colors[o, a]
        for a in range(6):
            rest[s, a] = covs[o, a]
        rest[s, 9] = kappa[o]
        rest[s, 10] = o
    return near, rest


@numba.njit(cache=True)
def _packed_range(
    lo: int,
    hi: int,
    sums: np.ndarray,
    rows: np.ndarray,
    order: np.ndarray,
    epsilon: float,
    near: np.ndarray,
    rest: np.ndarray,
    kappa: np.ndarray,
) -> None:
    for p in range(lo, hi):
        i = order[p]
        s = sums[rows[i]]
        n = s[0]
        mx, my, mz = s[1] / n, s[2] / n, s[3] / n
        near[0, p], near[1, p], near[2, p] = mx, my, mz
        rest[p, 0] = s[4] / n - mx * mx + epsilon
        rest[p, 1] = s[5] / n - mx * my
        rest[p, 2] = s[6] / n - mx * mz
        rest[p, 3] = s[7] / n - my * my + epsilon
        rest[p, 4] = s[8] / n - my * mz
        rest[p, 5] = s[9] / n - mz * mz + epsilon
        rest[p, 6], rest[p, 7], rest[p, 8] = s[10] / n, s[11] / n, s[12] / n
        rest[p, 10] = i
    curvatures_into(rest, lo, hi, kappa)  # reads the covariance rows, columns 0..5
    for p in range(lo, hi):
        rest[p, 9] = kappa[p]


@numba.njit(cache=True, parallel=True)
def _packed_parallel(
    n_chunks: int,
    sums: np.ndarray,
    rows: np.ndarray,
    order: np.ndarray,
    epsilon: float,
    near: np.ndarray,
    rest: np.ndarray,
    kappa: np.ndarray,
) -> None:
    g = rows.shape[0]
    for c in numba.prange(n_chunks):  # nothing else here: array code would spawn parfors
        _packed_range(
            c * g // n_chunks, (c + 1) * g // n_chunks, sums, rows, order, epsilon, near, rest,
            kappa,
        )  # fmt: skip


@numba.njit(cache=True)
def packed_candidates(
    sums: np.ndarray, rows: np.ndarray, order: np.ndarray, epsilon: float, n_chunks: int
) -> tuple[np.ndarray, np.ndarray]:
    """The candidate Gaussians of the moment rows sums[rows] in the sweep's layout.

    Args:
        sums: [V, 13] moment rows.
        rows: [G] the row of each Gaussian.
        order: [G] the Gaussians in key order.
        epsilon: added to the covariances' diagonal.
        n_chunks: > 1 splits the work over the thread team.

    Returns:
        (means [3, G] (x, y, z rows), rest [G, 11] (covariance row xx xy xz yy yz zz with
         eps, colour, kappa, Gaussian index)), both in key order: `pack_in_key_order` of
         `candidate_gaussians`.
    """
    g = rows.shape[0]
    near = np.empty((3, g))
    rest = np.empty((g, 11))
    kappa = np.empty(g)
    if n_chunks == 1:
        _packed_range(ZERO, g, sums, rows, order, epsilon, near, rest, kappa)
    else:
        _packed_parallel(n_chunks, sums, rows, order, epsilon, near, rest, kappa)
    return near, rest
