"""The stop rule's footprint of a matched instance: its densest cells, not every cell a mask
that bled over a depth edge gave it; and the lines of sight to it."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from glmap_tools import synthetic as scenes
from glmap_tools.errors import InvalidInputError
from glmap_tools.language.embed import HashingEmbedder
from glmap_tools.map import GLMap, MapConfig
from glmap_tools.map.occupancy import FREE, OBSTACLE, UNKNOWN, DenseOccupancy
from glmap_tools.nav import NavConfig
from glmap_tools.nav.footprint import (
    ROOM_WALL,
    ROOM_WALL_TOLERANCE_CELLS,
    GoalMatch,
    in_clear_sight,
)
from glmap_tools.nav.value import unit_cell_array, unit_core_cells

PLANT = ("plant", "a potted plant")
# A plant (x 1.4-1.6, y -0.1-0.1) on a table top at 0.75 m, seen by a 0.88 m camera: the
# table top is seen at a grazing angle, so each pixel of it spans decimetres.
PLANT_LO, PLANT_HI = np.array([1.4, -0.1]), np.array([1.6, 0.1])


def plant_on_table(bleed_px: int) -> tuple[GLMap, int]:
    """The plant seen from three places, its mask grown `bleed_px` pixels over the table top
    (same depth as the plant's base, so the map's depth-edge cleaning keeps them)."""
    boxes = scenes.floor(6.0) + scenes.table(1.5, 0.0, object_id=2)
    boxes.append(scenes.Box((1.4, -0.1, 0.75), (1.6, 0.1, 1.1), (0.2, 0.6, 0.2), 3))
    glmap = GLMap(MapConfig(floor_z=0.0), embedder=HashingEmbedder())
    for eye_y in (-0.4, 0.0, 0.4):
        frame, ids = scenes.view(boxes, (-0.3, eye_y, 0.88), (1.5, 0.0, 0.8), 160, 120)
        plant = ids == 3
        if bleed_px:
            plant |= ndimage.binary_dilation(plant, iterations=bleed_px) & (ids == 2)
        glmap.integrate(frame, scenes.semantics(np.where(plant, 3, 0), {3: PLANT}))
    (uid,) = glmap.instances
    return glmap, uid


def farthest_from_plant(cells: np.ndarray, cell_size: float) -> float:
    """Metres from the plant's footprint to the farthest cell centre."""
    xy = (cells + 0.5) * cell_size
    gap = np.maximum(np.maximum(PLANT_LO - xy, xy - PLANT_HI), 0.0)
    return float(np.hypot(gap[:, 0], gap[:, 1]).max())


@pytest.mark.parametrize("bleed_px", [2, 4])
def test_a_mask_bled_over_the_table_widens_the_unit_but_its_core_stays_on_the_plant(
    bleed_px: int,
) -> None:
    glmap, uid = plant_on_table(bleed_px)
    size = glmap.grid.cell_size
    every = unit_cell_array(glmap.grid, uid)
    core = unit_core_cells(glmap, uid, 0.8)
    assert farthest_from_plant(every, size) > 0.3  # decimetres of table top per bled pixel
    assert farthest_from_plant(core, size) <= 0.15  # the core and its 2-cell margin
    assert set(map(tuple, core.tolist())) < set(map(tuple, every.tolist()))


def test_a_clean_mask_keeps_most_of_its_cells_and_share_one_keeps_every_cell() -> None:
    glmap, uid = plant_on_table(bleed_px=0)
    every = unit_cell_array(glmap.grid, uid)
    core = unit_core_cells(glmap, uid, 0.8)
    assert len(core) >= 0.6 * len(every)
    assert np.array_equal(unit_core_cells(glmap, uid, 1.0), every)


@pytest.mark.parametrize("share", [0.0, -0.1, 1.5, float("nan")])
def test_a_footprint_core_outside_zero_to_one_is_refused_by_name(share: float) -> None:
    with pytest.raises(InvalidInputError, match="footprint_core"):
        NavConfig(footprint_core=share)


def _clear_sight_on_the_window(match, occ, points_rc, walls=None, tolerance=2):
    """in_clear_sight as numpy computes it: masks over the whole window, every sample."""
    points_rc = np.asarray(points_rc, dtype=np.int64).reshape(-1, 2)
    h, w = occ.state.shape
    rc = np.stack([match.cells[:, 1] - occ.origin[1], match.cells[:, 0] - occ.origin[0]], 1)
    rc = rc[(rc[:, 0] >= 0) & (rc[:, 0] < h) & (rc[:, 1] >= 0) & (rc[:, 1] < w)]
    if len(rc) == 0 or len(points_rc) == 0:
        return np.zeros(len(points_rc), dtype=bool)
    cells = np.zeros((h, w), dtype=bool)
    cells[rc[:, 0], rc[:, 1]] = True

    def near(steps: int) -> np.ndarray:
        return ndimage.binary_dilation(cells, iterations=steps) if steps >= 1 else cells

    near_unit = near(tolerance)
    blocking = (occ.state == OBSTACLE) & ~near_unit
    if walls is not None:
        room = walls >= ROOM_WALL
        near_room = near(min(tolerance, ROOM_WALL_TOLERANCE_CELLS))
        blocking = (occ.state == OBSTACLE) & ((walls > 0) & ~near_unit | room & ~near_room)
    d2 = ((points_rc[:, None, :] - rc[None, :, :]) ** 2).sum(axis=2)
    ends = rc[np.argmin(d2, axis=1)]
    n = int(np.ceil(np.sqrt(d2.min(axis=1).max()) * 4)) + 2
    f = np.linspace(0.0, 1.0, n)[None, :, None]
    samples = points_rc[:, None, :] + f * (ends - points_rc)[:, None, :]
    cells_on = np.clip(np.rint(samples).astype(np.int64), 0, [h - 1, w - 1])
    return ~blocking[cells_on[..., 0], cells_on[..., 1]].any(axis=1)


@pytest.mark.parametrize("seed", range(4))
def test_clear_sight_answers_as_the_masks_over_the_whole_window(seed: int) -> None:
    rng = np.random.default_rng(seed)
    for trial in range(400):
        h, w = (int(v) for v in rng.integers(3, 60, 2))
        origin = (int(rng.integers(-5, 5)), int(rng.integers(-5, 5)))
        state = rng.choice([UNKNOWN, FREE, OBSTACLE], (h, w), p=[0.2, 0.6, 0.2]).astype(np.int8)
        occ = DenseOccupancy(state, origin, 0.05)
        k = int(rng.integers(1, 15))  # some cells may fall outside the window
        ij = np.stack([rng.integers(-3, w + 3, k), rng.integers(-3, h + 3, k)], 1) + origin
        if trial % 7 == 0:  # a unit at the window's corners
            ij = np.vstack([ij, np.array([[0, 0], [w - 1, h - 1]]) + origin])
        match = GoalMatch(1, 0.9, 3, ij)
        points = np.stack([rng.integers(0, h, 30), rng.integers(0, w, 30)], 1)
        walls = [None, rng.integers(0, 3, (h, w)).astype(np.int8), rng.uniform(size=(h, w)) < 0.3]
        for tolerance in (-1, 0, 1, 2, 3):
            for wall in walls:
                expected = _clear_sight_on_the_window(match, occ, points, wall, tolerance)
                assert np.array_equal(in_clear_sight(match, occ, points, wall, tolerance), expected)
