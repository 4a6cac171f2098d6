"""The Gaussian Estimator written plainly (dict of voxels, Python loops): slow and obvious.

Every Gaussian is fitted directly from the points it stands for; tests hold the numba fast
path (`_estimator_fast`) equal to this.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from glmap_tools.gaussians.merge import curvature, merge_threshold, pair_distance
from glmap_tools.gaussians.types import GaussianSet

if TYPE_CHECKING:
    from glmap_tools.gaussians.config import EstimatorConfig

Key = tuple[int, int, int]
NEIGHBOUR_OFFSETS: list[Key] = [(a, b, c) for a, b, c in itertools.product((-1, 0, 1), repeat=3)]


def voxel_coords(points: np.ndarray, voxel_size: float) -> np.ndarray:
    """[N, 3] int64 voxel coordinates floor(p / voxel) of [N, 3] float64 points."""
    return np.floor(points / voxel_size).astype(np.int64)


def direct_fit(
    points: np.ndarray, colors: np.ndarray, epsilon: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(mean [3], covariance [3, 3] with 1/n and +eps*I, mean colour [3]) of a point set."""
    mean = points.mean(axis=0)
    d = points - mean
    cov = d.T @ d / len(points) + epsilon * np.eye(3)
    return mean, cov, colors.mean(axis=0)


@dataclass(frozen=True)
class ReferenceFit:
    """What the reference estimator found.

    Attributes:
        gaussians: the fitted (and merged) Gaussians.
        support: per Gaussian, the sorted int64 indices of the points it was fitted from.
        members: per Gaussian, the indices of the voxel Gaussians merged into it (into the
            unmerged fit with the same settings).
    """

    gaussians: GaussianSet
    support: list[np.ndarray]
    members: list[list[int]]


def fit_reference(points: np.ndarray, colors: np.ndarray, config: EstimatorConfig) -> ReferenceFit:
    """Fit and merge Gaussians, keeping each one's points and merged voxel Gaussians.

    Args:
        points: [N, 3] float64, validated.
        colors: [N, 3] float64 in [0, 1], validated.
        config: estimator settings.
    """
    cells: dict[Key, list[int]] = {}
    for i, key in enumerate(voxel_coords(points, config.voxel_size).tolist()):
        cells.setdefault(tuple(key), []).append(i)

    def points_of(keys: frozenset[Key]) -> np.ndarray:
        return np.sort(np.concatenate([np.asarray(cells[k], dtype=np.int64) for k in keys]))

    # One candidate Gaussian per occupied voxel, in the order voxels first appear.
    supports: list[frozenset[Key]] = []
    for key in cells:
        around = (tuple(a + b for a, b in zip(key, o, strict=True)) for o in NEIGHBOUR_OFFSETS)
        neighbourhood = frozenset(k for k in around if k in cells)
        if sum(len(cells[k]) for k in neighbourhood) >= config.min_points:
            supports.append(neighbourhood)
    if not supports:
        return ReferenceFit(GaussianSet.empty(), [], [])

    members = [[i] for i in range(len(supports))]
    if config.merge and len(supports) > 1:
        members = _merge(supports, points, colors, points_of, config)
        supports = [frozenset().union(*(supports[m] for m in group)) for group in members]

    fits = [
        direct_fit(points[idx], colors[idx], config.epsilon) for idx in map(points_of, supports)
    ]
    n = len(fits)
    gaussians = GaussianSet(
        np.array([f[0] for f in fits]),
        np.array([f[1] for f in fits]),
        np.array([f[2] for f in fits]),
        np.full(n, config.opacity),
        np.array([len(points_of(s)) for s in supports]),
    )
    return ReferenceFit(gaussians, [points_of(s) for s in supports], members)


def _merge(supports, points, colors, points_of, config):  # type: ignore[no-untyped-def]
    """Cluster the voxel Gaussians; return the clusters' members, by smallest member."""
    fits = [
        direct_fit(points[idx], colors[idx], config.epsilon) for idx in map(points_of, supports)
    ]
    means = np.array([f[0] for f in fits])
    covs = np.array([f[1] for f in fits])
    cols = np.array([f[2] for f in fits])
    kappa = curvature(covs)
    n = len(fits)

    pi_list, pj_list = [], []
    for i in range(n - 1):  # all pairs, brute force
        dm = means[i] - means[i + 1 :]
        near = np.sqrt(dm[:, 0] ** 2 + dm[:, 1] ** 2 + dm[:, 2] ** 2) <= config.candidate_radius
        js = i + 1 + np.flatnonzero(near)
        pi_list.append(np.full(len(js), i))
        pj_list.append(js)
    pi, pj = np.concatenate(pi_list), np.concatenate(pj_list)
    if len(pi) == 0:
        return [[i] for i in range(n)]
    d = pair_distance(means[pi], covs[pi], cols[pi], means[pj], covs[pj], cols[pj], config)
    ok = d < merge_threshold(kappa[pi], kappa[pj], config)
    ordered = sorted(zip(d[ok].tolist(), pi[ok].tolist(), pj[ok].tolist(), strict=True))

    counts = np.array([len(points_of(s)) for s in supports], dtype=np.float64)
    cap = config.merge_cap_trace
    owner = list(range(n))
    members: dict[int, list[int]] = {i: [i] for i in range(n)}
    for _, i, j in ordered:
        ri, rj = owner[i], owner[j]
        if ri == rj:
            continue
        union = members[ri] + members[rj]
        if _combined_trace(counts[union], means[union], covs[union], config.epsilon) > cap:
            continue
        root, other = min(ri, rj), max(ri, rj)
        for m in members[other]:
            owner[m] = root
        members[root] = union
        del members[other]
    return [sorted(members[r]) for r in sorted(members)]


def _combined_trace(n: np.ndarray, means: np.ndarray, covs: np.ndarray, epsilon: float) -> float:
    """trace(Sigma) of the count-weighted combination of Gaussians (Chan), +3 eps."""
    mean = (n[:, None] * means).sum(axis=0) / n.sum()
    spread = np.trace(covs, axis1=1, axis2=2) - 3 * epsilon + ((means - mean) ** 2).sum(axis=1)
    return float((n * spread).sum() / n.sum()) + 3 * epsilon
