"""Ingest readers: the bundled Redwood frames, a synthetic TUM folder, and bad inputs."""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from glmap_tools.errors import GLMapError, InvalidInputError
from glmap_tools.geometry import Intrinsics, backproject
from glmap_tools.ingest import (
    load_depth_png,
    load_rgb,
    open_sequence,
    read_annotation,
    write_annotation,
)
from glmap_tools.ingest.tum import associate, quaternion_to_matrix

BUNDLED = Path(__file__).resolve().parents[1] / "glmap_tools/data/redwood_livingroom1_5frames"
LABELS = {1: "lounge chair", 2: "curtain", 3: "door frame", 4: "floor", 5: "wall"}


@pytest.fixture(scope="module")
def redwood_frames():
    return list(open_sequence(BUNDLED).frames())


@pytest.fixture
def redwood_copy(tmp_path):
    folder = tmp_path / "redwood"
    shutil.copytree(BUNDLED, folder)
    return folder


# --- the bundled Redwood (ICL-NUIM living room) frames --------------------------------------


def test_the_bundled_redwood_folder_opens_as_five_frames_with_primesense_intrinsics():
    seq = open_sequence(BUNDLED)
    assert (seq.format, len(seq), seq.frame_count) == ("redwood", 5, 5)
    assert seq.intrinsics == Intrinsics(525.0, 525.0, 319.5, 239.5, 640, 480)
    assert seq.intrinsics_source == "camera_primesense.json"
    assert (seq.depth_scale, seq.up_axis) == (1000.0, "y")


def test_redwood_poses_are_z_up_with_the_camera_down_axis_near_minus_z(redwood_frames):
    for item in redwood_frames:
        down = item.frame.pose.rotation[:, 1]
        assert down @ np.array([0.0, 0.0, -1.0]) > 0.99
        assert abs(item.frame.pose.rotation[2, 2]) < 0.1  # looking roughly level


def test_redwood_depth_is_float_metres_in_a_room_sized_range(redwood_frames):
    for item in redwood_frames:
        depth = item.frame.depth
        valid = depth[depth > 0]
        assert depth.dtype == np.float32
        assert valid.min() > 0.5 and valid.max() < 4.0
        assert 1.5 < float(np.median(valid)) < 2.5


def test_the_redwood_floor_back_projects_to_one_horizontal_plane_in_every_frame(redwood_frames):
    heights = []
    for item in redwood_frames:
        floor = next(o for o in item.semantics.objects if o.label == "floor")
        f = item.frame
        cloud = backproject(f.depth, f.intrinsics, f.pose, mask=floor.mask)
        assert np.std(cloud.points[:, 2]) < 0.01
        heights.append(np.median(cloud.points[:, 2]))
    assert np.ptp(heights) < 0.005


def test_bundled_annotations_parse_into_the_expected_labels_and_groups(redwood_frames):
    for item in redwood_frames:
        assert item.semantics is not None
        assert {o.local_id: o.label for o in item.semantics.objects} == LABELS
        assert all(o.description for o in item.semantics.objects)
        members = {g.local_id: g.members for g in item.semantics.groups}
        assert members == {1: (1, 2), 2: (2, 3)}
        assert "lounge chair" in item.semantics.groups[0].description


def test_each_annotated_object_has_one_world_centroid_across_frames_within_5_cm(redwood_frames):
    for object_id, label in LABELS.items():
        centroids = []
        for item in redwood_frames:
            obj = next(o for o in item.semantics.objects if o.local_id == object_id)
            f = item.frame
            cloud = backproject(f.depth, f.intrinsics, f.pose, mask=obj.mask)
            assert len(cloud) > 5000, label
            centroids.append(cloud.points.mean(axis=0))
        c = np.array(centroids)
        spread = np.linalg.norm(c - c.mean(axis=0), axis=1).max()
        assert spread < 0.05, f"{label}: {spread:.3f} m"


