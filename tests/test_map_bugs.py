"""Behaviour the planner and fusion stand on, pinned so that plausible slips fail a test.

Each test here was checked to fail under one deliberate bug: a grid cell off by one for
negative coordinates; a region merge without the shared-instance check (regions seen in
different frames); instance matching by the paper's "some mergeable Gaussian pair" clause
alone; the 300-word text-merger trigger skipped or fired early at map level.
"""

import numpy as np
import pytest

from glmap_tools import synthetic as scenes
from glmap_tools.language.embed import HashingEmbedder
from glmap_tools.language.text_merger import DELIMITER
from glmap_tools.map import FREE, OBSTACLE, GLMap, MapConfig
from glmap_tools.map.grid import IndexGrid, cells_of_points, gaussian_cells

CHAIR = ("chair", "a wooden chair with a red cushion")


@pytest.fixture
def glmap():
    return GLMap(MapConfig(floor_z=0.0), embedder=HashingEmbedder())


@pytest.mark.parametrize("cell_size", [0.05, 0.1, 0.37])
def test_grid_cells_equal_the_floor_of_points_in_all_four_quadrants(cell_size):
    rng = np.random.default_rng(7)
    xy = rng.uniform(-20.0, 20.0, size=(5000, 2))
    xy[:8] = [[-0.01, -0.01], [0.01, -0.01], [-0.01, 0.01], [0.0, 0.0]] * 2
    expected = np.unique(np.floor(xy / cell_size).astype(np.int64), axis=0)
    got = cells_of_points(xy, cell_size)
    np.testing.assert_array_equal(got[np.lexsort((got[:, 1], got[:, 0]))], expected)
    quadrants = {(bool(i >= 0), bool(j >= 0)) for i, j in got}
    assert len(quadrants) == 4


def test_a_gaussian_footprint_covers_exactly_its_cells_in_every_quadrant():
    s = 0.05
    for sx, sy in ((1, 1), (-1, 1), (1, -1), (-1, -1)):
        mean = np.array([[sx * 1.02, sy * 2.03, 0.5]])
        cov = np.diag([0.03**2, 0.03**2, 0.01])[None]
        cells = {tuple(c) for c in gaussian_cells(mean, cov, s).tolist()}
        lo = np.floor((mean[0, :2] - 0.03) / s).astype(int)
        hi = np.floor((mean[0, :2] + 0.03) / s).astype(int)
        expected = {(i, j) for i in range(lo[0], hi[0] + 1) for j in range(lo[1], hi[1] + 1)}
        assert cells == expected


def test_index_grid_cells_agree_with_cell_of_and_units_near():
    grid = IndexGrid(0.05)
    rng = np.random.default_rng(3)
    xy = rng.uniform(-3.0, 3.0, size=(200, 2))
    for uid, (x, y) in enumerate(xy, start=1):
        grid.set_unit(uid, cells_of_points(np.array([[x, y]]), grid.cell_size))
        assert grid.cells_of_unit(uid) == {grid.cell_of(x, y)}
        assert (uid, 0.0) in grid.units_near(x, y, 0.01)


