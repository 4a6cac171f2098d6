"""The model-free segmenter on ray-cast scenes with known objects, and segment labelling."""

from __future__ import annotations

import numpy as np
import pytest

from glmap_tools import synthetic as sy
from glmap_tools.errors import InvalidInputError, UnknownIdError
from glmap_tools.perception.geometric import (
    GeometricConfig,
    grid_components,
    grid_components_reference,
    segment_frame,
)
from glmap_tools.perception.labelling import (
    SegmentGroup,
    SegmentLabel,
    best_iou,
    oracle_semantics,
    semantics_from_labels,
)

WALL = sy.Box((-3.0, 3.0, 0.0), (3.0, 3.1, 2.5), (0.9, 0.9, 0.85), 0)
BOX_ON_FLOOR = sy.Box((-1.6, 0.8, 0.0), (-1.1, 1.3, 0.45), (0.2, 0.5, 0.8), 3)
SCENE = sy.floor() + [WALL, BOX_ON_FLOOR] + sy.chair(-0.3, 0.6, object_id=1) + sy.table(1.4, 1.2, 2)
EYES = [(0.0, -2.0, 1.5), (-1.5, -1.5, 1.6)]


def _composition(segment_mask: np.ndarray, ids: np.ndarray) -> dict[int, int]:
    values, counts = np.unique(ids[segment_mask], return_counts=True)
    return dict(zip(values.tolist(), counts.tolist(), strict=True))


@pytest.mark.parametrize("eye", EYES)
def test_each_object_of_a_raycast_room_is_one_segment_and_floor_and_wall_are_none(eye):
    frame, ids = sy.view(SCENE, eye, (0.0, 1.0, 0.4))
    segments = segment_frame(frame)
    owners = []
    for seg in segments:
        parts = _composition(seg.mask, ids)
        owner = max(parts, key=parts.get)
        assert owner != 0, f"segment {seg.id} lies on the floor or wall: {parts}"
        assert parts[owner] >= 0.98 * seg.pixels, f"segment {seg.id} straddles objects: {parts}"
        owners.append(owner)
    assert sorted(owners) == [1, 2, 3]
    for seg, owner in zip(segments, owners, strict=True):  # table legs 2 px wide may go
        assert seg.pixels >= 0.55 * (ids == owner).sum()


def test_segments_carry_world_bounds_and_a_colour_crop_of_their_object():
    frame, ids = sy.view(SCENE, EYES[0], (0.0, 1.0, 0.4))
    segments = segment_frame(frame)
    box = next(s for s in segments if _composition(s.mask, ids).get(3, 0) > s.pixels / 2)
    np.testing.assert_allclose(box.lo[2], 0.0, atol=0.06)  # the floor band goes with the floor
    np.testing.assert_allclose(box.hi[2], 0.45, atol=0.03)
    assert BOX_ON_FLOOR.lo[0] - 0.03 <= box.centroid[0] <= BOX_ON_FLOOR.hi[0] + 0.03
    assert box.crop.dtype == np.uint8 and box.crop.ndim == 3
    assert max(box.crop.shape[:2]) <= GeometricConfig().crop_size
    blue = np.array([0.2, 0.5, 0.8]) * 255
    r0, c0, r1, c1 = box.box
    inside = frame.rgb[r0:r1, c0:c1][box.mask[r0:r1, c0:c1]]
    np.testing.assert_allclose(inside.mean(axis=0), blue, atol=2)


def test_an_object_standing_on_a_table_is_cut_from_the_table_at_the_concave_crease():
    cube = sy.Box((1.2, 1.0, 0.75), (1.5, 1.3, 1.05), (0.1, 0.7, 0.2), 4)
    frame, ids = sy.view(
        sy.floor() + sy.table(1.4, 1.2, 2) + [cube], (1.4, -0.6, 1.7), (1.4, 1.2, 0.7)
    )
    segments = segment_frame(frame)
    assert max(best_iou(ids == 4, segments), 0) >= 0.8
    assert best_iou(ids == 2, segments) >= 0.8


