import math
import re

import numpy as np
import pytest

from glmap_tools.errors import InvalidInputError
from glmap_tools.geometry import Intrinsics, Pose, adapters, backproject, depth_from_uint16
from glmap_tools.geometry.frame import RGBDFrame


def test_intrinsics_from_fov_put_the_principal_point_at_the_image_centre():
    k = Intrinsics.from_fov(640, 480, 90.0)
    assert k.fx == pytest.approx(320.0)
    assert (k.cx, k.cy) == (319.5, 239.5)


@pytest.mark.parametrize("bad", [dict(fx=0.0), dict(fy=-1.0), dict(cx=float("nan")), dict(width=0)])
def test_non_positive_or_non_finite_intrinsics_are_refused(bad):
    args = dict(fx=525.0, fy=525.0, cx=319.5, cy=239.5, width=640, height=480) | bad
    with pytest.raises(InvalidInputError, match=next(iter(bad))):
        Intrinsics(**args)


def test_a_scaled_pose_is_refused_as_not_rigid():
    m = np.eye(4)
    m[:3, :3] *= 1.1
    with pytest.raises(InvalidInputError, match="not rigid"):
        Pose(m)


def test_a_pose_with_nan_is_refused():
    m = np.eye(4)
    m[0, 3] = np.nan
    with pytest.raises(InvalidInputError, match="NaN"):
        Pose(m)


