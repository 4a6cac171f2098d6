"""Fusion keeps one instance unit per object and one region unit per region (map/dedup.py)."""

import numpy as np
import pytest

from glmap_tools import synthetic as scenes
from glmap_tools.errors import UnknownIdError
from glmap_tools.language.embed import HashingEmbedder
from glmap_tools.map import GLMap, InstanceUnit, MapConfig
from glmap_tools.perception import FrameSemantics, GroupObservation, ObjectObservation

TABLE = ("table", "a brown wooden dining table")
CHAIR = ("chair", "a wooden chair with a red cushion")
LAMP = ("lamp", "a table lamp with a white shade")
FRONT = ((0.0, -2.5, 1.4), (0.0, 0.0, 0.4))


@pytest.fixture
def config():
    return MapConfig(floor_z=0.0)


@pytest.fixture
def glmap(config):
    return GLMap(config, embedder=HashingEmbedder())


def _observe(glmap, frame, masks, groups=()):
    """Integrate `frame` with one observation per (local id, (label, text), mask)."""
    objects = [ObjectObservation(i, label, text, mask) for i, (label, text), mask in masks]
    return glmap.integrate(frame, FrameSemantics(objects, list(groups)))


def _column_band(mask, lo, hi):
    """`mask` restricted to the fraction [lo, hi) of the columns it spans."""
    cols = np.flatnonzero(mask.any(axis=0))
    c0, c1 = cols[0] + lo * (cols[-1] + 1 - cols[0]), cols[0] + hi * (cols[-1] + 1 - cols[0])
    band = np.zeros_like(mask)
    band[:, int(c0) : int(c1)] = True
    return mask & band


def _assert_consistent(glmap):
    """Grid, reverse index and regions name only units that exist."""
    ids = set(glmap.instances) | set(glmap.regions)
    assert {u for cell_ids in glmap.grid.snapshot().values() for u in cell_ids} <= ids
    for region in glmap.regions.values():
        assert set(region.instance_ids) <= set(glmap.instances)
        for iid in region.instance_ids:
            assert region.id in glmap.regions_of_instance(iid)


def test_a_sliver_overlapping_a_big_unit_with_the_same_label_is_fused_into_it(config):
    boxes = scenes.floor() + scenes.table(0.0, 0.0, 1)
    frame, ids = scenes.view(boxes, *FRONT)
    scratch = GLMap(config, embedder=HashingEmbedder())
    _observe(scratch, frame, [(1, TABLE, ids == 1)])
    _observe(scratch, frame, [(1, ("table", "a sliver"), _column_band(ids == 1, 0.9, 1.0))])
    big, sliver = scratch.instances[1], scratch.instances[2]  # the sliver's text kept it apart
    sliver = InstanceUnit(2, "Table ", big.text, big.embedding, sliver.gaussians, 1, 1, 1)
    glmap = GLMap.from_units({1: big, 2: sliver}, {}, 3, config, HashingEmbedder())

    report = _observe(glmap, frame, [(1, TABLE, ids == 1)])

    assert list(glmap.instances) == [1] and report.fused == {2: 1}
    assert glmap.instances[1].observations == big.observations + 2
    assert not glmap.grid.cells_of_unit(2) and glmap.unit_details(1).num_gaussians > 0
    _assert_consistent(glmap)


def test_two_parts_of_one_table_that_touch_become_one_unit_and_the_file_agrees(tmp_path, config):
    boxes = scenes.floor() + scenes.table(0.0, 0.0, 1)
    frame, ids = scenes.view(boxes, *FRONT, 640, 480)
    left, middle, right = (_column_band(ids == 1, a, a + 1 / 3) for a in (0, 1 / 3, 2 / 3))
    glmap = GLMap.open(tmp_path / "map.glmap", config, embedder=HashingEmbedder())
    area = "a dining area"
    _observe(glmap, frame, [(1, TABLE, left)], [GroupObservation(1, area, (1,))])
    _observe(glmap, frame, [(1, TABLE, right)], [GroupObservation(1, area, (1,))])
    assert sorted(glmap.instances) == [1, 3]  # the two ends do not touch: two units

    report = _observe(glmap, frame, [(1, TABLE, middle)])  # joins the ends

    assert list(glmap.instances) == [1] and report.fused == {3: 1, 4: 2}
    assert list(glmap.regions) == [2] and glmap.regions[2].instance_ids == (1,)
    with pytest.raises(UnknownIdError, match="fused into unit 1"):
        glmap.unit(3)
    xs = glmap.instances[1].gaussians.means[:, 0]
    assert xs.min() < -0.5 and xs.max() > 0.5  # the whole table top
    _assert_consistent(glmap)
    before = (glmap.grid.snapshot(), glmap.regions[2].text, len(glmap.instances[1].gaussians))
    glmap.close()
    reopened = GLMap.open(tmp_path / "map.glmap", embedder=HashingEmbedder())
    assert list(reopened.instances) == [1] and list(reopened.regions) == [2]
    after = (
        reopened.grid.snapshot(),
        reopened.regions[2].text,
        len(reopened.instances[1].gaussians),
    )
    assert after == before
    reopened.close()