def test_the_chair_sits_between_the_floor_and_a_metre_above_it(redwood_frames):
    item = redwood_frames[0]
    f = item.frame
    chair = next(o for o in item.semantics.objects if o.label == "lounge chair")
    floor = next(o for o in item.semantics.objects if o.label == "floor")
    chair_z = backproject(f.depth, f.intrinsics, f.pose, mask=chair.mask).points[:, 2]
    floor_z = np.median(backproject(f.depth, f.intrinsics, f.pose, mask=floor.mask).points[:, 2])
    assert chair_z.min() > floor_z
    assert 0.6 < chair_z.max() - floor_z < 1.1


def test_stride_and_max_frames_select_frames_and_keep_their_sequence_index():
    seq = open_sequence(BUNDLED, stride=2, max_frames=2)
    assert [item.index for item in seq.frames()] == [0, 2]


def test_up_axis_override_changes_the_world_but_not_the_camera():
    default = open_sequence(BUNDLED, max_frames=1).poses[0]
    as_is = open_sequence(BUNDLED, max_frames=1, up_axis="z").poses[0]
    assert as_is.rotation[1, 1] < -0.99  # raw y-up world: camera down is -y
    np.testing.assert_allclose(default.rotation[2], as_is.rotation[1], atol=1e-12)


def test_a_redwood_folder_without_camera_json_gets_the_primesense_default(redwood_copy):
    (redwood_copy / "camera_primesense.json").unlink()
    seq = open_sequence(redwood_copy)
    assert seq.intrinsics == Intrinsics(525.0, 525.0, 319.5, 239.5, 640, 480)
    assert seq.intrinsics_source.startswith("default")


def test_a_redwood_folder_without_rgbd_match_pairs_images_by_name(redwood_copy):
    (redwood_copy / "rgbd.match").unlink()
    seq = open_sequence(redwood_copy)
    assert [s.rgb_path.name for s in seq.sources] == [f"{i:05d}.jpg" for i in range(5)]
    assert [s.depth_path.name for s in seq.sources] == [f"{i:05d}.png" for i in range(5)]


def test_a_frame_without_annotation_files_has_no_semantics(redwood_copy):
    for path in (redwood_copy / "annotations").glob("00001.*"):
        path.unlink()
    items = list(open_sequence(redwood_copy).frames())
    assert [item.semantics is None for item in items] == [False, True, False, False, False]


# --- image helpers -------------------------------------------------------------------------


def test_load_rgb_returns_rgb_order_although_opencv_reads_bgr(tmp_path):
    bgr = np.zeros((4, 5, 3), np.uint8)
    bgr[..., 2] = 255  # red in OpenCV's BGR order
    cv2.imwrite(str(tmp_path / "red.png"), bgr)
    rgb = load_rgb(tmp_path / "red.png")
    assert rgb.shape == (4, 5, 3) and rgb.dtype == np.uint8
    assert rgb[0, 0].tolist() == [255, 0, 0]


def test_load_depth_png_divides_raw_units_by_the_scale(tmp_path):
    raw = np.array([[0, 5000], [2500, 65535]], np.uint16)
    cv2.imwrite(str(tmp_path / "d.png"), raw)
    depth = load_depth_png(tmp_path / "d.png", 5000.0)
    assert depth.dtype == np.float32
    np.testing.assert_allclose(depth, [[0.0, 1.0], [0.5, 13.107]], rtol=1e-6)


def test_write_annotation_round_trips_through_read_annotation(tmp_path):
    mask = np.zeros((6, 8), np.int64)
    mask[1:3, 1:4] = 7
    mask[4:, 5:] = 2
    labels = {
        "objects": [
            {"id": 7, "label": "lamp", "description": "a brass floor lamp"},
            {"id": 2, "label": "rug"},
        ],
        "groups": [{"id": 1, "description": "reading nook: lamp and rug", "members": [7, 2]}],
    }
    png, _ = write_annotation(tmp_path, "frame_a", mask, labels)
    assert cv2.imread(str(png), cv2.IMREAD_UNCHANGED).dtype == np.uint8
    semantics = read_annotation(tmp_path, "frame_a", (6, 8))
    assert {o.local_id: int(o.mask.sum()) for o in semantics.objects} == {7: 6, 2: 6}
    assert semantics.groups[0].members == (7, 2)


