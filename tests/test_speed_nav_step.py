"""Shortcuts of the agent's step that must not change a bit: cached Gaussian bounds, the
structure update's row order, any_mergeable's early exit and grid pair search,
the index grid's cell replacement, block pooling."""

from __future__ import annotations

import numpy as np
import pytest

from glmap_tools.gaussians.config import EstimatorConfig
from glmap_tools.gaussians.merge import any_mergeable, mergeable_pairs
from glmap_tools.gaussians.types import GaussianSet
from glmap_tools.map.structure import _row_order
from glmap_tools.nav.planner import pool_any, pool_max


def test_cached_bounds_are_the_means_extremes_and_callers_cannot_spoil_them() -> None:
    rng = np.random.default_rng(1)
    n = 50
    g = GaussianSet(
        rng.normal(size=(n, 3)), np.tile(np.eye(3), (n, 1, 1)), np.full((n, 3), 0.5),
        np.full(n, 0.8), np.ones(n),
    )  # fmt: skip
    lo, hi = g.bounds()
    np.testing.assert_array_equal(lo, g.means.min(axis=0))
    np.testing.assert_array_equal(hi, g.means.max(axis=0))
    lo -= 1.0  # a caller widening its copy
    np.testing.assert_array_equal(g.bounds()[0], g.means.min(axis=0))


def test_replacing_a_units_cells_by_their_difference_leaves_the_grid_a_fresh_one_would_be():
    from glmap_tools.map.grid import IndexGrid

    rng = np.random.default_rng(8)
    grid, final = IndexGrid(), {}
    for _ in range(300):
        uid = int(rng.integers(0, 12))
        cells = rng.integers(0, 15, (int(rng.integers(0, 40)), 2))
        if rng.random() < 0.5:  # as the map passes them: a frozenset of int pairs
            cells = frozenset(map(tuple, cells.tolist()))
        grid.set_unit(uid, cells)
        final[uid] = {(int(i), int(j)) for i, j in cells}
    fresh = IndexGrid()
    for uid, cells in final.items():
        fresh.set_unit(uid, cells)
    assert grid.snapshot() == fresh.snapshot()
    assert all(grid.cells_of_unit(u) == c for u, c in final.items())


