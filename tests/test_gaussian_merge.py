"""Curvature-aware merging: distance, threshold, pair search, exact combination, remerge."""

import re

import numpy as np
import pytest

from glmap_tools.errors import InvalidInputError
from glmap_tools.gaussians import merge
from glmap_tools.gaussians._estimator_fast import gaussian_rows, sorted_mergeable_pairs
from glmap_tools.gaussians._estimator_reference import direct_fit, fit_reference
from glmap_tools.gaussians._estimator_union import union_additive, union_additive_reference
from glmap_tools.gaussians.estimator import EstimatorConfig, GaussianEstimator
from glmap_tools.gaussians.types import GaussianSet

CONFIG = EstimatorConfig()
VOXEL = CONFIG.voxel_size


def random_set(n: int, seed: int, extent: float = 0.15, offset: float = 0.0) -> GaussianSet:
    """n flat-ish random Gaussians packed closely enough that many pairs are candidates."""
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(n, 3, 3)) * np.array([0.012, 0.012, 0.002])
    covs = a @ a.transpose(0, 2, 1) + 1e-6 * np.eye(3)
    base = np.array([0.5, 0.4, 0.3])
    return GaussianSet(
        means=rng.uniform(0, extent, (n, 3)) * [1, 1, 0.2] + offset + base,
        covs=covs,
        colors=rng.uniform(0.47, 0.53, (n, 3)),
        opacities=np.full(n, 0.8),
        counts=rng.integers(1, 50, n),
    )


def brute_force_pairs(a: GaussianSet, b: GaussianSet, config: EstimatorConfig) -> set:
    """Every (i, j) with ||mu_i - mu_j|| <= one voxel and D < threshold, by plain loops."""
    kappa_a, kappa_b = merge.curvature(a.covs), merge.curvature(b.covs)
    found = set()
    for i in range(len(a)):
        for j in range(len(b)):
            mu_i, mu_j = a.means[i].astype(float), b.means[j].astype(float)
            if np.linalg.norm(mu_i - mu_j) > config.voxel_size:
                continue
            d = (
                np.linalg.norm(mu_i - mu_j)
                + config.lambda_cov * np.linalg.norm(a.covs[i].astype(float) - b.covs[j], "fro")
                + config.lambda_color * np.linalg.norm(a.colors[i].astype(float) - b.colors[j])
            )
            threshold = 2 * config.voxel_size * (1 + config.tau * (kappa_a[i] + kappa_b[j]))
            if d < threshold:
                found.add((i, j))
    return found


def gaussians_of(point_sets: list[tuple[np.ndarray, np.ndarray]]) -> GaussianSet:
    """One directly fitted Gaussian per (points, colours) set."""
    fits = [direct_fit(p, c, 1e-6) for p, c in point_sets]
    return GaussianSet(
        np.array([f[0] for f in fits]),
        np.array([f[1] for f in fits]),
        np.array([f[2] for f in fits]),
        np.full(len(fits), 0.8),
        np.array([len(p) for p, _ in point_sets]),
    )


def test_curvature_is_zero_on_a_plane_and_a_third_for_a_ball():
    flat = np.diag([1e-3, 1e-3, 0.0])
    ball = np.eye(3) * 2e-3
    np.testing.assert_allclose(merge.curvature(np.stack([flat, ball])), [0.0, 1 / 3], atol=1e-12)


def test_the_threshold_shrinks_with_curvature_and_scales_with_the_voxel():
    config = EstimatorConfig(voxel_size=0.05, tau=-20.0)
    np.testing.assert_allclose(
        merge.merge_threshold(np.array([0.0, 0.01]), np.array([0.0, 0.02]), config),
        [0.1, 0.1 * (1 - 20 * 0.03)],
    )


def test_gaussian_distance_adds_mean_covariance_and_colour_terms():
    g = random_set(6, 0)
    ia, ib = np.array([0, 2, 5]), np.array([1, 3, 4])
    expected = [
        np.linalg.norm(g.means[i].astype(float) - g.means[j])
        + 0.6 * np.linalg.norm(g.covs[i].astype(float) - g.covs[j])
        + 0.4 * np.linalg.norm(g.colors[i].astype(float) - g.colors[j])
        for i, j in zip(ia, ib, strict=True)
    ]
    np.testing.assert_allclose(merge.gaussian_distance(g, ia, g, ib, CONFIG), expected)