def test_write_annotation_refuses_a_malformed_annotation_and_writes_nothing(tmp_path):
    mask = np.ones((4, 4), np.uint8)
    with pytest.raises(InvalidInputError, match="unknown member ids"):
        write_annotation(
            tmp_path,
            "x",
            mask,
            {
                "objects": [{"id": 1, "label": "sofa"}],
                "groups": [{"id": 1, "description": "g", "members": [9]}],
            },
        )
    assert not (tmp_path / "annotations").exists()


# --- a synthetic TUM RGB-D folder ----------------------------------------------------------


RGB_STAMPS = [10.000, 10.033, 10.066, 10.110, 10.200]  # 10.110 has no depth within 0.02 s
DEPTH_STAMPS = [10.004, 10.031, 10.080, 10.205, 10.300]  # 10.066 pairs with 10.080
TRUTH = {  # timestamp: (tx, ty, tz, qx, qy, qz, qw)
    9.995: (1.0, 2.0, 1.5, 0.0, 0.0, math.sin(math.pi / 4), math.cos(math.pi / 4)),
    10.035: (1.1, 2.0, 1.5, 0.5, 0.5, 0.5, 0.5),
    10.070: (1.2, 2.0, 1.5, 0.0, 0.0, 0.0, 1.0),
}  # 10.200 has depth but no pose within 0.02 s


def make_tum(folder: Path, width: int = 32, height: int = 24) -> Path:
    """Write a tiny TUM-style folder: 5 colour, 5 depth images, 3 ground-truth poses."""
    (folder / "rgb").mkdir(parents=True)
    (folder / "depth").mkdir()
    rgb_lines, depth_lines = ["# color images"], ["# depth maps"]
    for n, t in enumerate(RGB_STAMPS):
        bgr = np.full((height, width, 3), (10 * n, 100, 200), np.uint8)
        cv2.imwrite(str(folder / f"rgb/{t:.6f}.png"), bgr)
        rgb_lines.append(f"{t:.6f} rgb/{t:.6f}.png")
    for n, t in enumerate(DEPTH_STAMPS):
        raw = np.full((height, width), 5000 * (n + 1), np.uint16)
        cv2.imwrite(str(folder / f"depth/{t:.6f}.png"), raw)
        depth_lines.append(f"{t:.6f} depth/{t:.6f}.png")
    truth_lines = ["# timestamp tx ty tz qx qy qz qw"]
    truth_lines += [f"{t:.4f} " + " ".join(f"{v:.9f}" for v in row) for t, row in TRUTH.items()]
    (folder / "rgb.txt").write_text("\n".join(rgb_lines) + "\n")
    (folder / "depth.txt").write_text("\n".join(depth_lines) + "\n")
    (folder / "groundtruth.txt").write_text("\n".join(truth_lines) + "\n")
    return folder


