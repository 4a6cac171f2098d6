"""The structure background layer: walls and floor render and occlude, but are never units."""

from __future__ import annotations

import numpy as np
import pytest

from glmap_tools import synthetic as scenes
from glmap_tools.gaussians.ply import read_ply
from glmap_tools.gaussians.types import GaussianSet
from glmap_tools.language.embed import HashingEmbedder
from glmap_tools.map import GLMap, MapConfig
from glmap_tools.map.structure import StructureLayer
from glmap_tools.views import export_ply, render_map, select_view, situated_views, view_intrinsics

CHAIR_XY = (0.0, 0.7)
TEXTS = {1: ("chair", "a red chair with wooden legs")}
OPEN_SIDE = [(0.0, 2.6), (1.6, 2.2), (-1.6, 2.2)]
WALL_SIDE = [(0.0, -2.4), (1.5, -2.2), (-1.5, -2.2)]


def room() -> list[scenes.Box]:
    """A floor, an unannotated wall at y = 0 (object id 0) and a red chair behind it."""
    wall = scenes.Box((-2.0, -0.05, 0.0), (2.0, 0.05, 1.6), (0.85, 0.85, 0.8), 0)
    return scenes.floor(4.0) + [wall] + scenes.chair(*CHAIR_XY)


def build(config: MapConfig | None = None) -> GLMap:
    glmap = GLMap(config or MapConfig(floor_z=0.0), embedder=HashingEmbedder())
    for x, y in OPEN_SIDE:
        frame, ids = scenes.view(room(), (x, y, 1.2), (*CHAIR_XY, 0.3), 160, 120)
        glmap.integrate(frame, scenes.semantics(ids, TEXTS))
    for x, y in WALL_SIDE:
        frame, ids = scenes.view(room(), (x, y, 1.2), (0.0, 0.0, 0.5), 160, 120)
        glmap.integrate(frame, scenes.semantics(ids, TEXTS))
    return glmap


@pytest.fixture(scope="module")
def glmap() -> GLMap:
    return build()


def red(rgb: np.ndarray) -> int:
    """Pixels of the chair's red."""
    return int(((rgb[..., 0] > 150) & (rgb[..., 1] < 100) & (rgb[..., 2] < 100)).sum())


def test_an_object_behind_a_wall_is_hidden_from_the_far_side_in_situated_views(glmap):
    intr = view_intrinsics(64, 48)
    facing_wall = situated_views(glmap, 0.0, -1.5, np.pi / 2, intr).by_direction()["front"]
    see_through = situated_views(glmap, 0.0, -1.5, np.pi / 2, intr, structure=False)
    assert red(see_through.by_direction()["front"].rgb) > 20  # without the layer: seen
    assert red(facing_wall.rgb) == 0
    # The wall itself is drawn: most of the front view is covered.
    assert facing_wall.alpha.mean() > 0.5
    # From the open side the chair is in plain view, walls or not.
    open_side = situated_views(glmap, 0.0, 2.0, -np.pi / 2, intr).by_direction()["front"]
    assert red(open_side.rgb) > 20


def test_view_selection_counts_the_wall_as_an_occluder(glmap):
    choice = select_view(glmap, 1, view_intrinsics(64, 48))
    assert choice.pose.translation[1] > 0.2  # on the chair's open side of the wall
    behind = [c for c in choice.candidates if c.score is not None and c.y < -0.3]
    assert behind, "some scored candidates stand behind the wall"
    assert max(c.visible or 0.0 for c in behind) < 0.05


def test_structure_is_never_a_unit(glmap):
    assert len(glmap.structure) > 0
    assert set(glmap.instances) == {1} and not glmap.regions
    grid_ids = set().union(*glmap.grid.snapshot().values())
    assert grid_ids <= set(glmap.instances) | set(glmap.regions)
    hits = glmap.find_instances("a long white wall", k=10)
    assert [h.id for h in hits] == [1]
    assert glmap.units_at(1.5, 0.0, radius=0.3) == []  # on the wall, far from the chair
    assert glmap.summary().structure_gaussians == len(glmap.structure)


def test_frames_without_any_object_build_only_structure():
    glmap = GLMap(MapConfig(floor_z=0.0), embedder=HashingEmbedder())
    frame, ids = scenes.view(room(), (0.0, -2.4, 1.2), (0.0, 0.0, 0.5), 160, 120)
    report = glmap.integrate(frame, scenes.semantics(ids, {}))
    assert report.structure_gaussians > 0 and len(glmap.structure) > 0
    assert not glmap.instances and len(glmap.grid) == 0
    assert glmap.find_instances("wall") == [] and glmap.units_at(0.0, 0.0, 1.0) == []
    view = render_map(glmap, frame.pose, view_intrinsics(48, 36))
    assert view.alpha.mean() > 0.5  # the wall and floor are drawn


