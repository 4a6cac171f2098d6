"""The fast Gaussian Estimator: numba kernels glued together (twin of `_estimator_reference`)."""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

import numba
import numpy as np

from glmap_tools.gaussians import _estimator_candidates as candidates
from glmap_tools.gaussians import _estimator_clusters as clusters
from glmap_tools.gaussians import _estimator_grid as grid
from glmap_tools.gaussians import _estimator_numba as kernels
from glmap_tools.gaussians import _estimator_sweep as sweep
from glmap_tools.gaussians import _estimator_voxels as voxels
from glmap_tools.gaussians._estimator_union import union_additive
from glmap_tools.gaussians.types import GaussianSet

if TYPE_CHECKING:
    from glmap_tools.gaussians.config import EstimatorConfig

CHUNKS_PER_THREAD = 1  # numba splits a prange statically: more chunks only cost
PARALLEL_MIN_VOXELS = 10_000  # smaller clouds run on one thread (see design.md)
PARALLEL_MIN_POINTS = 40_000  # smaller clouds are voxelised on one thread


class StageTimes:
    """Process CPU seconds of each stage of one fit, in the order they ran
    (`python -m glmap_tools.bench estimator` prints where the time goes)."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}
        self._last = time.process_time()

    def lap(self, stage: str) -> None:
        """The time since the last lap (or since the clock was made) goes to `stage`."""
        now = time.process_time()
        self.seconds[stage] = self.seconds.get(stage, 0.0) + now - self._last
        self._last = now


def scan(points: np.ndarray, colors: np.ndarray) -> tuple[bool, bool, np.ndarray, np.ndarray]:
    """(points all finite, colours all in [0, 1], [3] point min, [3] point max), one pass
    (in two halves on two threads from PARALLEL_MIN_POINTS points)."""
    if len(points) >= PARALLEL_MIN_POINTS and numba.get_num_threads() > 1:
        stats = voxels.scan_cloud_halves(points, colors)
    else:
        stats = voxels.scan_cloud(points, colors)
    return bool(stats[0]), bool(stats[1]), stats[2:5], stats[5:8]


def fit_fast(
    points: np.ndarray,
    colors: np.ndarray,
    config: EstimatorConfig,
    lo: np.ndarray,
    stages: StageTimes | None = None,
    halves: bool | None = None,
) -> GaussianSet:
    """Fit and merge Gaussians to a validated, non-empty cloud.

    Args:
        points: [N, 3] float64, finite.
        colors: [N, 3] float32 in [0, 1].
        config: estimator settings.
        lo: [3] float64 smallest point coordinate per axis.
        stages: when given, each stage's process CPU time is added to it.
        halves: voxelise and sum the voxel moments in two halves on two threads (the same
            output); None: when the cloud has PARALLEL_MIN_POINTS points or more and numba
            two threads or more.
    """
    lap = stages.lap if stages is not None else _no_lap
    voxel = float(config.voxel_size)
    lo_cell = np.floor(lo / voxel).astype(np.int64)
    origin = (lo_cell - voxels.CELL_MARGIN).astype(np.float64) * voxel
    if halves is None:
        halves = len(points) >= PARALLEL_MIN_POINTS and numba.get_num_threads() > 1
    if halves:
        *voxelised, split = voxels.voxelize_halves(points, voxel, lo_cell)
    else:
        voxelised = list(voxels.voxelize(points, voxel, lo_cell))
    point_voxel, slot_voxel, voxel_block, voxel_slot, keys, table_keys, table_ids = voxelised
    lap("voxelise")
    block_nbrs = grid.block_neighbours(keys, table_keys, table_ids)
    lap("block neighbours")
    threads = numba.get_num_threads() if len(voxel_block) >= PARALLEL_MIN_VOXELS else 1
    n_chunks = 1 if threads == 1 else CHUNKS_PER_THREAD * threads
    if halves:
        moments = kernels.voxel_moments_split(
            points, colors, point_voxel, len(voxel_block), origin, split
        )
    else:
        moments = kernels.voxel_moments(points, colors, point_voxel, len(voxel_block), origin)
    lap("voxel moments")
    neighbours, first, n_neighbours, sums = kernels.neighbourhood_moments(
        voxel_block, voxel_slot, slot_voxel, block_nbrs, moments, n_chunks
    )
    emitted = np.flatnonzero(sums[:, 0] >= config.min_points)
    lap("neighbourhood sums")
    if len(emitted) == 0:
        return GaussianSet.empty()
    if config.merge and len(emitted) > 1:
        pairs = _fit_pairs(sums, emitted, config, n_chunks)
        lap("mergeable pairs")
        labels = union_additive(
            clusters.trace_rows(sums, emitted),
            pairs,
            config.merge_cap_trace,
            config.epsilon,
        )
        lap("capped union")
        sums = clusters.cluster_moments(
            labels, emitted, neighbours, first, n_neighbours, sums, moments, threads
        )
        emitted = np.arange(len(sums))
        lap("cluster sums")
    means32, covs32, cols32, counts = kernels.output_gaussians(
        sums, emitted, config.epsilon, origin
    )
    lap("output")
    return GaussianSet(means32, covs32, cols32, np.full(len(means32), config.opacity), counts)


def _no_lap(stage: str) -> None:
    """`StageTimes.lap` when no stage is timed."""


def _fit_pairs(
    sums: np.ndarray, emitted: np.ndarray, config: EstimatorConfig, n_chunks: int
) -> np.ndarray:
    """The mergeable pairs of the candidate Gaussians sums[emitted], ordered by (D, i, j):
    `sorted_mergeable_pairs` with the candidates computed straight into the sweep's order."""
    cells = candidates.candidate_cells(sums, emitted, config.candidate_radius)
    keys, ny, nz = sweep.cell_keys(cells)
    if len(keys) > 0 and keys[0] < 0:  # cell keys would overflow int64
        means, covs, cols, kappa = kernels.candidate_gaussians(
            sums, emitted, config.epsilon, n_chunks
        )
        return sorted_mergeable_pairs(means, covs, cols, kappa, config, n_chunks)
    order = sweep.radix_order(keys)
    near, rest = candidates.packed_candidates(sums, emitted, order, config.epsilon, n_chunks)
    pi, pj, d = sweep.sweep_packed(
        keys, order, ny, nz, near, rest, _pair_params(config), sweep.PAIR_BUFFER, n_chunks
    )
    return clusters.sort_pairs(pi, pj, d)