def test_quaternions_become_the_hand_computed_rotations():
    s = math.sin(math.pi / 4)
    np.testing.assert_allclose(
        quaternion_to_matrix(0.0, 0.0, s, s), [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-12
    )
    # 120 degrees about (1, 1, 1): x -> y -> z -> x.
    np.testing.assert_allclose(
        quaternion_to_matrix(0.5, 0.5, 0.5, 0.5), [[0, 0, 1], [1, 0, 0], [0, 1, 0]], atol=1e-12
    )
    np.testing.assert_allclose(quaternion_to_matrix(2.0, 0, 0, 0), np.diag([1, -1, -1]), atol=0)


def test_association_pairs_nearest_timestamps_one_to_one_within_20_ms():
    assert associate(RGB_STAMPS, DEPTH_STAMPS) == [(0, 0), (1, 1), (2, 2), (4, 3)]
    # Two colour frames near one depth frame: only the closer one gets it.
    assert associate([1.000, 1.010], [1.012]) == [(1, 0)]
    assert associate([1.0], [1.03]) == []


def test_a_tum_folder_round_trips_poses_depth_and_association(tmp_path):
    seq = open_sequence(make_tum(tmp_path / "rgbd_dataset_custom"))
    assert (seq.format, seq.depth_scale, seq.up_axis) == ("tum", 5000.0, "z")
    assert len(seq) == 3 and seq.dropped == 2
    assert [s.timestamp for s in seq.sources] == RGB_STAMPS[:3]
    assert [s.depth_path.name for s in seq.sources] == [f"{t:.6f}.png" for t in DEPTH_STAMPS[:3]]
    items = list(seq.frames())
    np.testing.assert_allclose(
        items[0].frame.pose.matrix,
        [[0, -1, 0, 1.0], [1, 0, 0, 2.0], [0, 0, 1, 1.5], [0, 0, 0, 1]],
        atol=1e-9,
    )
    np.testing.assert_allclose(
        items[1].frame.pose.rotation, [[0, 0, 1], [1, 0, 0], [0, 1, 0]], atol=1e-9
    )
    np.testing.assert_allclose(items[2].frame.pose.matrix[:3, 3], [1.2, 2.0, 1.5])
    assert [float(i.frame.depth[0, 0]) for i in items] == [1.0, 2.0, 3.0]
    assert items[0].frame.rgb[0, 0].tolist() == [200, 100, 0]
    assert all(i.semantics is None for i in items)


def test_tum_default_intrinsics_follow_the_freiburg_camera_or_the_ros_default(tmp_path):
    fr2 = open_sequence(make_tum(tmp_path / "rgbd_dataset_freiburg2_desk", 640, 480))
    assert (fr2.intrinsics.fx, fr2.intrinsics.cy) == (520.9, 249.7)
    small = open_sequence(make_tum(tmp_path / "custom"))  # 32x24: ROS default, rescaled
    assert small.intrinsics == Intrinsics(525.0, 525.0, 319.5, 239.5, 640, 480).scaled(32, 24)
    given = Intrinsics(30.0, 30.0, 15.5, 11.5, 32, 24)
    assert open_sequence(tmp_path / "custom", intrinsics=given).intrinsics == given


# --- bad inputs ----------------------------------------------------------------------------


def test_a_missing_folder_is_named_in_the_error(tmp_path):
    with pytest.raises(InvalidInputError, match="does not exist"):
        open_sequence(tmp_path / "nope")


def test_an_unrecognised_folder_says_what_each_format_needs(tmp_path):
    (tmp_path / "notes.txt").write_text("hi")
    with pytest.raises(GLMapError) as err:
        open_sequence(tmp_path)
    message = str(err.value)
    assert "trajectory.log" in message and "groundtruth.txt" in message and "notes.txt" in message


def test_more_images_than_poses_is_refused(redwood_copy):
    log = redwood_copy / "trajectory.log"
    log.write_text("\n".join(log.read_text().splitlines()[:20]) + "\n")
    with pytest.raises(InvalidInputError, match="4 poses but the folder has 5 image pairs"):
        open_sequence(redwood_copy)


def test_a_truncated_trajectory_log_is_refused(redwood_copy):
    log = redwood_copy / "trajectory.log"
    log.write_text("\n".join(log.read_text().splitlines()[:22]) + "\n")
    with pytest.raises(InvalidInputError, match="multiple of 5"):
        open_sequence(redwood_copy)


@pytest.mark.parametrize("name", ["trajectory.log", "rgbd.match"])
def test_a_text_file_that_is_not_utf8_is_refused_naming_it(redwood_copy, name):
    path = redwood_copy / name
    path.write_bytes(path.read_bytes().replace(b"0", b"\xff", 1))
    with pytest.raises(InvalidInputError, match=f"cannot read .*{name}' as text"):
        open_sequence(redwood_copy)


def test_a_tum_list_that_is_not_utf8_is_refused_naming_it(tmp_path):
    from glmap_tools.ingest.tum import read_file_list

    path = tmp_path / "rgb.txt"
    path.write_bytes(b"1305031102.175304 rgb/\xff.png\n")
    with pytest.raises(InvalidInputError, match="rgb.txt' as text"):
        read_file_list(path)


@pytest.mark.parametrize(("value", "match"), [("1.3", "not rigid"), ("nan", "NaN")])
def test_a_non_rigid_or_non_finite_pose_names_its_frame(redwood_copy, value, match):
    log = redwood_copy / "trajectory.log"
    lines = log.read_text().splitlines()
    lines[11] = f"{value} 0 0 0"  # first row of frame 2's matrix
    log.write_text("\n".join(lines) + "\n")
    with pytest.raises(InvalidInputError, match=f"trajectory.log frame 2.*{match}"):
        open_sequence(redwood_copy)


def test_an_unreadable_image_is_named(redwood_copy):
    (redwood_copy / "color/00003.jpg").write_bytes(b"not a jpeg")
    seq = open_sequence(redwood_copy)
    with pytest.raises(InvalidInputError, match="00003.jpg"):
        list(seq.frames())


def test_an_8_bit_depth_image_is_refused(redwood_copy):
    cv2.imwrite(str(redwood_copy / "depth/00000.png"), np.zeros((480, 640), np.uint8))
    with pytest.raises(InvalidInputError, match="16-bit"):
        open_sequence(redwood_copy)


def test_colour_and_depth_of_different_sizes_are_refused(redwood_copy):
    cv2.imwrite(str(redwood_copy / "depth/00000.png"), np.ones((240, 320), np.uint16))
    with pytest.raises(InvalidInputError, match="640x480 but depth .* is 320x240"):
        open_sequence(redwood_copy)


def test_images_that_do_not_match_the_camera_file_are_refused(tmp_path):
    folder = make_tum(tmp_path / "custom")
    with pytest.raises(InvalidInputError, match="intrinsics"):
        open_sequence(folder, intrinsics=Intrinsics(525.0, 525.0, 319.5, 239.5, 640, 480))


def test_a_mask_without_its_json_is_refused(redwood_copy):
    (redwood_copy / "annotations/00000.json").unlink()
    with pytest.raises(InvalidInputError, match="no partner"):
        next(open_sequence(redwood_copy).frames())


def test_an_annotation_json_that_does_not_parse_is_refused(redwood_copy):
    (redwood_copy / "annotations/00000.json").write_text("{objects: ")
    with pytest.raises(InvalidInputError, match="not valid JSON"):
        next(open_sequence(redwood_copy).frames())


def test_an_annotation_naming_an_unknown_group_member_is_refused(redwood_copy):
    path = redwood_copy / "annotations/00000.json"
    labels = json.loads(path.read_text())
    labels["groups"][0]["members"] = [1, 42]
    path.write_text(json.dumps(labels))
    with pytest.raises(InvalidInputError, match=r"00000.json.*\[42\]"):
        next(open_sequence(redwood_copy).frames())


def test_an_annotation_mask_of_the_wrong_size_is_refused(redwood_copy):
    cv2.imwrite(str(redwood_copy / "annotations/00000.png"), np.zeros((10, 10), np.uint8))
    with pytest.raises(InvalidInputError, match="10x10 but the frame is 640x480"):
        next(open_sequence(redwood_copy).frames())


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        (dict(depth_scale=0.0), "depth_scale"),
        (dict(stride=0), "stride"),
        (dict(max_frames=0), "max_frames"),
        (dict(up_axis="up"), "up axis"),
    ],
)
def test_bad_arguments_are_refused_by_name(kwargs, match):
    with pytest.raises(InvalidInputError, match=match):
        open_sequence(BUNDLED, **kwargs)


def test_a_tum_folder_whose_times_never_meet_is_refused(tmp_path):
    folder = make_tum(tmp_path / "custom")
    (folder / "groundtruth.txt").write_text("50.0 0 0 0 0 0 0 1\n")
    with pytest.raises(InvalidInputError, match="within 0.02 s"):
        open_sequence(folder)


def test_a_zero_quaternion_names_its_groundtruth_line(tmp_path):
    folder = make_tum(tmp_path / "custom")
    (folder / "groundtruth.txt").write_text("# header\n10.0 0 0 0 0 0 0 0\n")
    with pytest.raises(InvalidInputError, match="groundtruth.txt line 2.*non-zero"):
        open_sequence(folder)


def test_a_camera_json_that_declares_a_z_up_world_is_read_as_z_up(tmp_path):
    from glmap_tools.ingest.cli import bundled_folder

    folder = tmp_path / "tour"
    shutil.copytree(bundled_folder(), folder)
    camera = folder / "camera_primesense.json"
    data = json.loads(camera.read_text())
    camera.write_text(json.dumps(data | {"up_axis": "z"}))
    assert open_sequence(folder).up_axis == "z"
    assert open_sequence(bundled_folder()).up_axis == "y"
