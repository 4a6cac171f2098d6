"""Incremental fusion on ray-cast synthetic scenes with known poses."""

import numpy as np
import pytest

from glmap_tools import synthetic as scenes
from glmap_tools.errors import InvalidInputError
from glmap_tools.language.embed import HashingEmbedder
from glmap_tools.map import FREE, OBSTACLE, UNKNOWN, GLMap, MapConfig
from glmap_tools.perception import FrameSemantics, GroupObservation, ObjectObservation

CHAIR = ("chair", "a wooden chair with a red cushion")
CHAIR_AGAIN = ("chair", "wooden chair with red cushion")


@pytest.fixture
def glmap():
    return GLMap(MapConfig(floor_z=0.0), embedder=HashingEmbedder())


def test_a_chair_seen_from_two_sides_becomes_one_instance(glmap):
    boxes = scenes.floor() + scenes.chair(0.0, 0.0)
    for angle, text in ((-60, CHAIR), (150, CHAIR_AGAIN)):
        frame, ids = scenes.view(boxes, scenes.orbit_eye((0, 0), 2.0, angle), (0, 0, 0.3))
        report = glmap.integrate(frame, scenes.semantics(ids, {1: text}))
    assert len(glmap.instances) == 1
    assert report.instances_merged and report.instances_merged[0].global_id == 1
    unit = glmap.instances[1]
    assert unit.observations == 2
    assert "red cushion" in unit.text and unit.text.count("|") == 1
    np.testing.assert_allclose(unit.centroid[:2], [0.0, 0.0], atol=0.1)


def test_two_identical_chairs_two_metres_apart_stay_two(glmap):
    boxes = (
        scenes.floor() + scenes.chair(-1.0, 0.0, object_id=1) + scenes.chair(1.0, 0.0, object_id=2)
    )
    frame, ids = scenes.view(boxes, (0.0, -3.5, 1.3), (0.0, 0.0, 0.3))
    glmap.integrate(frame, scenes.semantics(ids, {1: CHAIR, 2: CHAIR}))
    frame, ids = scenes.view(boxes, (0.5, -3.0, 1.3), (0.0, 0.0, 0.3))
    glmap.integrate(frame, scenes.semantics(ids, {1: CHAIR, 2: CHAIR}))
    assert len(glmap.instances) == 2
    xs = sorted(u.centroid[0] for u in glmap.instances.values())
    np.testing.assert_allclose(xs, [-1.0, 1.0], atol=0.15)


def test_different_descriptions_of_overlapping_geometry_stay_separate(glmap):
    boxes = scenes.floor() + scenes.chair(0.0, 0.0)
    frame, ids = scenes.view(boxes, (0.0, -2.5, 1.3), (0.0, 0.0, 0.3))
    glmap.integrate(frame, scenes.semantics(ids, {1: CHAIR}))
    glmap.integrate(frame, scenes.semantics(ids, {1: ("refrigerator", "a tall white fridge")}))
    assert len(glmap.instances) == 2


def test_regions_merge_through_a_shared_instance(glmap):
    boxes = scenes.floor() + scenes.table(0.0, 0.0, 1) + scenes.chair(0.0, -0.8, object_id=2)
    texts = {1: ("table", "a brown wooden dining table"), 2: CHAIR}
    region = "dining area with a table and chairs for eating meals"
    frame, ids = scenes.view(boxes, (0.3, -3.0, 1.4), (0.0, 0.0, 0.4))
    r1 = glmap.integrate(frame, scenes.semantics(ids, texts, [(1, region, (1, 2))]))
    frame, ids = scenes.view(boxes, (-2.5, -1.5, 1.4), (0.0, 0.0, 0.4))
    r2 = glmap.integrate(
        frame, scenes.semantics(ids, texts, [(7, "dining area: table and chairs for meals", (1,))])
    )
    assert len(r1.regions_added) == 1 and len(r2.regions_merged) == 1
    assert len(glmap.regions) == 1
    region_unit = next(iter(glmap.regions.values()))
    assert set(region_unit.instance_ids) == {r1.local_to_global[1], r1.local_to_global[2]}
    # The region is indexed on the grid wherever its instances are.
    assert region_unit.id in {u.id for u in glmap.units_at(0.0, 0.0, 0.3)}


