"""Render targets: an instance, a region, a subset, the whole map; sizes, poses, bad ids."""

from __future__ import annotations

import numpy as np
import pytest

from glmap_tools import synthetic as scenes
from glmap_tools.errors import GLMapError, InvalidInputError, UnknownIdError
from glmap_tools.geometry import Intrinsics, Pose
from glmap_tools.views import (
    MAX_VIEW_SIDE,
    map_gaussians,
    overview_pose,
    render_map,
    render_subset,
    render_unit,
    unit_gaussians,
    view_intrinsics,
)
from tests.test_views_fixtures import CHAIR_XY, TEXTS, build_wall_scene, empty_map, wall_boxes


@pytest.fixture(scope="module")
def scene():
    return build_wall_scene()


def front_of_chair() -> Pose:
    return Pose.looking_at(np.array([0.0, 2.4, 1.0]), np.array([*CHAIR_XY, 0.4]))


def drawn(rgb: np.ndarray) -> np.ndarray:
    """[H, W] bool: pixels that are not the white background."""
    return np.any(rgb < 245, axis=2)


def test_an_instance_alone_draws_only_its_own_gaussians(scene):
    intr = view_intrinsics(96, 72)
    alone = render_unit(scene.glmap, scene.chair, front_of_chair(), intr)
    with_context = render_unit(scene.glmap, scene.chair, front_of_chair(), intr, context=True)
    assert alone.label == "instance 1 (chair)" and alone.rgb.shape == (72, 96, 3)
    # The wall fills the background in context; alone, the chair covers a small part.
    assert 0.02 < drawn(alone.rgb).mean() < 0.35
    assert drawn(with_context.rgb).mean() > drawn(alone.rgb).mean() + 0.2
    # Where the chair is drawn alone, it stays red in context (it stands in front of the
    # wall, which only shows through its translucency).
    red = (alone.rgb[..., 0] > 150) & (alone.rgb[..., 1] < 100)
    assert red.sum() > 20
    diff = np.abs(with_context.rgb[red].astype(int) - alone.rgb[red].astype(int))
    assert np.median(diff) <= 10


def test_a_region_renders_the_union_of_its_instances(scene):
    assert scene.region is not None
    region = scene.glmap.regions[scene.region]
    g = unit_gaussians(scene.glmap, scene.region)
    assert len(g) == sum(len(scene.glmap.instances[i].gaussians) for i in region.instance_ids)
    intr = view_intrinsics(64, 48)
    a = render_unit(scene.glmap, scene.region, front_of_chair(), intr)
    b = render_subset(scene.glmap, list(region.instance_ids), front_of_chair(), intr)
    np.testing.assert_array_equal(a.rgb, b.rgb)
    assert a.label == f"region {scene.region}"


def test_a_subset_of_units_draws_more_than_either_alone(scene):
    intr = view_intrinsics(64, 48)
    pose = front_of_chair()
    both = render_subset(scene.glmap, [scene.chair, *scene.walls], pose, intr)
    chair = render_unit(scene.glmap, scene.chair, pose, intr)
    assert drawn(both.rgb).sum() > drawn(chair.rgb).sum()
    whole = render_map(scene.glmap, pose, intr, structure=False)
    np.testing.assert_array_equal(whole.rgb, both.rgb)  # the map is exactly these units


def test_the_whole_map_render_matches_the_ray_cast_view_where_it_is_covered(scene):
    intr = view_intrinsics(80, 60)
    pose = front_of_chair()
    view = render_map(scene.glmap, pose, intr, return_depth=True)
    depth, _, ids = scenes.raycast(wall_boxes(), pose, intr)
    covered = (view.alpha > 0.9) & (ids > 0)
    assert covered.mean() > 0.2
    assert view.depth is not None
    assert np.median(np.abs(view.depth[covered] - depth[covered])) < 0.03  # metres


def test_the_overview_camera_frames_every_instance_from_above(scene):
    intr = view_intrinsics(80, 60)
    pose = overview_pose(scene.glmap, intr)
    assert pose.translation[2] > 1.5 and pose.rotation[2, 2] < -0.5  # above, looking down
    for unit in scene.glmap.instances.values():
        cam = (unit.centroid - pose.translation) @ pose.rotation
        u, v = intr.fx * cam[0] / cam[2] + intr.cx, intr.fy * cam[1] / cam[2] + intr.cy
        assert 0 <= u < intr.width and 0 <= v < intr.height, unit.id
    assert drawn(render_map(scene.glmap, pose, intr).rgb).mean() > 0.08
    with pytest.raises(InvalidInputError, match="elevation"):
        overview_pose(scene.glmap, intr, elevation_deg=90.0)