def test_seeing_the_same_wall_again_does_not_grow_the_layer():
    glmap = GLMap(MapConfig(floor_z=0.0), embedder=HashingEmbedder())
    frame, ids = scenes.view(room(), (0.3, -2.4, 1.2), (0.0, 0.0, 0.5), 96, 72)
    sizes, points = [], []
    for _ in range(4):
        glmap.integrate(frame, scenes.semantics(ids, TEXTS))
        sizes.append(len(glmap.structure))
        points.append(int(glmap.structure.gaussians().counts.sum()))
    assert sizes == [sizes[0]] * 4  # one Gaussian per coarse voxel, merged
    assert points[1] == 2 * points[0]  # the re-observations are counted in
    keys = np.concatenate([c.keys for c in glmap.structure.chunks.values()])
    assert len(np.unique(keys, axis=0)) == len(keys)


def test_the_layer_can_be_switched_off():
    glmap = GLMap(MapConfig(floor_z=0.0, structure_voxel=None), embedder=HashingEmbedder())
    frame, ids = scenes.view(room(), (0.0, 2.6, 1.2), (*CHAIR_XY, 0.3), 96, 72)
    assert glmap.integrate(frame, scenes.semantics(ids, TEXTS)).structure_gaussians == 0
    assert len(glmap.structure) == 0 and len(glmap.instances) == 1


def _random_structure(rng: np.random.Generator, n: int, centre: float) -> GaussianSet:
    means = centre + rng.uniform(-0.25, 0.25, (n, 3))
    a = rng.normal(0, 0.01, (n, 3, 3))
    covs = a @ a.transpose(0, 2, 1) + 1e-5 * np.eye(3)
    colors = rng.uniform(0, 1, (n, 3))
    return GaussianSet(means, covs, colors, np.full(n, 0.8), rng.integers(5, 50, n))


def _assert_same_chunks(fast: dict, slow: dict) -> None:
    assert list(fast) == list(slow)  # the same chunks, in the same order
    for key, chunk in fast.items():
        np.testing.assert_array_equal(chunk.keys, slow[key].keys)
        assert chunk.gaussians.equals(slow[key].gaussians), key  # to the bit


@pytest.mark.parametrize("centre", [0.0, 1e5])  # 1e5 m: keys of 2 million voxels
def test_the_fast_per_voxel_merge_equals_the_plain_reference(centre):
    rng = np.random.default_rng(7)
    layer = StructureLayer(0.05)
    for _ in range(3):
        fitted = _random_structure(rng, 500, centre)
        fast, slow = layer.compute_update(fitted), layer.compute_update_reference(fitted)
        _assert_same_chunks(fast, slow)
        layer.apply(fast)
    assert len(layer) == len({tuple(k) for c in layer.chunks.values() for k in c.keys.tolist()})


@pytest.mark.parametrize("members", [9, 40, 128, 129, 200])
def test_a_crowded_voxel_sums_as_merge_combine_does(members):
    """Many Gaussians in one voxel: numpy's pairwise sums (>= 8 terms), the kernel's limit
    (129) and beyond it (the plain path takes over)."""
    rng = np.random.default_rng(members)
    layer = StructureLayer(0.05)
    layer.apply(layer.compute_update(_random_structure(rng, 300, 0.0)))
    crowd = _random_structure(rng, members, 0.0)
    crowd = GaussianSet(
        np.full((members, 3), 0.1) + rng.uniform(0, 0.04, (members, 3)),
        crowd.covs, crowd.colors, crowd.opacities, crowd.counts,
    )  # fmt: skip
    fitted = GaussianSet.concat([crowd, _random_structure(rng, 50, 0.0)])
    fast = layer.compute_update(fitted)
    _assert_same_chunks(fast, layer.compute_update_reference(fitted))
    merged = fast[(0, 0)]
    assert merged.gaussians.counts[(merged.keys == (2, 2, 2)).all(axis=1)].item() >= sum(
        crowd.counts
    )


def test_stored_keys_out_of_order_are_merged_as_well():
    """A chunk whose keys are not in order (not written by this layer) still merges right."""
    rng = np.random.default_rng(3)
    layer = StructureLayer(0.05)
    layer.apply(layer.compute_update(_random_structure(rng, 400, 0.0)))
    key, chunk = next(iter(layer.chunks.items()))
    shuffled = rng.permutation(len(chunk))
    layer.chunks[key] = type(chunk)(chunk.keys[shuffled], chunk.gaussians.subset(shuffled))
    fitted = _random_structure(rng, 400, 0.0)
    _assert_same_chunks(layer.compute_update(fitted), layer.compute_update_reference(fitted))


def test_a_ply_export_holds_the_structure_only_when_asked(glmap, tmp_path):
    units = export_ply(glmap, tmp_path / "units.ply")
    both = export_ply(glmap, tmp_path / "both.ply", structure=True)
    assert both.gaussians == units.gaussians + len(glmap.structure)
    assert len(read_ply(tmp_path / "both.ply")) == both.gaussians
