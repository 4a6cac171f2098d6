"""Curvature-aware Gaussian merging (paper Eq. merge) and exact moment combination.

D(Gi, Gj) = ||mu_i - mu_j|| + lambda_cov ||Sigma_i - Sigma_j||_F + lambda_color ||c_i - c_j||;
Gi and Gj merge when their means lie within one voxel and
D < 2 * voxel * (1 + tau * (kappa_i + kappa_j)), kappa = lambda_min(Sigma) / tr(Sigma).
Merged Gaussians are combined exactly from point counts and second moments, so the result
is the fit of the union (as a multiset) of the points behind them.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial import cKDTree

from glmap_tools.errors import InvalidInputError
from glmap_tools.gaussians.types import COVARIANCE_EPSILON, GaussianSet

if TYPE_CHECKING:
    from glmap_tools.gaussians.config import EstimatorConfig

# Imports inside functions stay there: gaussians, numba load on first use.

ANY_MERGEABLE_CHUNK = 4096  # Gaussians per early-exit step of `any_mergeable`
ANY_MERGEABLE_FIRST = 32  # pairs whose curvature `any_mergeable` computes first (then 4x more)
ANY_MERGEABLE_PROBE = 256  # pairs whose D `any_mergeable` computes first (then 4x more)
MAX_GRID_SPAN = 1 << 22  # candidate radii across a set that the numba grid search can key


def curvature(covs: np.ndarray) -> np.ndarray:
    """kappa = lambda_min(Sigma) / tr(Sigma), the paper's curvature proxy.

    Args:
        covs: [N, 3, 3] covariances (with their +eps*I).

    Returns:
        [N] float64 in [0, 1/3]: ~0 on a plane, 1/3 for an isotropic blob.
    """
    covs = np.asarray(covs, dtype=np.float64).reshape(-1, 3, 3)
    if len(covs) == 0:
        return np.zeros(0)
    lam_min = np.linalg.eigvalsh(covs)[:, 0]
    trace = covs[:, 0, 0] + covs[:, 1, 1] + covs[:, 2, 2]
    return np.maximum(lam_min, 0.0) / trace


def merge_threshold(
    kappa_i: np.ndarray, kappa_j: np.ndarray, config: EstimatorConfig
) -> np.ndarray:
    """The merge threshold 2 * voxel * (1 + tau * (kappa_i + kappa_j)), metres.

    Args:
        kappa_i: [K] curvature of the first Gaussian of each pair.
        kappa_j: [K] curvature of the second.
        config: supplies voxel_size and tau.
    """
    ki = np.asarray(kappa_i, dtype=np.float64)
    kj = np.asarray(kappa_j, dtype=np.float64)
    return 2.0 * config.voxel_size * (1.0 + config.tau * (ki + kj))


def pair_distance(
    mu_i: np.ndarray,
    cov_i: np.ndarray,
    c_i: np.ndarray,
    mu_j: np.ndarray,
    cov_j: np.ndarray,
    c_j: np.ndarray,
    config: EstimatorConfig,
) -> np.ndarray:
    """D on raw float64 arrays ([K, 3], [K, 3, 3], [K, 3] each side) -> [K].

    The sums are written out term by term, in the order the numba kernel uses.
    """
    dm = mu_i - mu_j
    ds = cov_i - cov_j
    dc = c_i - c_j
    d_mu = np.sqrt(dm[:, 0] ** 2 + dm[:, 1] ** 2 + dm[:, 2] ** 2)
    diag = ds[:, 0, 0] ** 2 + ds[:, 1, 1] ** 2 + ds[:, 2, 2] ** 2
    off = ds[:, 0, 1] ** 2 + ds[:, 0, 2] ** 2 + ds[:, 1, 2] ** 2
    d_cov = np.sqrt(diag + 2.0 * off)
    d_col = np.sqrt(dc[:, 0] ** 2 + dc[:, 1] ** 2 + dc[:, 2] ** 2)
    return d_mu + config.lambda_cov * d_cov + config.lambda_color * d_col


def gaussian_distance(
    a: GaussianSet, ia: np.ndarray, b: GaussianSet, ib: np.ndarray, config: EstimatorConfig
) -> np.ndarray:
    """D(a[ia[k]], b[ib[k]]) for each pair k, metres.

    Args:
        a, b: Gaussian sets (may be the same set).
        ia, ib: [K] integer indices into a and b.
        config: supplies lambda_cov and lambda_color.

    Returns:
        [K] float64 distances.
    """
    ia = np.asarray(ia, dtype=np.int64)
    ib = np.asarray(ib, dtype=np.int64)
    f = np.float64
    return pair_distance(
        a.means[ia].astype(f),
        a.covs[ia].astype(f),
        a.colors[ia].astype(f),
        b.means[ib].astype(f),
        b.covs[ib].astype(f),
        b.colors[ib].astype(f),
        config,
    )


def _filter_mergeable(
    a: GaussianSet,
    ia: np.ndarray,
    b: GaussianSet,
    ib: np.ndarray,
    config: EstimatorConfig,
    kappa_a: np.ndarray | None = None,
    kappa_b: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """(keep [K] bool, D [K]) for candidate pairs: D < merge threshold."""
    if len(ia) == 0:
        return np.zeros(0, dtype=bool), np.zeros(0)
    d = gaussian_distance(a, ia, b, ib, config)
    ka = (curvature(a.covs) if kappa_a is None else kappa_a)[ia]
    kb = (curvature(b.covs) if kappa_b is None else kappa_b)[ib]
    return d < merge_threshold(ka, kb, config), d


def _candidates_between(a: GaussianSet, b: GaussianSet, radius: float) -> np.ndarray:
    """[K, 2] (ia, ib) with ||mu_a - mu_b|| <= radius, sorted."""
    if len(a) == 0 or len(b) == 0:
        return np.zeros((0, 2), dtype=np.int64)
    ia, ib = _pairs_within(a.means.astype(np.float64), b.means.astype(np.float64), radius)
    pairs = np.stack([ia, ib], axis=1).reshape(-1, 2)
    return pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]


def check_finite_means(g: GaussianSet) -> None:
    """Refuse a set with a NaN or infinite mean (the pair searches need coordinates).

    Raises:
        InvalidInputError: naming the first such Gaussian and the fix.
    """
    finite = np.isfinite(g.means).all(axis=1)
    if not finite.all():
        k = int(np.argmin(finite))
        raise InvalidInputError(
            f"GaussianSet.means[{k}] = {g.means[k].tolist()} is not finite "
            f"({int((~finite).sum())} such Gaussians); drop them first, e.g. "
            "g.subset(np.isfinite(g.means).all(axis=1))."
        )


def candidate_pairs_within(g: GaussianSet, radius: float) -> np.ndarray:
    """[K, 2] (i, j), i < j, with ||mu_i - mu_j|| <= radius, sorted."""
    check_finite_means(g)
    if len(g) < 2:
        return np.zeros((0, 2), dtype=np.int64)
    pairs = cKDTree(g.means.astype(np.float64)).query_pairs(radius, output_type="ndarray")
    pairs = np.sort(pairs.astype(np.int64).reshape(-1, 2), axis=1)
    return pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]


def mergeable_pairs(a: GaussianSet, b: GaussianSet, config: EstimatorConfig) -> np.ndarray:
    """All (ia, ib) whose Gaussians would merge: means within one voxel and D < threshold.

    Args:
        a, b: Gaussian sets.
        config: estimator settings (voxel_size, tau, lambda_cov, lambda_color).

    Returns:
        [K, 2] int64 index pairs into (a, b), sorted lexicographically.
    """
    check_finite_means(a)
    check_finite_means(b)
    pairs = _candidates_between(a, b, config.candidate_radius)
    keep, _ = _filter_mergeable(a, pairs[:, 0], b, pairs[:, 1], config)
    return pairs[keep]


def any_mergeable(a: GaussianSet, b: GaussianSet, config: EstimatorConfig) -> bool:
    """Whether at least one Gaussian of `a` would merge with one of `b` (early exit).

    Used to match a newly observed instance against the map's instances.
    """
    check_finite_means(a)
    check_finite_means(b)
    if len(a) == 0 or len(b) == 0:
        return False
    r = config.candidate_radius
    a_lo, a_hi = a.means.min(axis=0) - r, a.means.max(axis=0) + r
    b_lo, b_hi = b.means.min(axis=0) - r, b.means.max(axis=0) + r
    a = a.subset(np.all((a.means >= b_lo) & (a.means <= b_hi), axis=1))
    b = b.subset(np.all((b.means >= a_lo) & (b.means <= a_hi), axis=1))
    if len(a) == 0 or len(b) == 0:
        return False
    if len(a) < len(b):
        a, b = b, a
    a_means = a.means.astype(np.float64)
    for start in range(0, len(b), ANY_MERGEABLE_CHUNK):
        chunk = b.subset(np.arange(start, min(start + ANY_MERGEABLE_CHUNK, len(b))))
        ia, ib = _pairs_within(a_means, chunk.means.astype(np.float64), r)
        if len(ia) and _some_pair_merges(a, ia, chunk, ib, config):
            return True
    return False


def _pairs_within(a: np.ndarray, b: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """([K] ia, [K] ib): every pair of float64 points with ||a[ia] - b[ib]|| <= radius, by the
    numba grid (`_pairs_numba`), or by cKDTree when the grid would be too large."""
    from glmap_tools.gaussians._pairs_numba import pairs_within

    done, ia, ib = pairs_within(a, b, radius)
    if done:
        return ia, ib
    found = cKDTree(a).sparse_distance_matrix(cKDTree(b), radius, output_type="ndarray")
    return found["i"].astype(np.int64), found["j"].astype(np.int64)


def _some_pair_merges(
    a: GaussianSet, ia: np.ndarray, b: GaussianSet, ib: np.ndarray, config: EstimatorConfig
) -> bool:
    """Whether any pair (a[ia[k]], b[ib[k]]) has D < its merge threshold.

    The pairs are tested in slices (ANY_MERGEABLE_PROBE of them, then 4x more each time),
    each as `_slice_merges` tests it, until one merges. The answer is that of
    `_filter_mergeable(...)[0].any()`: the same D and kappa per pair (eigvalsh gives the
    same bits for a matrix in any batch), only fewer of them.
    """
    lo, size = 0, ANY_MERGEABLE_PROBE
    while lo < len(ia):
        if _slice_merges(a, ia[lo : lo + size], b, ib[lo : lo + size], config):
            return True
        lo, size = lo + size, 4 * size
    return False


def _slice_merges(
    a: GaussianSet, ia: np.ndarray, b: GaussianSet, ib: np.ndarray, config: EstimatorConfig
) -> bool:
    """`_some_pair_merges` of one slice of pairs: D for every pair, then the curvatures (an
    eigvalsh per Gaussian, the cost) in increasing D, in batches, until one pair merges.
    With tau <= 0 the threshold is at most 2 * voxel, so pairs with D >= 2 * voxel are
    dropped before any curvature."""
    d = gaussian_distance(a, ia, b, ib, config)
    bound = 2.0 * config.voxel_size if config.tau <= 0 else np.inf
    near = np.flatnonzero(d < bound)
    order = near[np.argsort(d[near], kind="stable")]
    lo, size = 0, ANY_MERGEABLE_FIRST
    while lo < len(order):
        pick = order[lo : lo + size]
        ka, kb = curvature(a.covs[ia[pick]]), curvature(b.covs[ib[pick]])
        if np.any(d[pick] < merge_threshold(ka, kb, config)):
            return True
        lo, size = lo + size, 4 * size
    return False


def combine(g: GaussianSet, groups: np.ndarray, epsilon: float = COVARIANCE_EPSILON) -> GaussianSet:
    """Combine the Gaussians sharing a group label, exactly, from counts and moments.

    With n = sum n_k: mu = sum n_k mu_k / n and
    Sigma = sum n_k ((Sigma_k - eps I) + (mu_k - mu)(mu_k - mu)^T) / n + eps I
    (the parallel / Chan formula, float64 inside), colour and opacity count-weighted: the
    fit of the union (as a multiset) of the points behind the members.

    Args:
        g: N Gaussians with counts >= 1.
        groups: [N] integer group labels.
        epsilon: the eps*I each covariance carries (removed before, added once after).

    Returns:
        One Gaussian per distinct label, in increasing label order.

    Raises:
        InvalidInputError: a label array of the wrong shape, or a zero count.
    """
    groups = np.asarray(groups)
    if groups.shape != (len(g),) or (len(g) and groups.dtype.kind not in "iu"):
        raise InvalidInputError(
            f"groups has shape {groups.shape} and dtype {groups.dtype}; pass [{len(g)}] "
            "integer labels, one per Gaussian."
        )
    if len(g) == 0:
        return GaussianSet.empty()
    labels, inverse = np.unique(groups, return_inverse=True)
    return _combine_groups(g, inverse.reshape(-1), len(labels), epsilon)


def _combine_groups(
    g: GaussianSet, inverse: np.ndarray, n_groups: int, epsilon: float
) -> GaussianSet:
    """`combine` of N > 0 Gaussians into groups 0..n_groups - 1 (`inverse` [N]: each one's)."""
    if np.any(g.counts == 0):
        k = int(np.argmax(g.counts == 0))
        raise InvalidInputError(
            f"Gaussian {k} has count 0, so it cannot be weighted; set counts to the number "
            "of points behind each Gaussian (1 when unknown)."
        )
    from glmap_tools.gaussians._combine_numba import MAX_MEMBERS, combine_groups

    order = np.argsort(inverse, kind="stable")
    starts = np.searchsorted(inverse[order], np.arange(n_groups))
    n = np.add.reduceat(g.counts.astype(np.float64)[order], starts)
    if n.max() > np.iinfo(np.uint32).max:
        raise InvalidInputError(
            f"a combined Gaussian would hold {int(n.max())} points, more than uint32 counts "
            "can store; combine fewer Gaussians at once."
        )
    bounds = np.append(starts, len(order))
    if np.diff(bounds).max() > MAX_MEMBERS:
        return _combine_by_numpy(g, inverse, order, starts, epsilon)
    out = GaussianSet.allocate(n_groups)  # the numba kernel: the same operations, in order
    combine_groups(order, bounds, g.arrays(), epsilon, out.arrays())
    return out


def _combine_by_numpy(
    g: GaussianSet, inverse: np.ndarray, order: np.ndarray, starts: np.ndarray, epsilon: float
) -> GaussianSet:
    """`combine`'s formula in numpy (group k: rows order[starts[k]:starts[k + 1]])."""
    w = g.counts.astype(np.float64)
    n = np.add.reduceat(w[order], starts)

    def weighted_mean(x: np.ndarray) -> np.ndarray:  # [N, ...] -> [M, ...]
        flat = x.reshape(len(x), -1).astype(np.float64)[order] * w[order, None]
        return (np.add.reduceat(flat, starts, axis=0) / n[:, None]).reshape((-1, *x.shape[1:]))

    mu = weighted_mean(g.means)
    dev = g.means.astype(np.float64) - mu[inverse]
    scatter = g.covs.astype(np.float64) - epsilon * np.eye(3) + dev[:, :, None] * dev[:, None, :]
    cov = weighted_mean(scatter) + epsilon * np.eye(3)
    return GaussianSet(
        mu,
        cov,
        np.clip(weighted_mean(g.colors), 0.0, 1.0),
        weighted_mean(g.opacities),
        n.astype(np.uint32),
    )


def remerge_groups(g: GaussianSet, config: EstimatorConfig) -> np.ndarray:
    """Group labels of the curvature-aware merge of an existing set (label = smallest member).

    Mergeable pairs (means within one voxel, D < threshold) are visited by increasing D
    (ties by index); a union is refused when the combined Gaussian would have
    trace(Sigma) > (remerge_sigma * voxel)^2.

    Returns:
        [N] int64 labels; equal labels merge.
    """
    from glmap_tools.gaussians._estimator_fast import gaussian_rows, sorted_mergeable_pairs
    from glmap_tools.gaussians._estimator_union import union_additive

    check_finite_means(g)
    if len(g) == 0:
        return np.zeros(0, dtype=np.int64)
    span = float((g.means.max(axis=0) - g.means.min(axis=0)).max()) / config.candidate_radius
    if span < MAX_GRID_SPAN:  # the numba grid search
        pairs = sorted_mergeable_pairs(*gaussian_rows(g), config)
    else:  # too wide for its 21-bit block keys: cKDTree, then sort by (D, i, j)
        pairs = candidate_pairs_within(g, config.candidate_radius)
        keep, d = _filter_mergeable(g, pairs[:, 0], g, pairs[:, 1], config)
        pairs, d = pairs[keep], d[keep]
        pairs = pairs[np.lexsort((pairs[:, 1], pairs[:, 0], d))]
    origin = g.means.astype(np.float64).mean(axis=0)
    return union_additive(
        additive_moments(g, origin, config.epsilon),
        pairs,
        config.remerge_cap_trace,
        config.epsilon,
    )


def additive_moments(g: GaussianSet, origin: np.ndarray, epsilon: float) -> np.ndarray:
    """[N, 5] float64 (n, n*mu - n*origin, n * (tr(Sigma - eps I) + |mu - origin|^2)).

    Sums of these rows give the count, first moment and trace of the second moment of a
    union, from which its trace(Sigma) follows.
    """
    n = g.counts.astype(np.float64)
    mu = g.means.astype(np.float64) - origin
    tr = np.trace(g.covs.astype(np.float64), axis1=1, axis2=2) - 3.0 * epsilon
    out = np.empty((len(g), 5))
    out[:, 0] = n
    out[:, 1:4] = n[:, None] * mu
    out[:, 4] = n * (tr + np.einsum("ij,ij->i", mu, mu))
    return out


def remerge(g: GaussianSet, config: EstimatorConfig) -> GaussianSet:
    """Curvature-aware merge of an existing set, e.g. two instances' Gaussians unioned.

    Returns `g` itself when `config.merge` is False or nothing merges.
    """
    if not config.merge or len(g) < 2:
        return g
    labels = remerge_groups(g, config)
    roots = labels == np.arange(len(g))  # a label is its group's smallest member
    if roots.all():
        return g
    # combine's np.unique, read off the roots: a label's rank among them
    return _combine_groups(g, np.cumsum(roots)[labels] - 1, int(roots.sum()), config.epsilon)