def test_the_map_gaussian_cache_follows_new_frames():
    scene = build_wall_scene()
    before = map_gaussians(scene.glmap)
    assert map_gaussians(scene.glmap) is before
    frame, ids = scenes.view(wall_boxes(), (2.0, 1.5, 1.2), (*CHAIR_XY, 0.3), 64, 48)
    scene.glmap.integrate(frame, scenes.semantics(ids, {k: TEXTS[k] for k in (1, 2)}))
    after = map_gaussians(scene.glmap)
    assert after is not before
    assert len(after.gaussians) == sum(len(u.gaussians) for u in scene.glmap.instances.values())


def test_view_intrinsics_follow_the_field_of_view_and_cap_the_size():
    k = view_intrinsics(320, 240, 90.0)
    assert k.fx == pytest.approx(160.0) and (k.cx, k.cy) == (159.5, 119.5)
    for width, height in ((0, 240), (320, -1), (MAX_VIEW_SIDE + 1, 10), (10**9, 10**9)):
        with pytest.raises(InvalidInputError, match="pixels"):
            view_intrinsics(width, height)
    with pytest.raises(InvalidInputError, match=str(MAX_VIEW_SIDE)):
        view_intrinsics(4000, 100)
    with pytest.raises(InvalidInputError, match="integer"):
        view_intrinsics(320.5, 240)  # type: ignore[arg-type]
    with pytest.raises(InvalidInputError, match="hfov"):
        view_intrinsics(320, 240, 0.0)


def test_intrinsics_over_the_view_cap_are_refused_before_rendering(scene):
    wide = Intrinsics(1000.0, 1000.0, 2999.5, 1.0, 6000, 4)  # a valid camera, over the cap
    with pytest.raises(InvalidInputError, match=f"1..{MAX_VIEW_SIDE}"):
        render_map(scene.glmap, front_of_chair(), wide)
    with pytest.raises(InvalidInputError, match="Intrinsics"):
        render_map(scene.glmap, front_of_chair(), (320, 240))  # type: ignore[arg-type]
    tiny = render_unit(scene.glmap, scene.chair, front_of_chair(), view_intrinsics(1, 1))
    assert tiny.rgb.shape == (1, 1, 3)


def test_a_non_rigid_pose_is_refused_with_the_reason(scene):
    scaled = front_of_chair().matrix.copy()
    scaled[:3, :3] *= 1.5
    with pytest.raises(InvalidInputError, match="not rigid"):
        render_map(scene.glmap, scaled, view_intrinsics(32, 24))
    with pytest.raises(InvalidInputError, match="4x4"):
        render_map(scene.glmap, np.eye(3), view_intrinsics(32, 24))
    with pytest.raises(InvalidInputError, match="Pose"):
        render_map(scene.glmap, "front", view_intrinsics(32, 24))  # type: ignore[arg-type]
    # A plain 4x4 rigid matrix is accepted.
    view = render_map(scene.glmap, front_of_chair().matrix, view_intrinsics(32, 24))
    assert view.rgb.shape == (24, 32, 3)


def test_an_unknown_unit_id_names_the_closest_one(scene):
    with pytest.raises(UnknownIdError, match="does not exist") as info:
        render_unit(scene.glmap, 999, front_of_chair(), view_intrinsics(32, 24))
    assert "Closest id" in str(info.value) or "Did you mean" in str(info.value)
    with pytest.raises(InvalidInputError, match="integer"):
        render_unit(scene.glmap, "chair", front_of_chair(), view_intrinsics(32, 24))  # type: ignore[arg-type]
    with pytest.raises(InvalidInputError, match="integer"):
        render_unit(scene.glmap, True, front_of_chair(), view_intrinsics(32, 24))
    with pytest.raises(InvalidInputError, match="empty"):
        render_subset(scene.glmap, [], front_of_chair(), view_intrinsics(32, 24))


def test_an_empty_map_raises_a_glmap_error_for_every_target():
    glmap = empty_map()
    intr = view_intrinsics(32, 24)
    with pytest.raises(GLMapError, match="empty"):
        render_map(glmap, front_of_chair(), intr)
    with pytest.raises(GLMapError, match="empty"):
        render_unit(glmap, 1, front_of_chair(), intr)
    with pytest.raises(GLMapError, match="empty"):
        overview_pose(glmap, intr)