def test_a_similar_region_without_a_shared_instance_is_a_new_region(glmap):
    boxes = scenes.floor() + scenes.table(-2.0, 0.0, 1) + scenes.table(2.0, 0.0, 2)
    texts = {1: ("table", "a wooden table"), 2: ("table", "a wooden table")}
    frame, ids = scenes.view(boxes, (0.0, -4.0, 1.5), (0.0, 0.0, 0.4))
    glmap.integrate(
        frame,
        scenes.semantics(ids, texts, [(1, "dining area", (1,)), (2, "dining area", (2,))]),
    )
    assert len(glmap.regions) == 2


def test_queries_find_units_by_text_and_by_position(glmap):
    boxes = scenes.floor() + scenes.table(0.0, 0.0, 1) + scenes.chair(1.5, 0.0, object_id=2)
    frame, ids = scenes.view(boxes, (0.5, -3.0, 1.4), (0.5, 0.0, 0.4), 640, 480)
    report = glmap.integrate(
        frame, scenes.semantics(ids, {1: ("table", "a brown wooden dining table"), 2: CHAIR})
    )
    chair_id = report.local_to_global[2]
    hits = glmap.find_instances("red chair", k=2)
    assert hits[0].id == chair_id and hits[0].score >= hits[1].score
    near = glmap.units_at(1.5, 0.0, radius=0.3)
    assert near[0].id == chair_id and near[0].distance == 0.0
    details = glmap.unit_details(chair_id)
    assert details.observations == 1 and details.label == "chair"
    lo, hi = np.array(details.bounds)
    assert np.all(lo <= details.centroid) and np.all(details.centroid <= hi)


def test_occupancy_marks_furniture_as_obstacles_and_the_floor_in_between_as_free(glmap):
    boxes = scenes.floor() + scenes.table(0.0, 0.0, 1)
    frame, ids = scenes.view(boxes, (0.0, -3.0, 1.4), (0.0, 0.0, 0.4))
    glmap.integrate(frame, FrameSemantics())
    dense = glmap.occupancy.to_dense()
    rows, cols = np.nonzero(dense.state == OBSTACLE)
    xy = np.array([dense.index_to_world(r, c) for r, c in zip(rows, cols, strict=True)])
    # Every obstacle cell lies on the table (0.6 x 0.4 half-extents, one cell of slack) ...
    assert np.all(np.abs(xy[:, 0]) <= 0.65) and np.all(np.abs(xy[:, 1]) <= 0.45)
    # ... and the table's edge facing the camera is an obstacle along its whole width.
    front = xy[xy[:, 1] < -0.3]
    assert len(np.unique(np.round(front[:, 0], 3))) >= 20
    assert glmap.occupancy.state_at(0.0, -1.5) == FREE
    assert glmap.occupancy.state_at(0.0, 5.5) == UNKNOWN  # behind the camera's view


def _frame_and_semantics():
    boxes = scenes.floor() + scenes.chair(0.0, 0.0)
    frame, ids = scenes.view(boxes, (0.0, -2.5, 1.3), (0.0, 0.0, 0.3))
    return frame, ids, scenes.semantics(ids, {1: CHAIR})


def _state(glmap):
    return (
        dict(glmap.instances),
        dict(glmap.regions),
        glmap.grid.snapshot(),
        glmap.occupancy.copy(),
        glmap.next_id,
        len(glmap.trajectory),
    )


def _assert_unchanged(glmap, before):
    inst, regs, cells, occ, next_id, frames = before
    assert glmap.instances == inst and glmap.regions == regs
    assert glmap.grid.snapshot() == cells and glmap.occupancy.equals(occ)
    assert glmap.next_id == next_id and len(glmap.trajectory) == frames