def test_objects_smaller_than_the_pixel_threshold_are_dropped():
    pebble = sy.Box((0.0, 0.5, 0.0), (0.05, 0.55, 0.05), (0.9, 0.1, 0.1), 7)
    frame, ids = sy.view(sy.floor() + [pebble], (0.0, -2.0, 1.5), (0.0, 1.0, 0.4))
    assert (ids == 7).sum() > 0
    assert segment_frame(frame) == []


def test_fast_components_equal_the_flood_fill_reference():
    rng = np.random.default_rng(3)
    for h, w in [(7, 9), (16, 12), (30, 41)]:
        keep = rng.random((h, w)) < 0.7
        idx = np.arange(h * w).reshape(h, w)
        pairs = [(idx[:, :-1], idx[:, 1:]), (idx[:-1], idx[1:])]
        a = np.concatenate([p[0].ravel() for p in pairs])
        b = np.concatenate([p[1].ravel() for p in pairs])
        ok = keep.ravel()[a] & keep.ravel()[b] & (rng.random(len(a)) < 0.6)
        np.testing.assert_array_equal(
            grid_components(keep, a[ok], b[ok]), grid_components_reference(keep, a[ok], b[ok])
        )


@pytest.fixture(scope="module")
def labelled_view():
    frame, ids = sy.view(SCENE, EYES[0], (0.0, 1.0, 0.4))
    return frame, ids, segment_frame(frame)


def test_labels_become_semantics_and_ignore_leaves_a_segment_out(labelled_view):
    segments = labelled_view[2]
    first, second, third = (s.id for s in segments[:3])
    semantics = semantics_from_labels(
        segments,
        [
            SegmentLabel((first, second), "furniture", "two pieces named as one"),
            SegmentLabel((third,), "Ignore"),
        ],
        [SegmentGroup((second,), "a corner")],
    )
    assert [o.local_id for o in semantics.objects] == [first]
    assert semantics.objects[0].mask.sum() == segments[0].pixels + segments[1].pixels
    assert semantics.groups[0].members == (first,)


@pytest.mark.parametrize(
    ("labels", "error", "words"),
    [
        ([SegmentLabel((99,), "chair")], UnknownIdError, "segment 99"),
        ([SegmentLabel((1,), "chair"), SegmentLabel((1,), "seat")], InvalidInputError, "twice"),
        ([SegmentLabel((1,), "  ")], InvalidInputError, "empty label"),
        ([SegmentLabel((), "chair")], InvalidInputError, "no segment"),
    ],
)
def test_bad_labels_name_the_problem(labelled_view, labels, error, words):
    with pytest.raises(error, match=words):
        semantics_from_labels(labelled_view[2], labels)


def test_a_group_member_must_be_a_labelled_segment(labelled_view):
    segments = labelled_view[2]
    with pytest.raises(InvalidInputError, match="not a labelled object"):
        semantics_from_labels(
            segments, [SegmentLabel((1,), "chair")], [SegmentGroup((1, 2), "a corner")]
        )


def test_the_ground_truth_oracle_names_each_segment_after_its_object(labelled_view):
    frame, ids, segments = labelled_view
    truth = sy.semantics(
        ids, {1: ("chair", ""), 2: ("table", ""), 3: ("box", "")}, [(1, "g", (1, 2))]
    )
    semantics, labels = oracle_semantics(segments, truth)
    assert sorted(o.label for o in semantics.objects) == ["box", "chair", "table"]
    assert len(semantics.groups) == 1 and len(semantics.groups[0].members) == 2


@pytest.mark.parametrize("size", [(1, 1), (3, 5), (60, 80)])
@pytest.mark.parametrize("fill", [0.0, np.nan, np.inf, -1.0])
def test_a_frame_without_usable_depth_has_no_segments(size, fill):
    from glmap_tools.geometry import Intrinsics, Pose
    from glmap_tools.geometry.frame import RGBDFrame

    h, w = size
    frame = RGBDFrame(
        np.zeros((h, w, 3), np.uint8),
        np.full((h, w), fill, np.float32),
        Intrinsics.from_fov(w, h, 70.0),
        Pose.looking_at(np.array([0.0, 0.0, 1.2]), np.array([1.0, 0.0, 1.0])),
    )
    assert segment_frame(frame) == []