@pytest.mark.parametrize(
    ("n_a", "n_b", "seed", "extent"), [(5, 7, 0, 0.03), (40, 30, 1, 0.1), (120, 90, 2, 0.15)]
)
def test_mergeable_pairs_agree_with_a_brute_force_all_pairs_search(n_a, n_b, seed, extent):
    a, b = random_set(n_a, seed, extent), random_set(n_b, seed + 100, extent)
    pairs = merge.mergeable_pairs(a, b, CONFIG)
    expected = brute_force_pairs(a, b, CONFIG)
    assert len(expected) > 0
    assert {tuple(p) for p in pairs.tolist()} == expected
    assert pairs.tolist() == sorted(pairs.tolist())


@pytest.mark.parametrize("seed", [3, 4, 5, 6])
def test_any_mergeable_agrees_with_a_brute_force_all_pairs_search(seed, monkeypatch):
    monkeypatch.setattr(merge, "ANY_MERGEABLE_CHUNK", 7)  # exercise the early-exit chunks
    a = random_set(60, seed)
    for offset in (0.0, 0.02, 0.05, 0.3):
        b = random_set(50, seed + 50, offset=offset)
        assert merge.any_mergeable(a, b, CONFIG) == bool(brute_force_pairs(a, b, CONFIG))
        assert merge.any_mergeable(b, a, CONFIG) == bool(brute_force_pairs(b, a, CONFIG))
    assert not merge.any_mergeable(a, GaussianSet.empty(), CONFIG)


@pytest.mark.parametrize(("n", "seed", "extent"), [(10, 20, 0.03), (150, 21, 0.1), (600, 22, 0.2)])
def test_the_numba_pair_search_within_a_set_agrees_with_brute_force(n, seed, extent):
    g = random_set(n, seed, extent)
    pairs = sorted_mergeable_pairs(*gaussian_rows(g), CONFIG)
    expected = {p for p in brute_force_pairs(g, g, CONFIG) if p[0] < p[1]}
    assert len(expected) > 0
    assert {tuple(p) for p in pairs.tolist()} == expected
    d = merge.gaussian_distance(g, pairs[:, 0], g, pairs[:, 1], CONFIG)
    assert np.all(np.diff(d) >= 0)  # visited by increasing D


def test_the_closed_form_curvature_matches_eigvalsh():
    rng = np.random.default_rng(23)
    scales = rng.uniform(1e-6, 1e-3, (3000, 3))
    scales[::3, 2] = 0.0  # planes
    scales[1::5, 1] = scales[1::5, 2]  # lines: a repeated smallest eigenvalue
    scales[2::7] = scales[2::7, :1]  # balls: all three equal
    rotations = np.linalg.qr(rng.normal(size=(3000, 3, 3)))[0]
    covs = rotations @ (scales[:, :, None] * rotations.transpose(0, 2, 1)) + 1e-6 * np.eye(3)
    g = GaussianSet(np.zeros((3000, 3)), covs, np.zeros((3000, 3)), np.ones(3000), np.ones(3000))
    np.testing.assert_allclose(gaussian_rows(g)[3], merge.curvature(g.covs), atol=1e-6)


def test_combine_of_two_direct_fits_equals_the_direct_fit_of_the_concatenation():
    rng = np.random.default_rng(7)
    p1, p2 = rng.normal(0, 0.01, (40, 3)) + 2.0, rng.normal(0.01, 0.02, (25, 3)) + 2.0
    c1, c2 = rng.uniform(0, 1, (40, 3)), rng.uniform(0, 1, (25, 3))
    p3, c3 = rng.normal(0, 0.03, (10, 3)) - 1.0, rng.uniform(0, 1, (10, 3))
    parts = gaussians_of([(p1, c1), (p3, c3), (p2, c2)])
    combined = merge.combine(parts, np.array([4, 9, 4]))  # label order: 4 then 9
    whole = gaussians_of([(np.r_[p1, p2], np.r_[c1, c2]), (p3, c3)])
    np.testing.assert_allclose(combined.means, whole.means, atol=1e-6)
    np.testing.assert_allclose(combined.covs, whole.covs, rtol=1e-5, atol=1e-10)
    np.testing.assert_allclose(combined.colors, whole.colors, atol=1e-6)
    np.testing.assert_array_equal(combined.counts, [65, 10])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_combine_gives_the_numpy_formulas_bits(seed):
    """The numba kernel sums each group in numpy's order: groups of 1 to 129 members (the
    pairwise sum's 8 accumulators from 9 on), with -0.0 and colours outside [0, 1]."""
    rng = np.random.default_rng(seed)
    sizes = np.r_[1, 2, 3, 8, 9, 16, 17, 128, 129, rng.integers(1, 40, 30)]
    n = int(sizes.sum())
    g = random_set(n, seed)
    colors = rng.uniform(-0.2, 1.2, (n, 3))
    colors[::7] = -0.0
    g = GaussianSet(g.means, g.covs, colors, g.opacities, rng.integers(1, 10**6, n))
    groups = rng.permutation(np.repeat(rng.permutation(len(sizes)) * 3 - 20, sizes))
    labels, inverse = np.unique(groups, return_inverse=True)
    order = np.argsort(inverse, kind="stable")
    starts = np.searchsorted(inverse[order], np.arange(len(labels)))
    expected = merge._combine_by_numpy(g, inverse, order, starts, 1e-6)
    assert merge.combine(g, groups).equals(expected)
    big = np.zeros(n, np.int64)  # one group of them all: the numpy path itself
    assert merge.combine(g, big).equals(
        merge._combine_by_numpy(g, big, np.arange(n), np.zeros(1, np.int64), 1e-6)
    )