def test_looking_at_points_the_optical_axis_at_the_target_with_image_down_toward_minus_z():
    pose = Pose.looking_at(np.array([0, 0, 1.0]), np.array([2.0, 0, 1.0]))
    np.testing.assert_allclose(pose.rotation[:, 2], [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(pose.rotation[:, 1], [0, 0, -1], atol=1e-12)
    assert pose.heading == pytest.approx(0.0)


def test_backprojection_of_the_principal_point_lands_on_the_optical_axis():
    k = Intrinsics(100.0, 100.0, 2.0, 2.0, 5, 5)
    pose = Pose.from_position_heading(1.0, 2.0, 0.5, math.pi / 2)
    depth = np.zeros((5, 5), np.float32)
    depth[2, 2] = 3.0
    cloud = backproject(depth, k, pose)
    np.testing.assert_allclose(cloud.points, [[1.0, 5.0, 0.5]], atol=1e-9)


def test_backprojection_skips_zero_nan_inf_and_far_depth():
    k = Intrinsics(10.0, 10.0, 1.0, 0.5, 3, 2)
    depth = np.array([[0.0, np.nan, np.inf], [1.0, 9.0, 2.0]], np.float32)
    cloud = backproject(depth, k, Pose.identity(), max_range=5.0)
    assert len(cloud) == 2
    np.testing.assert_allclose(sorted(cloud.points[:, 2]), [1.0, 2.0])


def test_backprojection_keeps_only_masked_pixels_and_their_colours():
    k = Intrinsics(10.0, 10.0, 1.0, 1.0, 3, 3)
    depth = np.ones((3, 3), np.float32)
    rgb = np.zeros((3, 3, 3), np.uint8)
    rgb[1, 2] = (255, 0, 0)
    mask = np.zeros((3, 3), bool)
    mask[1, 2] = True
    cloud = backproject(depth, k, Pose.identity(), rgb, mask)
    np.testing.assert_allclose(cloud.colors, [[1.0, 0.0, 0.0]])


def test_mismatched_depth_and_rgb_shapes_name_both_shapes():
    k = Intrinsics(10.0, 10.0, 1.0, 1.0, 3, 3)
    with pytest.raises(InvalidInputError, match=r"\(2, 3, 3\)"):
        RGBDFrame(np.zeros((2, 3, 3), np.uint8), np.ones((3, 3), np.float32), k, Pose.identity())


@pytest.mark.parametrize(
    ("field", "value", "said"),
    [
        ("intrinsics", None, "intrinsics is NoneType, not Intrinsics"),
        ("intrinsics", [525.0, 525.0, 1.0, 1.0], "intrinsics is list, not Intrinsics"),
        ("pose", np.eye(4), "pose is ndarray, not Pose; pass Pose(world_from_camera)"),
    ],
)
def test_a_frame_with_intrinsics_or_a_pose_of_another_kind_is_refused(field, value, said):
    k = Intrinsics(1.0, 1.0, 1.0, 1.0, 3, 3)
    parts = {"intrinsics": k, "pose": Pose.identity(), field: value}
    with pytest.raises(InvalidInputError, match=re.escape(said)):
        RGBDFrame(np.zeros((3, 3, 3), np.uint8), np.ones((3, 3), np.float32), **parts)


def test_uint16_depth_converts_with_the_stated_scale():
    d = depth_from_uint16(np.array([[1000, 0]], np.uint16), 1000.0)
    np.testing.assert_allclose(d, [[1.0, 0.0]])
    for bad in (0, -1.0, float("nan"), 1e-300, 1e39, "1000", True):  # 1e-300 was 0 in float32
        with pytest.raises(
            InvalidInputError, match=re.escape(f"depth_scale={bad!r} must be a positive")
        ):
            depth_from_uint16(np.zeros((1, 1), np.uint16), bad)  # type: ignore[arg-type]


def test_opengl_adapter_flips_the_camera_y_and_z_axes():
    gl = np.eye(4)
    pose = adapters.from_opengl(gl)
    np.testing.assert_allclose(pose.rotation, np.diag([1.0, -1.0, -1.0]))
    np.testing.assert_allclose(adapters.to_opengl(pose), gl)


def test_habitat_identity_camera_looks_along_minus_z_habitat_which_is_plus_y_here():
    pose = adapters.from_habitat(np.array([1.0, 1.5, -2.0]), np.array([1.0, 0, 0, 0]))
    np.testing.assert_allclose(pose.translation, [1.0, 2.0, 1.5])
    np.testing.assert_allclose(pose.rotation[:, 2], [0, 1, 0], atol=1e-12)  # forward
    np.testing.assert_allclose(pose.rotation[:, 1], [0, 0, -1], atol=1e-12)  # image down


@pytest.mark.parametrize("up", ["x", "-x", "y", "-y", "z", "-z"])
def test_every_dataset_up_axis_maps_onto_plus_z(up):
    r = adapters.world_zup_from_up_axis(up)
    axis = {"x": [1, 0, 0], "y": [0, 1, 0], "z": [0, 0, 1]}[up.strip("-")]
    sign = -1 if up.startswith("-") else 1
    np.testing.assert_allclose(r @ (sign * np.array(axis, float)), [0, 0, 1], atol=1e-12)
    assert np.linalg.det(r) == pytest.approx(1.0)


def test_an_unknown_up_axis_is_refused():
    with pytest.raises(InvalidInputError, match="up axis 'w'"):
        adapters.world_zup_from_up_axis("w")


@pytest.mark.parametrize(
    ("bad", "message"),
    [
        (dict(fx=1e-300), "horizontal field of view"),
        (dict(fy=1e-3), "vertical field of view"),
        (dict(fx=1e9), "times the image side"),
        (dict(cx=1e300), "principal point"),
        (dict(cy=-1000.0), "principal point"),
        (dict(cx=float("inf")), "principal point"),
    ],
)
def test_intrinsics_of_an_impossible_camera_are_refused_naming_the_value(bad, message):
    args = dict(fx=525.0, fy=525.0, cx=319.5, cy=239.5, width=640, height=480) | bad
    with pytest.raises(InvalidInputError, match=message):
        Intrinsics(**args)


@pytest.mark.parametrize("hfov", [170.0001, 179.999, 179.9999999, 180.0, float("nan"), True])
def test_a_field_of_view_over_170_degrees_is_refused(hfov):
    with pytest.raises(InvalidInputError, match="hfov_deg"):
        Intrinsics.from_fov(64, 48, hfov)


def test_the_widest_and_narrowest_accepted_cameras_keep_finite_rays():
    wide = Intrinsics.from_fov(64, 48, 170.0)
    narrow = Intrinsics(6400.0, 6400.0, 31.5, 23.5, 64, 48)
    for k in (wide, narrow):
        depth = np.ones((48, 64), np.float32)
        cloud = backproject(depth, k, Pose.identity())
        assert len(cloud) == 64 * 48 and np.all(np.isfinite(cloud.points))


def test_a_pose_translated_1e300_m_is_refused_though_finite_and_rigid():
    with pytest.raises(InvalidInputError, match="from the origin"):
        Pose.from_rt(np.eye(3), np.array([1e300, 0.0, 0.0]))
    assert Pose.from_rt(np.eye(3), np.array([1e5, 0.0, 0.0])).translation[0] == 1e5


@pytest.mark.parametrize(
    ("make", "said"),
    [
        (lambda: Intrinsics([525.0], 525.0, 1.0, 1.0, 3, 3), "Intrinsics fx=[525.0] is not a"),
        (lambda: Intrinsics(525.0, 525.0, "1", 1.0, 3, 3), "Intrinsics cx='1' is not a number"),
        (lambda: Intrinsics.from_fov("640", 480, 79.0), "Intrinsics width='640' must be an int"),
        (lambda: Intrinsics.from_fov(640, 2**40, 79.0), "Intrinsics height=1099511627776"),
        (lambda: Intrinsics.from_fov(8, 8, 60).scaled(float("nan"), 4), "width=nan must be"),
        (lambda: Pose("x"), "pose 'x' is not numbers; pass a 4x4"),
        (lambda: Pose.from_position_heading(0.0, 0.0, 1.0, heading=None), "heading=None must"),
        (lambda: Pose.from_position_heading(0.0, 0.0, 1.0, 0.0, pitch=math.nan), "pitch=nan"),
        (lambda: Pose.looking_at([1e308, 0.0, 1.0], [0.0, 0.0, 0.0]), "must be finite metres"),
        (lambda: Pose.looking_at([0.0, 1.0], [0.0, 0.0, 0.0]), "three numbers each"),
    ],
)
def test_a_camera_made_from_values_of_another_kind_names_the_value(make, said):
    with pytest.raises(InvalidInputError, match=re.escape(said)):
        make()