def _pair_params(config: EstimatorConfig) -> np.ndarray:
    """[5] (radius, voxel, tau, lambda_cov, lambda_color), the sweep's parameters."""
    return np.array(
        [
            config.candidate_radius,
            config.voxel_size,
            config.tau,
            config.lambda_cov,
            config.lambda_color,
        ]
    )


def sorted_mergeable_pairs(
    means: np.ndarray,
    covs: np.ndarray,
    colors: np.ndarray,
    kappa: np.ndarray,
    config: EstimatorConfig,
    n_chunks: int = 1,
) -> np.ndarray:
    """Mergeable pairs of G Gaussians, ordered by (D, i, j).

    A pair (i < j) is mergeable when ||mu_i - mu_j|| <= one voxel and
    D < 2 voxel (1 + tau (kappa_i + kappa_j)).

    Args:
        means: [G, 3] float64, every coordinate >= 0 (shift by an origin first).
        covs: [G, 6] float64 covariance rows (xx, xy, xz, yy, yz, zz) with their eps.
        colors: [G, 3] float64.
        kappa: [G] curvature.
        config: estimator settings.
        n_chunks: split the search over the thread team when > 1.

    Returns:
        [K, 2] int64.
    """
    m_cells = clusters.mean_cells(means, config.candidate_radius)
    params = _pair_params(config)
    keys, ny, nz = sweep.cell_keys(m_cells)
    if len(keys) == 0 or keys[0] >= 0:
        pi, pj, d = sweep.sweep_pairs(
            keys, ny, nz, means, covs, colors, kappa, params, sweep.PAIR_BUFFER, n_chunks
        )
    else:  # cell keys would overflow int64 (a cloud of ~2M radii along every axis)
        pi, pj, d = grid_pairs(m_cells, means, covs, colors, kappa, params, n_chunks)
    return clusters.sort_pairs(pi, pj, d)


def grid_pairs(
    m_cells: np.ndarray,
    means: np.ndarray,
    covs: np.ndarray,
    colors: np.ndarray,
    kappa: np.ndarray,
    params: np.ndarray,
    n_chunks: int = 1,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The mergeable pairs by the hashed block grid (any extent), unordered; see `sweep_pairs`."""
    m_block, m_keys, m_table_keys, m_table_ids = grid.blocks_of(m_cells)
    m_nbrs = grid.block_neighbours(m_keys, m_table_keys, m_table_ids)
    head, nxt = clusters.cell_lists(m_cells, m_block, len(m_keys))
    return clusters.pairs_by_chunk(
        n_chunks, m_cells, m_block, m_nbrs, head, nxt, means, covs, colors, kappa, params
    )


def gaussian_rows(g: GaussianSet) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Float64 (means [N, 3] shifted to be >= 0, covariance rows [N, 6], colours, kappa)."""
    means = g.means.astype(np.float64)
    means -= means.min(axis=0)
    c = g.covs.astype(np.float64)
    rows = np.stack(
        [c[:, 0, 0], c[:, 0, 1], c[:, 0, 2], c[:, 1, 1], c[:, 1, 2], c[:, 2, 2]], axis=1
    )
    return means, rows, g.colors.astype(np.float64), kernels.curvatures(rows)