def test_two_chairs_9_cm_apart_seen_one_at_a_time_stay_two(glmap):
    boxes = scenes.floor() + scenes.chair(-0.27, 0.0, object_id=1)
    boxes += scenes.chair(0.27, 0.0, object_id=2)  # 9 cm gap between the seats
    for eye in [(0.0, -2.5, 1.3), (0.6, -2.3, 1.3), (-0.6, -2.3, 1.3)]:
        frame, ids = scenes.view(boxes, eye, (0.0, 0.0, 0.3), 640, 480)
        for chair in (1, 2):
            _observe(glmap, frame, [(1, CHAIR, ids == chair)])
    assert len(glmap.instances) == 2


def test_two_chairs_a_metre_apart_seen_one_at_a_time_stay_two(glmap):
    boxes = scenes.floor() + scenes.chair(-0.5, 0.0, object_id=1)
    boxes += scenes.chair(0.5, 0.0, object_id=2)
    for eye in [(0.0, -2.5, 1.3), (0.5, -2.3, 1.3), (-0.5, -2.3, 1.3)]:
        frame, ids = scenes.view(boxes, eye, (0.0, 0.0, 0.3))
        for chair in (1, 2):  # never both in one frame: perception does not tell them apart
            _observe(glmap, frame, [(1, CHAIR, ids == chair)])
    assert len(glmap.instances) == 2
    xs = sorted(u.centroid[0] for u in glmap.instances.values())
    np.testing.assert_allclose(xs, [-0.5, 0.5], atol=0.1)


def test_a_lamp_standing_on_a_table_stays_a_unit_of_its_own(glmap):
    lamp = scenes.Box((-0.1, -0.1, 0.75), (0.1, 0.1, 1.1), (0.9, 0.9, 0.8), 2)
    boxes = scenes.floor() + scenes.table(0.0, 0.0, 1) + [lamp]
    frame, ids = scenes.view(boxes, *FRONT)
    # Similar texts: only the labels tell the two apart.
    texts = {1: TABLE, 2: ("lamp", TABLE[1] + " lamp")}
    assert float(np.dot(*glmap.embedder.embed([texts[1][1], texts[2][1]]))) >= glmap.tau_s
    for _ in range(2):
        for obj in (1, 2):
            _observe(glmap, frame, [(1, texts[obj], ids == obj)])
    assert sorted(u.label for u in glmap.instances.values()) == ["lamp", "table"]


def test_regions_with_the_same_description_and_a_shared_member_become_one(glmap):
    boxes = scenes.floor() + scenes.table(0.0, 0.0, 1) + scenes.chair(0.0, -0.8, object_id=2)
    frame, ids = scenes.view(boxes, (0.3, -3.0, 1.4), (0.0, 0.0, 0.4))
    objects = [(1, TABLE, ids == 1), (2, CHAIR, ids == 2)]
    area = "a dining area"
    _observe(glmap, frame, objects, [GroupObservation(1, area, (1,))])
    _observe(glmap, frame, objects, [GroupObservation(1, area, (2,))])  # no shared member yet
    assert len(glmap.regions) == 2
    report = _observe(glmap, frame, objects, [GroupObservation(1, area, (1, 2))])
    (region,) = glmap.regions.values()
    assert region.id == 3 and region.instance_ids == (1, 2) and report.fused == {4: 3}
    _assert_consistent(glmap)


def test_far_apart_regions_with_the_same_description_stay_two(glmap):
    boxes = scenes.floor() + scenes.table(-2.0, 0.0, 1) + scenes.table(2.0, 0.0, 2)
    frame, ids = scenes.view(boxes, (0.0, -4.0, 1.5), (0.0, 0.0, 0.4))
    objects = [
        (1, ("table", "a wooden table"), ids == 1),
        (2, ("table", "a wooden table"), ids == 2),
    ]
    for groups in ([(1, (1,)), (2, (2,))], [(1, (1,))], [(1, (2,))]):
        _observe(
            glmap, frame, objects, [GroupObservation(g, "a dining area", m) for g, m in groups]
        )
    assert len(glmap.instances) == 2 and len(glmap.regions) == 2
    assert sorted(r.instance_ids for r in glmap.regions.values()) == [(1,), (2,)]