@pytest.mark.parametrize(
    ("mutate", "message"),
    [
        (
            lambda f, ids, s: (f, FrameSemantics([ObjectObservation(1, "chair", "", ids == 99)])),
            "empty",
        ),
        (
            lambda f, ids, s: (f, FrameSemantics(s.objects, [GroupObservation(1, "area", (1, 5))])),
            "unknown member ids",
        ),
        (
            lambda f, ids, s: (
                f,
                FrameSemantics([ObjectObservation(1, "chair", "", ids[:10] == 1)]),
            ),
            "mask",
        ),
        (
            lambda f, ids, s: (type(f)(f.rgb, np.zeros_like(f.depth), f.intrinsics, f.pose), s),
            "no valid pixel",
        ),
        (
            lambda f, ids, s: (
                f,
                FrameSemantics([ObjectObservation(1, "chair\ud800", "", ids == 1)]),
            ),
            "object 1's label 'chair\\\\ud800' holds a lone surrogate at character 5",
        ),
        (
            lambda f, ids, s: (
                f,
                FrameSemantics(s.objects, [GroupObservation(3, "a \udcff corner", (1,))]),
            ),
            "group 3's description .* lone surrogate",
        ),
        (
            lambda f, ids, s: (f, FrameSemantics([ObjectObservation("1", "chair", "", ids == 1)])),
            "object '1': its local_id is not an integer",
        ),
        (
            lambda f, ids, s: (f, FrameSemantics([ObjectObservation(1, "chair", None, ids == 1)])),
            "object 1: its label and description must be text",
        ),
        (
            lambda f, ids, s: (
                f,
                FrameSemantics([ObjectObservation(1, "chair", "", (ids == 1).astype(np.uint8))]),
            ),
            r"object 1: its mask is uint8 \[\(.*\)\]; give a boolean \[H, W\] array",
        ),
        (
            lambda f, ids, s: (f, FrameSemantics(s.objects, [GroupObservation(3, "area", 1.5)])),
            "group 3: its members 1.5 must be a list of object local ids",
        ),
        (
            lambda f, ids, s: (f, FrameSemantics(s.objects, [{"id": 3}])),
            "groups holds {'id': 3}, not a GroupObservation",
        ),
        (lambda f, ids, s: (f, {"objects": []}), "semantics is dict, not FrameSemantics"),
    ],
    ids=[
        "empty-mask",
        "unknown-group-member",
        "mask-shape",
        "all-invalid-depth",
        "lone-surrogate-label",
        "lone-surrogate-group",
        "text-id",
        "none-description",
        "uint8-mask",
        "float-members",
        "dict-group",
        "dict-semantics",
    ],
)
def test_bad_input_is_refused_and_changes_nothing(glmap, mutate, message):
    frame, ids, sem = _frame_and_semantics()
    glmap.integrate(frame, sem)
    before = _state(glmap)
    bad_frame, bad_sem = mutate(frame, ids, sem)
    with pytest.raises(InvalidInputError, match=message):
        glmap.integrate(bad_frame, bad_sem)
    _assert_unchanged(glmap, before)


def test_a_frame_whose_depth_misses_the_occupancy_lattice_changes_no_cell_and_no_floor():
    # valid depth only on odd rows and columns (the lattice takes the even ones), inside a
    # masked chair: the occupancy and the floor have no pixel to read
    glmap = GLMap(MapConfig(floor_z=None, occupancy_stride=2), embedder=HashingEmbedder())
    frame, ids, sem = _frame_and_semantics()
    odd = np.zeros(frame.depth.shape, dtype=bool)
    odd[1::2, 1::2] = True
    depth = np.where(odd & (ids == 1), frame.depth, 0.0).astype(np.float32)
    sparse = type(frame)(frame.rgb, depth, frame.intrinsics, frame.pose)
    report = glmap.integrate(sparse, sem)
    assert glmap.floor_z is None and len(glmap.trajectory) == 1
    assert glmap.occupancy.chunks == {}
    assert report.instances_added  # the chair's pixels still make an instance
    glmap.integrate(frame, sem)  # a later full frame sets the floor
    assert glmap.floor_z is not None


def test_an_unknown_unit_id_suggests_the_closest_one(glmap):
    frame, _, sem = _frame_and_semantics()
    glmap.integrate(frame, sem)
    with pytest.raises(KeyError, match="Closest id: 1|Did you mean '1'"):
        glmap.unit(7)