@pytest.mark.parametrize("seed", [0, 1])
def test_the_two_member_combine_gives_the_general_kernels_bits(seed):
    """`combine_two_into` (the structure layer's re-observed voxel) against `combine_into` of
    the same two rows: means far from the origin, counts up to 10^9, colours outside [0, 1]
    and -0.0."""
    from glmap_tools.gaussians._combine_numba import (
        combine_into,
        combine_scratch,
        combine_two_into,
    )

    rng = np.random.default_rng(seed)
    n = 2000
    g = random_set(2 * n, seed)
    means = g.means + rng.choice([0.0, 1e3, -5e4], (2 * n, 1))
    colors = rng.uniform(-0.2, 1.2, (2 * n, 3))
    colors[::5] = -0.0
    counts = rng.integers(1, 10 ** rng.integers(1, 10, 2 * n), dtype=np.int64)
    g = GaussianSet(means, g.covs, colors, g.opacities, counts)
    general, two = GaussianSet.allocate(n), GaussianSet.allocate(n)
    scratch = combine_scratch()
    for k in range(n):
        pair = g.subset(np.array([2 * k, 2 * k + 1]))
        combine_into(np.arange(2), 2, scratch, pair.arrays(), 1e-6, general.arrays(), k)
        combine_two_into(pair.arrays(), 1e-6, two.arrays(), k)
    assert two.equals(general)


def test_combine_refuses_bad_labels_and_zero_counts():
    g = random_set(3, 8)
    with pytest.raises(InvalidInputError, match="groups has shape"):
        merge.combine(g, np.array([0, 1]))
    with pytest.raises(InvalidInputError, match="integer labels"):
        merge.combine(g, np.array([0.0, 1.0, 1.0]))
    zero = GaussianSet(g.means, g.covs, g.colors, g.opacities, np.array([3, 0, 2]))
    with pytest.raises(InvalidInputError, match="Gaussian 1 has count 0"):
        merge.combine(zero, np.array([0, 0, 1]))


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_a_set_with_a_mean_that_is_not_finite_is_refused_by_each_pair_search(bad):
    g = random_set(6, 9)
    means = g.means.copy()
    means[4, 1] = bad
    bad_set = GaussianSet(means, g.covs, g.colors, g.opacities, g.counts)
    config = EstimatorConfig()
    calls = [
        lambda: merge.remerge(bad_set, config),
        lambda: merge.any_mergeable(g, bad_set, config),
        lambda: merge.mergeable_pairs(bad_set, g, config),
        lambda: merge.candidate_pairs_within(bad_set, 0.02),
    ]
    for call in calls:
        with pytest.raises(InvalidInputError, match=r"means\[4\] = .* is not finite \(1 such"):
            call()