def test_the_row_order_is_lexsorts() -> None:
    rng = np.random.default_rng(6)
    for n, width in ((0, 5), (1, 5), (700, 5), (4000, 5), (300, 3)):
        rows = rng.integers(-300, 300, (n, width))
        rows[: n // 3] = rows[n // 3 : 2 * (n // 3)]  # repeated rows: the sort must be stable
        np.testing.assert_array_equal(_row_order(rows), np.lexsort(rows.T[::-1]))
    wide = rng.integers(-(1 << 40), 1 << 40, (50, 5))  # a key past int64: lexsort itself
    np.testing.assert_array_equal(_row_order(wide), np.lexsort(wide.T[::-1]))


def _flat_set(rng: np.random.Generator, n: int, lo: float) -> GaussianSet:
    spread = rng.choice([0.005, 0.01, 0.02])
    half = rng.normal(size=(n, 3, 3)) * [spread, spread, rng.choice([0.001, spread])]
    return GaussianSet(
        rng.uniform(lo, lo + 0.15, (n, 3)), half @ half.transpose(0, 2, 1) + 1e-6 * np.eye(3),
        rng.uniform(0, 1, (n, 3)), np.full(n, 0.8), np.ones(n),
    )  # fmt: skip


@pytest.mark.parametrize("tau", [-5.0, -20.0, 0.0, 2.0])
def test_any_mergeable_answers_as_the_full_pair_filter(tau: float) -> None:
    config = EstimatorConfig(voxel_size=0.02, tau=tau)
    rng = np.random.default_rng(3)
    answers = set()
    for _ in range(60):
        a = _flat_set(rng, int(rng.integers(1, 400)), 0.0)
        b = _flat_set(rng, int(rng.integers(1, 400)), rng.choice([0.0, 0.1]))
        if rng.random() < 0.7:  # b re-observes part of a: jittered means, similar colours
            pick = rng.integers(0, len(a), len(b))
            b = GaussianSet(
                a.means[pick] + rng.normal(0, rng.choice([0.003, 0.01, 0.03]), (len(b), 3)),
                a.covs[pick] if rng.random() < 0.5 else b.covs,
                np.clip(a.colors[pick] + rng.normal(0, rng.choice([0.01, 0.1]), (len(b), 3)), 0, 1),
                b.opacities, b.counts,
            )  # fmt: skip
        pairs = mergeable_pairs(a, b, config)  # every pair within the radius, filtered fully
        assert any_mergeable(a, b, config) == (len(pairs) > 0)
        answers.add(len(pairs) > 0)
    assert answers == {True, False}


def test_the_grid_pair_search_finds_the_pairs_cKDTree_finds() -> None:
    from scipy.spatial import cKDTree

    from glmap_tools.gaussians.merge import _pairs_within

    rng = np.random.default_rng(5)
    radius = 0.02
    lattice = np.stack(np.meshgrid(*[np.arange(6) * radius] * 3), axis=-1).reshape(-1, 3)
    cases = [(lattice, lattice + [radius, 0.0, 0.0]), (lattice[:1], lattice[1:2])]  # exactly r
    for _ in range(200):
        n, m = (int(v) for v in rng.integers(1, 600, 2))
        scale = rng.choice([0.05, 0.3, 2.0, 20.0])  # dense to sparse; the widest go to cKDTree
        a = rng.uniform(-scale, scale, (n, 3)) + rng.uniform(-50, 50, 3)
        b = a[rng.integers(0, n, m)] + rng.normal(0, radius, (m, 3)) if rng.random() < 0.7 else (
            rng.uniform(-scale, scale, (m, 3)) + a.mean(axis=0))  # fmt: skip
        cases.append((a.astype(np.float32).astype(np.float64), b))
    total = 0
    for a, b in cases:
        ia, ib = _pairs_within(a, b, radius)
        found = cKDTree(a).sparse_distance_matrix(cKDTree(b), radius, output_type="ndarray")
        expected = sorted(zip(found["i"].tolist(), found["j"].tolist(), strict=True))
        assert sorted(zip(ia.tolist(), ib.tolist(), strict=True)) == expected
        total += len(expected)
    assert total > 10_000


@pytest.mark.parametrize("shape", [(1, 1), (5, 3), (61, 47)])
@pytest.mark.parametrize("stride", [1, 2, 3, 4])
def test_block_pooling_by_strided_slices_is_the_block_reduction(shape, stride) -> None:
    rng = np.random.default_rng(4)
    values = np.where(rng.random(shape) < 0.7, rng.uniform(0.1, 1.0, shape), 0.0)
    mask = rng.random(shape) < 0.2
    h, w = shape
    pad = ((0, -h % stride), (0, -w % stride))
    hb, wb = (h + pad[0][1]) // stride, (w + pad[1][1]) // stride
    blocks = np.pad(values, pad).reshape(hb, stride, wb, stride)
    np.testing.assert_array_equal(pool_max(values, stride), blocks.max(axis=(1, 3)))
    blocks = np.pad(mask, pad).reshape(hb, stride, wb, stride)
    np.testing.assert_array_equal(pool_any(mask, stride), blocks.any(axis=(1, 3)))


def test_the_structure_layers_count_is_its_chunks_count_after_every_update() -> None:
    """`len(StructureLayer)` is kept by `apply`; it stays the sum over the chunks as frames
    add voxels, re-observe them and replace chunks."""
    from glmap_tools.map.structure import StructureLayer

    rng = np.random.default_rng(11)
    layer = StructureLayer(0.05)
    for _ in range(25):
        n = int(rng.integers(1, 400))
        means = rng.uniform(-1.5, 1.5, (n, 3)).astype(np.float32)
        g = GaussianSet(
            means,
            np.tile(np.eye(3, dtype=np.float32) * 1e-4, (n, 1, 1)),
            rng.uniform(0, 1, (n, 3)).astype(np.float32),
            np.full(n, 0.8, np.float32),
            rng.integers(1, 50, n).astype(np.uint32),
        )
        layer.apply(layer.compute_update(g))
        assert len(layer) == sum(len(c) for c in layer.chunks.values()) == len(layer.means())
