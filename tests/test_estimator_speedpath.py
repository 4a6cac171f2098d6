"""The estimator's fast kernels: the sorted sweep finds the same pairs as the hashed grid, and
the lockstep kernels give the bits of their plain scalar twins."""

import numpy as np
import pytest

from glmap_tools.gaussians import _estimator_candidates as candidates
from glmap_tools.gaussians import _estimator_clusters as clusters
from glmap_tools.gaussians import _estimator_numba as kernels
from glmap_tools.gaussians import _estimator_sweep as sweep
from glmap_tools.gaussians import _estimator_voxels as voxels
from glmap_tools.gaussians._estimator_fast import gaussian_rows, grid_pairs
from glmap_tools.gaussians.estimator import EstimatorConfig
from glmap_tools.gaussians.types import GaussianSet

CONFIG = EstimatorConfig()


def clustered_set(n: int, seed: int, duplicates: int = 0) -> GaussianSet:
    """n flat random Gaussians within a few voxels of each other, `duplicates` of them twice."""
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(n, 3, 3)) * np.array([0.012, 0.012, 0.002])
    means = rng.uniform(0, 0.12, (n, 3)) * [1, 1, 0.3] + [0.5, 0.4, 0.3]
    covs = a @ a.transpose(0, 2, 1) + 1e-6 * np.eye(3)
    colors = rng.uniform(0.47, 0.53, (n, 3))
    pick = rng.choice(n, duplicates, replace=False)
    return GaussianSet(
        means=np.concatenate([means, means[pick]]),
        covs=np.concatenate([covs, covs[pick]]),
        colors=np.concatenate([colors, colors[pick]]),
        opacities=np.full(n + duplicates, 0.8),
        counts=np.ones(n + duplicates),
    )


def sweep_and_grid(
    g: GaussianSet, buffer: int = sweep.PAIR_BUFFER, n_chunks: int = 1
) -> tuple[np.ndarray, np.ndarray]:
    means, covs, colors, kappa = gaussian_rows(g)
    params = np.array(
        [CONFIG.candidate_radius, CONFIG.voxel_size, CONFIG.tau, CONFIG.lambda_cov,
         CONFIG.lambda_color]
    )  # fmt: skip
    cells = clusters.mean_cells(means, CONFIG.candidate_radius)
    keys, ny, nz = sweep.cell_keys(cells)
    assert keys.min() >= 0
    by_sweep = clusters.sort_pairs(
        *sweep.sweep_pairs(keys, ny, nz, means, covs, colors, kappa, params, buffer, n_chunks)
    )
    by_grid = clusters.sort_pairs(*grid_pairs(cells, means, covs, colors, kappa, params))
    return by_sweep, by_grid