def test_a_chair_seen_again_under_brighter_exposure_still_merges(glmap):
    boxes = scenes.floor() + scenes.chair(0.0, 0.0)
    frame, ids = scenes.view(boxes, (0.0, -2.5, 1.3), (0.0, 0.0, 0.3), 640, 480)
    glmap.integrate(frame, scenes.semantics(ids, {1: CHAIR}))
    frame, ids = scenes.view(boxes, (0.4, -2.4, 1.3), (0.0, 0.0, 0.3), 640, 480)
    brighter = np.clip(frame.rgb.astype(np.int32) * 13 // 10 + 25, 0, 255).astype(np.uint8)
    frame = type(frame)(brighter, frame.depth, frame.intrinsics, frame.pose)
    report = glmap.integrate(frame, scenes.semantics(ids, {1: CHAIR_AGAIN}))
    assert len(glmap.instances) == 1 and report.instances_merged


def test_two_identical_chairs_side_by_side_stay_two(glmap):
    boxes = scenes.floor() + scenes.chair(-0.27, 0.0, object_id=1)
    boxes += scenes.chair(0.27, 0.0, object_id=2)  # 9 cm gap between the seats
    for eye in [(0.0, -2.5, 1.3), (0.6, -2.3, 1.3)]:
        frame, ids = scenes.view(boxes, eye, (0.0, 0.0, 0.3), 640, 480)
        glmap.integrate(frame, scenes.semantics(ids, {1: CHAIR, 2: CHAIR}))
    assert len(glmap.instances) == 2


def _three_objects():
    boxes = (
        scenes.floor()
        + scenes.table(0.0, 0.0, 1)
        + scenes.chair(0.0, -0.8, object_id=2)
        + scenes.chair(1.3, -0.2, object_id=3)
    )
    texts = {1: ("table", "a brown wooden dining table"), 2: CHAIR, 3: ("chair", "a blue stool")}
    frame, ids = scenes.view(boxes, (0.3, -3.2, 1.6), (0.3, 0.0, 0.4))
    return frame, ids, texts


def _member_sets(glmap):
    return [r.instance_ids for r in glmap.regions.values()]


def test_two_groups_with_the_same_members_in_one_frame_become_one_region(glmap):
    frame, ids, texts = _three_objects()
    groups = [(1, "a dining area", (1, 2)), (2, "a dining area", (1, 2))]
    report = glmap.integrate(frame, scenes.semantics(ids, texts, groups))
    assert len(glmap.regions) == 1 and len(report.regions_merged) == 1
    (region,) = glmap.regions.values()
    assert region.text == "a dining area" and region.observations == 1


def test_a_region_seen_again_in_other_words_with_the_same_members_merges(glmap):
    frame, ids, texts = _three_objects()
    glmap.integrate(frame, scenes.semantics(ids, texts, [(1, "a dining area", (1, 2))]))
    sem = scenes.semantics(ids, texts, [(1, "zebra crossing outside", (1, 2))])
    assert (
        float(
            glmap.embedder.embed(["zebra crossing outside"])[0]
            @ glmap.embedder.embed(["a dining area"])[0]
        )
        < glmap.tau_s
    )  # by text alone it would be a new region
    glmap.integrate(frame, sem)
    assert _member_sets(glmap) == [(1, 2)]
    assert glmap.regions[next(iter(glmap.regions))].observations == 2


def test_a_merge_that_would_copy_another_regions_members_joins_that_region(glmap):
    frame, ids, texts = _three_objects()
    groups = [(1, "a dining area by the window", (1, 2)), (2, "the whole room", (1, 2, 3))]
    glmap.integrate(frame, scenes.semantics(ids, texts, groups))
    assert sorted(_member_sets(glmap)) == [(1, 2), (1, 2, 3)]
    # Similar to the first region's text and sharing table 1 with it: the paper's rule
    # would grow it to (1, 2, 3), the second region's member set.
    sem = scenes.semantics(ids, texts, [(1, "a dining area by the window", (1, 3))])
    report = glmap.integrate(frame, sem)
    # The second region now holds the first one's description and shares its members:
    # fusion makes the two one region under the older id.
    assert _member_sets(glmap) == [(1, 2, 3)] and len(report.fused) == 1
    (merged,) = report.regions_merged
    assert glmap.regions[merged.global_id].instance_ids == (1, 2, 3)
    assert "the whole room" in glmap.regions[merged.global_id].text