@pytest.mark.parametrize(("n", "seed", "cap"), [(30, 0, 2.0), (200, 1, 4.0), (500, 2, np.inf)])
def test_the_numba_capped_union_matches_its_python_twin(n, seed, cap):
    g = random_set(n, seed)
    pairs = merge.candidate_pairs_within(g, 0.03)
    pairs = pairs[np.random.default_rng(seed).permutation(len(pairs))]
    rows = merge.additive_moments(g, g.means.mean(axis=0).astype(float), 1e-6)
    cap_trace = cap * float(np.median(np.trace(g.covs, axis1=1, axis2=2)))
    fast = union_additive(rows, pairs, cap_trace, 1e-6)
    np.testing.assert_array_equal(fast, union_additive_reference(rows, pairs, cap_trace, 1e-6))
    assert len(np.unique(fast)) < n
    assert len(np.unique(fast)) > 1 or cap == np.inf


def test_remerge_of_two_samplings_of_one_surface_reduces_the_count_and_stays_exact():
    rng = np.random.default_rng(9)
    clouds = []
    for _ in range(2):  # the same wavy sheet, sampled twice
        xy = rng.uniform(0, 0.3, (3000, 2))
        points = np.c_[xy, 0.03 * np.sin(10 * xy[:, 0])] + 1.0
        clouds.append((points, np.c_[xy / 0.3, np.full(len(xy), 0.5)]))
    fits = [fit_reference(p, c, CONFIG) for p, c in clouds]
    both = GaussianSet.concat([f.gaussians for f in fits])
    supports = fits[0].support + fits[1].support
    owner = [0] * len(fits[0].support) + [1] * len(fits[1].support)

    labels = merge.remerge_groups(both, CONFIG)
    merged = merge.remerge(both, CONFIG)
    assert len(merged) == len(np.unique(labels)) < 0.85 * len(both)
    assert merged.counts.sum() == both.counts.sum()
    for k, label in enumerate(np.unique(labels)):  # each = fit of its members' points
        members = np.flatnonzero(labels == label)
        pts = np.concatenate([clouds[owner[m]][0][supports[m]] for m in members])
        cols = np.concatenate([clouds[owner[m]][1][supports[m]] for m in members])
        mean, cov, color = direct_fit(pts, cols, 1e-6)
        np.testing.assert_allclose(merged.means[k], mean, atol=1e-6)
        np.testing.assert_allclose(merged.covs[k], cov, rtol=1e-4, atol=1e-9)
        np.testing.assert_allclose(merged.colors[k], color, atol=1e-6)
        assert merged.counts[k] == len(pts)
    sigma = np.sqrt(np.trace(merged.covs, axis1=1, axis2=2))
    grown = np.flatnonzero(np.bincount(np.unique(labels, return_inverse=True)[1]) > 1)
    assert sigma[grown].max() <= CONFIG.remerge_sigma * VOXEL * (1 + 1e-5)


def test_remerge_groups_match_on_the_grid_and_on_the_kd_tree_path(monkeypatch):
    g = random_set(400, 24, 0.2)
    grid = merge.remerge_groups(g, CONFIG)
    monkeypatch.setattr(merge, "MAX_GRID_SPAN", 0)  # as if the set were kilometres wide
    np.testing.assert_array_equal(merge.remerge_groups(g, CONFIG), grid)
    assert len(np.unique(grid)) < len(g)


def test_remerge_leaves_the_set_alone_when_merging_is_off():
    points = np.c_[np.random.default_rng(10).uniform(0, 0.3, (2000, 2)), np.full(2000, 0.1)]
    g = GaussianEstimator(EstimatorConfig(merge=False)).fit(points, np.full((2000, 3), 0.5))
    assert merge.remerge(g, EstimatorConfig(merge=False)) is g
    assert len(merge.remerge(g, CONFIG)) < len(g)
    assert len(merge.remerge(GaussianSet.empty(), CONFIG)) == 0


@pytest.mark.parametrize(
    ("field", "value", "said"),
    [
        ("means", None, "GaussianSet.means is of type NoneType"),
        ("colors", [[0.5, 0.5, 0.5]], "GaussianSet.colors is of type list"),
        ("opacities", np.array(["a"]), "GaussianSet.opacities is a <U1 array"),
        ("counts", np.int64(3), "GaussianSet.counts is of type int64"),
    ],
)
def test_a_gaussian_set_of_fields_that_are_not_numeric_arrays_names_the_field(field, value, said):
    parts = {
        "means": np.zeros((1, 3)),
        "covs": np.eye(3)[None] * 1e-4,
        "colors": np.full((1, 3), 0.5),
        "opacities": np.full(1, 0.8),
        "counts": np.ones(1, int),
    }
    with pytest.raises(InvalidInputError, match=re.escape(said)):
        GaussianSet(**{**parts, field: value})
