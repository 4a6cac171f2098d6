"""PLY export of a map, an instance or a region; PNG writes; no partial file on any error."""

from __future__ import annotations

import numpy as np
import pytest

from glmap_tools.errors import GLMapError, InvalidInputError, StoreError, UnknownIdError
from glmap_tools.gaussians.ply import read_ply
from glmap_tools.views import export_ply, unit_gaussians, write_png
from tests.test_views_fixtures import build_wall_scene, empty_map


@pytest.fixture(scope="module")
def scene():
    return build_wall_scene()


def assert_same_gaussians(read, written) -> None:
    np.testing.assert_allclose(read.means, written.means, atol=1e-6)
    np.testing.assert_allclose(read.covs, written.covs, rtol=1e-3, atol=1e-9)
    np.testing.assert_allclose(read.colors, written.colors, atol=1e-6)
    np.testing.assert_allclose(read.opacities, written.opacities, atol=1e-6)


def test_an_instance_exported_as_ply_reads_back_the_same(scene, tmp_path):
    out = export_ply(scene.glmap, tmp_path / "chair.ply", scene.chair)
    assert out.what == "instance 1 (chair)" and out.instance_ids == (scene.chair,)
    written = scene.glmap.instances[scene.chair].gaussians
    assert out.gaussians == len(written)
    assert_same_gaussians(read_ply(out.path), written)


def test_a_region_and_the_whole_map_export_the_union_of_their_instances(scene, tmp_path):
    assert scene.region is not None
    region = export_ply(scene.glmap, tmp_path / "region.ply", scene.region)
    assert_same_gaussians(read_ply(region.path), unit_gaussians(scene.glmap, scene.region))
    whole = export_ply(scene.glmap, tmp_path / "map.ply", sh_degree=3)
    assert whole.gaussians == sum(len(u.gaussians) for u in scene.glmap.instances.values())
    assert whole.instance_ids == tuple(sorted(scene.glmap.instances))
    assert b"f_rest_44" in whole.path.read_bytes()[:4096]
    assert len(read_ply(whole.path)) == whole.gaussians


def test_bad_exports_raise_before_any_file_is_written(scene, tmp_path):
    target = tmp_path / "out.ply"
    with pytest.raises(UnknownIdError, match="does not exist"):
        export_ply(scene.glmap, target, 999)
    with pytest.raises(InvalidInputError, match="sh_degree"):
        export_ply(scene.glmap, target, sh_degree=2)
    with pytest.raises(GLMapError, match="empty"):
        export_ply(empty_map(), target)
    with pytest.raises(StoreError, match="does not exist"):
        export_ply(scene.glmap, tmp_path / "missing" / "out.ply")
    with pytest.raises(StoreError, match="folder"):
        export_ply(scene.glmap, tmp_path)
    assert list(tmp_path.iterdir()) == []


def test_an_existing_file_is_kept_when_an_export_fails(scene, tmp_path):
    target = tmp_path / "keep.ply"
    target.write_bytes(b"keep me")
    with pytest.raises(UnknownIdError):
        export_ply(scene.glmap, target, 12345)
    assert target.read_bytes() == b"keep me"
    assert [p.name for p in tmp_path.iterdir()] == ["keep.ply"]


def test_png_writes_check_the_image_and_leave_no_partial_file(tmp_path):
    rgb = np.zeros((4, 5, 3), np.uint8)
    path = write_png(tmp_path / "a.png", rgb)
    assert path.read_bytes().startswith(b"\x89PNG")
    with pytest.raises(InvalidInputError, match="uint8"):
        write_png(tmp_path / "b.png", rgb.astype(np.float32))
    with pytest.raises(StoreError):
        write_png(tmp_path / "no" / "c.png", rgb)
    assert [p.name for p in tmp_path.iterdir()] == ["a.png"]