def test_units_at_and_occupancy_agree_on_a_table_at_negative_coordinates(glmap):
    boxes = scenes.floor() + scenes.table(-1.5, -1.2, 1)
    frame, ids = scenes.view(boxes, (-1.5, -4.0, 1.4), (-1.5, -1.2, 0.4), 640, 480)
    glmap.integrate(frame, scenes.semantics(ids, {1: ("table", "a brown wooden table")}))
    (uid,) = glmap.instances
    dense = glmap.occupancy.to_dense()
    rows, cols = np.nonzero(dense.state == OBSTACLE)
    xy = np.array([dense.index_to_world(r, c) for r, c in zip(rows, cols, strict=True)])
    # Obstacle cells whose centres lie a cell inside the table (0.6 x 0.4 half-extents) ...
    on_table = (np.abs(xy[:, 0] + 1.5) < 0.55) & (np.abs(xy[:, 1] + 1.2) < 0.35)
    assert on_table.sum() >= 20
    for x, y in xy[on_table]:
        # ... are cells of the table in the index grid, and units_at finds it there.
        assert uid in glmap.grid.ids_at(glmap.grid.cell_of(x, y)), (x, y)
        assert [u.id for u in glmap.units_at(x, y, radius=0.0)] == [uid]
    # Against the true geometry: the table spans x in [-2.1, -0.9] at y = -1.2.
    for x in (-2.075, -0.925):
        assert [u.id for u in glmap.units_at(x, -1.2, radius=0.0)] == [uid]
    for x in (-2.125, -0.875):
        assert glmap.units_at(x, -1.2, radius=0.0) == []
        assert glmap.occupancy.state_at(x, -1.2) != OBSTACLE
    assert glmap.occupancy.state_at(-1.5, -2.5) == FREE
    assert glmap.units_at(-1.5, -2.5, radius=0.1) == []


def test_similar_regions_seen_in_different_frames_without_a_shared_instance_stay_two(glmap):
    boxes = scenes.floor() + scenes.table(-2.5, 0.0, 1) + scenes.table(2.5, 0.0, 2)
    texts = {1: ("table", "a wooden table"), 2: ("table", "a wooden table")}
    frame, ids = scenes.view(boxes, (-2.5, -2.5, 1.4), (-2.5, 0.0, 0.4))
    assert not (ids == 2).any()
    glmap.integrate(frame, scenes.semantics(ids, texts, [(1, "dining area", (1,))]))
    frame, ids = scenes.view(boxes, (2.5, -2.5, 1.4), (2.5, 0.0, 0.4))
    assert not (ids == 1).any()
    report = glmap.integrate(frame, scenes.semantics(ids, texts, [(1, "dining area", (2,))]))
    assert len(glmap.instances) == 2
    assert len(glmap.regions) == 2 and len(report.regions_added) == 1
    members = sorted(r.instance_ids for r in glmap.regions.values())
    assert members == [(1,), (3,)]


def test_a_darker_re_observation_of_the_same_chair_merges_by_overlap(glmap):
    boxes = scenes.floor() + scenes.chair(0.0, 0.0)
    frame, ids = scenes.view(boxes, (0.0, -2.5, 1.3), (0.0, 0.0, 0.3))
    glmap.integrate(frame, scenes.semantics(ids, {1: CHAIR}))
    darker = type(frame)(
        (frame.rgb * 0.45).astype(np.uint8), frame.depth, frame.intrinsics, frame.pose
    )
    report = glmap.integrate(darker, scenes.semantics(ids, {1: CHAIR}))
    assert len(glmap.instances) == 1 and len(report.instances_merged) == 1


def _descriptions(n: int) -> list[str]:
    """n chair descriptions of 30 words that share most words (similar by text)."""
    base = "a wooden chair with a red cushion and four legs standing near the table"
    return [f"{base} " + " ".join(f"detail{k}x{w}" for w in range(16)) for k in range(n)]


def test_text_buffers_are_concatenated_up_to_300_words_and_merged_past_them(glmap):
    boxes = scenes.floor() + scenes.chair(0.0, 0.0)
    frame, ids = scenes.view(boxes, (0.0, -2.5, 1.3), (0.0, 0.0, 0.3))
    texts = _descriptions(12)
    word_counts = []
    for k, text in enumerate(texts):
        glmap.integrate(frame, scenes.semantics(ids, {1: ("chair", text)}))
        assert len(glmap.instances) == 1
        unit = next(iter(glmap.instances.values()))
        word_counts.append(len(unit.text.split()))
        if sum(len(t.split()) for t in texts[: k + 1]) + k <= glmap.config.max_text_words:
            # Below the trigger the buffer is the plain concatenation of what was seen.
            assert unit.text == DELIMITER.join(texts[: k + 1])
    assert max(word_counts) <= glmap.config.max_text_words
    assert word_counts[-1] > 0 and unit.text != DELIMITER.join(texts)
