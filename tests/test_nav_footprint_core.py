"""The stop rule's footprint of a matched instance: its densest cells, not every cell a mask
that bled over a depth edge gave it."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from glmap_tools import synthetic as scenes
from glmap_tools.errors import InvalidInputError
from glmap_tools.language.embed import HashingEmbedder
from glmap_tools.map import GLMap, MapConfig
from glmap_tools.nav import NavConfig
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


@pytest.mark.parametrize("seed", range(6))
def test_the_cells_near_a_unit_are_scipys_dilation_of_the_whole_window(seed: int) -> None:
    from glmap_tools.nav.footprint import _near_cells

    rng = np.random.default_rng(seed)
    shape = (int(rng.integers(3, 50)), int(rng.integers(3, 50)))
    rc = np.unique(rng.integers(0, shape, size=(int(rng.integers(1, 12)), 2)), axis=0)
    if seed % 2:  # a unit at the window's corner
        rc = np.vstack([rc, [0, 0], [shape[0] - 1, shape[1] - 1]])
    cells = np.zeros(shape, dtype=bool)
    cells[rc[:, 0], rc[:, 1]] = True
    assert np.array_equal(_near_cells(rc, shape, 0), cells)
    for steps in (1, 2, 3):
        expected = ndimage.binary_dilation(cells, iterations=steps)
        assert np.array_equal(_near_cells(rc, shape, steps), expected)
