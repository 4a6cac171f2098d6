"""Ordered, size-capped union-find over additive moments (used by `merge.remerge`).

Pairs arrive sorted by increasing D. A union of two clusters is refused when the Gaussian of
their combined points would have trace(Sigma) > cap; each cluster's moments are the sums of
its members' rows (n, first moment, trace of the second moment), exact for Gaussians fitted
from distinct points. The root of a cluster is its smallest member index.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def find_root(parent: np.ndarray, i: int) -> int:
    """Root of i with path halving."""
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i


@numba.njit(cache=True)
def _union_additive(
    moments: np.ndarray, pairs: np.ndarray, cap_trace: float, epsilon: float
) -> np.ndarray:
    n = moments.shape[0]
    parent = np.arange(n)
    acc = moments.copy()
    for k in range(pairs.shape[0]):
        ri = find_root(parent, pairs[k, 0])
        rj = find_root(parent, pairs[k, 1])
        if ri == rj:
            continue
        # The row of the union, as scalars (a row array would be a view per pair).
        w = acc[ri, 0] + acc[rj, 0]
        sx = acc[ri, 1] + acc[rj, 1]
        sy = acc[ri, 2] + acc[rj, 2]
        sz = acc[ri, 3] + acc[rj, 3]
        q = acc[ri, 4] + acc[rj, 4]
        mx, my, mz = sx / w, sy / w, sz / w
        if q / w - (mx * mx + my * my + mz * mz) + 3.0 * epsilon > cap_trace:
            continue
        root, other = (ri, rj) if ri < rj else (rj, ri)
        parent[other] = root
        acc[root, 0], acc[root, 1], acc[root, 2], acc[root, 3], acc[root, 4] = w, sx, sy, sz, q
    labels = np.empty(n, dtype=np.int64)
    for i in range(n):
        labels[i] = find_root(parent, i)
    return labels


def union_additive(
    moments: np.ndarray, pairs: np.ndarray, cap_trace: float, epsilon: float
) -> np.ndarray:
    """Cluster labels (smallest member) of the ordered, capped union of `pairs`.

    Args:
        moments: [N, 5] float64 additive rows (n, s_x, s_y, s_z, q), see
            `merge.additive_moments`.
        pairs: [K, 2] int64, in the order to try them.
        cap_trace: largest trace(Sigma) (m^2) a union may produce; inf = no cap.
        epsilon: the eps*I regulariser counted once in each trace.

    Returns:
        [N] int64 labels.
    """
    pairs = np.ascontiguousarray(pairs, dtype=np.int64).reshape(-1, 2)
    moments = np.ascontiguousarray(moments, dtype=np.float64).reshape(-1, 5)
    if len(moments) == 0:
        return np.zeros(0, dtype=np.int64)
    return _union_additive(moments, pairs, float(cap_trace), float(epsilon))


def union_additive_reference(
    moments: np.ndarray, pairs: np.ndarray, cap_trace: float, epsilon: float
) -> np.ndarray:
    """Plain-Python twin of `union_additive` (dict of member sets), for tests."""
    members = {i: {i} for i in range(len(moments))}
    owner = list(range(len(moments)))
    for i, j in pairs.tolist():
        ri, rj = owner[i], owner[j]
        if ri == rj:
            continue
        union = members[ri] | members[rj]
        row = moments[sorted(union)].sum(axis=0)
        n = row[0]
        mean = row[1:4] / n
        trace = row[4] / n - float(mean @ mean) + 3.0 * epsilon
        if trace > cap_trace:
            continue
        root = min(ri, rj)
        for m in union:
            owner[m] = root
        members.pop(max(ri, rj))
        members[root] = union
    return np.asarray(owner, dtype=np.int64)