@pytest.mark.parametrize("n", [1, 2, 40, 600])
@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.parametrize("n_chunks", [1, 3])
def test_the_sweep_and_the_grid_find_the_same_pairs_in_the_same_order(n, seed, n_chunks):
    by_sweep, by_grid = sweep_and_grid(clustered_set(n, seed, duplicates=n // 4), n_chunks=n_chunks)
    np.testing.assert_array_equal(by_sweep, by_grid)
    if n >= 40:
        assert len(by_sweep) > n  # the set is dense enough that many pairs merge


@pytest.mark.parametrize("buffer", [1, 7, 64])
@pytest.mark.parametrize("n_chunks", [1, 8])
def test_the_sweep_finds_the_same_pairs_whatever_its_buffer_holds(buffer, n_chunks):
    # 120 copies of one Gaussian share a cell: one run meets far more pairs than the buffer
    g = clustered_set(300, 4, duplicates=60)
    g = GaussianSet.concat([g, *[GaussianSet(
        g.means[:1], g.covs[:1], g.colors[:1], g.opacities[:1], g.counts[:1]
    )] * 120])  # fmt: skip
    by_sweep, by_grid = sweep_and_grid(g, buffer, n_chunks)  # 8 chunks: some overflow
    np.testing.assert_array_equal(by_sweep, by_grid)
    assert len(by_sweep) > 120 * 119 // 2


def test_the_sweep_computes_each_pairs_d_to_the_bit():
    # the merge's tolerance is zero: D and the mergeable test are those of pair_distance
    means, covs, colors, kappa = gaussian_rows(clustered_set(600, 6, duplicates=30))
    params = np.array(
        [CONFIG.candidate_radius, CONFIG.voxel_size, CONFIG.tau, CONFIG.lambda_cov,
         CONFIG.lambda_color]
    )  # fmt: skip
    keys, ny, nz = sweep.cell_keys(clusters.mean_cells(means, CONFIG.candidate_radius))
    # n_chunks given, as the fit gives it: leaving it out compiles the kernel a second time
    pi, pj, d = sweep.sweep_pairs(keys, ny, nz, means, covs, colors, kappa, params, 64, 1)
    assert len(d) > 600
    expected = [
        clusters.pair_distance(means, covs, colors, i, j, CONFIG.lambda_cov, CONFIG.lambda_color)
        for i, j in zip(pi.tolist(), pj.tolist(), strict=True)
    ]
    np.testing.assert_array_equal(d, expected)


def test_the_radius_test_without_a_square_root_is_the_one_with_it():
    rng = np.random.default_rng(5)
    for radius in (0.01, 0.015, 0.02, 0.1, 1e-3, *rng.uniform(1e-3, 0.1, 200)):
        bound = sweep.sqrt_bound(radius)
        assert np.sqrt(bound) <= radius < np.sqrt(np.nextafter(bound, np.inf))


def test_the_radix_order_is_a_stable_argsort():
    rng = np.random.default_rng(3)
    keys = rng.integers(0, 1 << 40, 5000)
    keys[::3] = keys[0]  # many ties
    np.testing.assert_array_equal(sweep.radix_order(keys), np.argsort(keys, kind="stable"))


def test_cell_keys_refuse_extents_that_would_overflow():
    cells = np.array([[1, 1, 1], [1 << 21, 1 << 21, 1 << 21]], dtype=np.int64)
    keys, _, _ = sweep.cell_keys(cells)
    assert (keys == -1).all()


def test_the_lockstep_curvatures_are_the_scalar_newton_bit_for_bit():
    rng = np.random.default_rng(11)
    a = rng.normal(size=(3000, 3, 3)) * rng.uniform(1e-4, 1e-2, (3000, 1, 3))
    covs = a @ a.transpose(0, 2, 1) + 1e-6 * np.eye(3)
    covs[:200] = np.diag([2e-5, 2e-5, 2e-5]) + 1e-9 * np.eye(3)  # repeated roots: the formula
    covs[200:400] = np.diag(rng.uniform(1e-6, 1e-4, 3))  # diagonal
    # C order, as the fit's rows: another layout would compile the kernel again (seconds in CI)
    rows = np.ascontiguousarray(covs[:, [0, 0, 0, 1, 1, 2], [0, 1, 2, 1, 2, 2]])
    expected = np.array([max(kernels.min_eigenvalue(*r), 0.0) / (r[0] + r[3] + r[5]) for r in rows])
    np.testing.assert_array_equal(kernels.curvatures(rows), expected)
    np.testing.assert_array_equal(kernels.curvatures(rows[5:70]), expected[5:70])


def test_the_input_scan_flags_what_numpy_flags_and_finds_the_extent():
    rng = np.random.default_rng(4)
    points = rng.normal(size=(1001, 3))
    colors = rng.uniform(0, 1, (1001, 3)).astype(np.float32)
    stats = voxels.scan_cloud(points, colors)
    assert stats[0] == 1.0 and stats[1] == 1.0
    np.testing.assert_array_equal(stats[2:5], points.min(axis=0))
    np.testing.assert_array_equal(stats[5:8], points.max(axis=0))
    for bad in (np.nan, np.inf, -np.inf):
        p = points.copy()
        p[700, 2] = bad
        assert voxels.scan_cloud(p, colors)[0] == 0.0
    one_up = np.nextafter(np.float32(1), np.float32(2))
    for value, ok in ((0.0, 1), (-0.0, 1), (1.0, 1), (-1e-30, 0), (one_up, 0), (np.nan, 0)):
        c = colors.copy()
        c[333, 1] = value
        assert voxels.scan_cloud(points, c)[1] == ok, value


@pytest.mark.parametrize("at", [0, 499, 500, 1000])
def test_the_input_scan_in_halves_is_the_one_pass_scan(at):
    rng = np.random.default_rng(7)
    points = rng.normal(size=(1001, 3))
    colors = rng.uniform(0, 1, (1001, 3)).astype(np.float32)
    points[at] = [40.0, -40.0, 7.0]  # the extent's corner in either half
    np.testing.assert_array_equal(
        voxels.scan_cloud_halves(points, colors), voxels.scan_cloud(points, colors)
    )
    for bad_points, bad_colors in ((np.inf, 0.5), (0.0, 1.5)):
        p, c = points.copy(), colors.copy()
        p[at, 1] = bad_points
        c[at, 2] = bad_colors
        flags = voxels.scan_cloud_halves(p, c)[:2]
        np.testing.assert_array_equal(flags, voxels.scan_cloud(p, c)[:2])
        assert flags.min() == 0.0


def test_the_candidates_in_key_order_are_the_candidates_packed_by_the_sweep():
    rng = np.random.default_rng(8)
    sums = np.abs(rng.normal(size=(500, 13))) + 0.01
    sums[:, 0] = rng.integers(3, 40, 500)
    sums[:, 4:10] += 10.0  # a positive-definite-ish second moment
    rows = np.sort(rng.choice(500, 400, replace=False))
    means, covs, colors, kappa = kernels.candidate_gaussians(sums, rows, 1e-6, 1)
    radius = 0.3
    cells = candidates.candidate_cells(sums, rows, radius)
    np.testing.assert_array_equal(cells, clusters.mean_cells(means, radius))
    keys, _, _ = sweep.cell_keys(cells)
    order = sweep.radix_order(keys)
    expected = candidates.pack_in_key_order(order, means, covs, colors, kappa)
    for n_chunks in (1, 3):
        got = candidates.packed_candidates(sums, rows, order, 1e-6, n_chunks)
        np.testing.assert_array_equal(got[0], expected[0])
        np.testing.assert_array_equal(got[1], expected[1])


def test_the_pair_order_does_not_depend_on_the_order_the_pairs_come_in():
    rng = np.random.default_rng(9)
    k = 3000
    pi = rng.integers(0, 500, k)
    pj = pi + rng.integers(1, 500, k)
    keep = np.unique(pi * 1000 + pj, return_index=True)[1]
    pi, pj = pi[keep], pj[keep]
    d = rng.choice([0.0, 0.25, 0.5, 0.75], len(pi))  # ties, crowded buckets of one D
    d[::7] = rng.uniform(0, 1, len(d[::7]))
    # a crowded bucket of two D values one ulp apart (the general path)
    d[d == 0.5] = rng.choice([0.5, np.nextafter(0.5, 1.0)], int(np.sum(d == 0.5)))
    assert np.sum(d == 0.0) > clusters.CROWDED_BUCKET
    assert np.sum(d == np.nextafter(0.5, 1.0)) > 0
    expected = np.stack([pi, pj], axis=1)[np.lexsort((pj, pi, d))]
    for seed in (0, 1):
        p = np.random.default_rng(seed).permutation(len(pi))
        np.testing.assert_array_equal(clusters.sort_pairs(pi[p], pj[p], d[p]), expected)


@pytest.mark.parametrize("d_max", [5e-324, 1e-310, 2.2e-308])
def test_pairs_whose_largest_d_is_subnormal_are_sorted(d_max):
    # n / d_max overflows to inf there: the buckets must not read 0 * inf
    pi, pj = np.arange(40), np.arange(40) + 1
    d = np.where(np.arange(40) % 3 == 0, d_max, 0.0)
    expected = np.stack([pi, pj], axis=1)[np.lexsort((pj, pi, d))]
    backwards = (np.ascontiguousarray(a[::-1]) for a in (pi, pj, d))  # C order, as the fit's
    np.testing.assert_array_equal(clusters.sort_pairs(*backwards), expected)


def test_the_stage_clock_times_every_stage_and_changes_no_output():
    from glmap_tools.bench.estimator import FIT_STAGES, MERGE_DECISIONS, stage_medians
    from glmap_tools.gaussians._estimator_fast import StageTimes, fit_fast
    from glmap_tools.gaussians.estimator import validate_cloud

    rng = np.random.default_rng(3)
    plane = np.c_[rng.uniform(0, 0.4, (6000, 2)), rng.normal(0, 0.002, 6000)]
    colours = rng.uniform(0, 1, (6000, 3))
    pts, cols, lo = validate_cloud(plane, colours, CONFIG.voxel_size)
    stages = StageTimes()
    timed = fit_fast(pts, cols, CONFIG, lo, stages)
    plain = fit_fast(pts, cols, CONFIG, lo)
    assert len(timed) < 1000  # the plane merged
    for a, b in zip(timed.arrays(), plain.arrays(), strict=True):
        assert np.array_equal(a, b)
    every = [*FIT_STAGES[1:], *MERGE_DECISIONS, "cluster sums", "output"]
    assert list(stages.seconds) == every
    assert all(s >= 0.0 for s in stages.seconds.values())
    assert list(stage_medians(plane, colours, CONFIG.voxel_size, 2)) == ["input checks", *every]


def halves_clouds() -> dict[str, tuple[np.ndarray, float]]:
    """Clouds for the two-thread voxelising: a noisy surface, one whose blocks overfill both
    halves' tables and the join (a block per point), shared and duplicate points, tiny ones."""
    rng = np.random.default_rng(11)
    surface = np.c_[rng.uniform(0, 1.5, (60_000, 2)), rng.normal(0, 0.004, 60_000)]
    sparse = rng.uniform(0, 60.0, (30_000, 3))
    dupes = np.repeat(rng.uniform(0, 0.2, (700, 3)), 3, axis=0)
    shared = np.concatenate([surface[:5000], surface[:5000][::-1]])  # the halves meet everywhere
    return {
        "surface": (surface, 0.015),
        "a block per point": (sparse, 0.01),
        "duplicates": (dupes, 0.015),
        "the second half repeats the first": (shared, 0.02),
        "one point": (surface[:1], 0.015),
        "two points": (surface[:2], 0.015),
        "three points": (surface[:3], 0.015),
    }


@pytest.mark.parametrize("name", list(halves_clouds()))
def test_voxelising_in_halves_numbers_blocks_and_voxels_as_one_pass_does(name):
    points, voxel = halves_clouds()[name]
    points = np.ascontiguousarray(points, dtype=np.float64)
    lo = np.floor(points.min(axis=0) / voxel).astype(np.int64)
    one_pass = voxels.voxelize(points, voxel, lo)
    *halves, split = voxels.voxelize_halves(points, voxel, lo)
    for a, b in zip(one_pass, halves, strict=True):
        assert a.dtype == b.dtype and np.array_equal(a, b)
    point_voxel = one_pass[0]
    # the voxels from `split` on hold points of the second half only, and those below it
    # are the first half's
    assert point_voxel[: len(points) // 2].max(initial=-1) < split
    assert set(np.unique(point_voxel[point_voxel >= split]).tolist()) <= set(
        point_voxel[len(points) // 2 :].tolist()
    )


@pytest.mark.parametrize("name", ["surface", "duplicates", "the second half repeats the first"])
def test_voxel_moments_summed_in_halves_are_the_one_thread_sums_to_the_bit(name):
    points, voxel = halves_clouds()[name]
    points = np.ascontiguousarray(points, dtype=np.float64)
    colors = np.random.default_rng(5).uniform(0, 1, (len(points), 3)).astype(np.float32)
    lo = np.floor(points.min(axis=0) / voxel).astype(np.int64)
    origin = (lo - voxels.CELL_MARGIN).astype(np.float64) * voxel
    point_voxel, *_, split = voxels.voxelize_halves(points, voxel, lo)
    n_voxels = int(point_voxel.max()) + 1
    one = kernels.voxel_moments(points, colors, point_voxel, n_voxels, origin)
    two = kernels.voxel_moments_split(points, colors, point_voxel, n_voxels, origin, split)
    assert np.array_equal(one, two)


def test_a_fit_in_halves_is_the_one_pass_fit():
    from glmap_tools.gaussians._estimator_fast import fit_fast
    from glmap_tools.gaussians.estimator import validate_cloud

    points, voxel = halves_clouds()["surface"]
    colours = np.random.default_rng(6).uniform(0, 1, (len(points), 3))
    config = EstimatorConfig(voxel_size=voxel)
    pts, cols, lo = validate_cloud(points, colours, voxel)
    halves = fit_fast(pts, cols, config, lo, halves=True)
    one_pass = fit_fast(pts, cols, config, lo, halves=False)
    assert len(one_pass) > 1000
    for a, b in zip(halves.arrays(), one_pass.arrays(), strict=True):
        assert np.array_equal(a, b)
