"""A mask that bled past its object's outline loses the pixels across the depth edge; a
mask that follows its object, even a slanted one, keeps every pixel."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from glmap_tools.map.mask_edges import depth_consistent


@pytest.mark.parametrize(("width", "bleed"), [(320, 2), (640, 3)])
def test_a_rim_that_bled_onto_the_wall_behind_is_dropped(width: int, bleed: int) -> None:
    h = width * 3 // 4
    depth = np.full((h, width), 3.0, np.float32)  # the wall
    obj = np.zeros((h, width), bool)
    obj[h // 4 : h // 2, width // 4 : width // 2] = True
    depth[obj] = 2.0  # a box in front of it
    kernel = np.ones((2 * bleed + 1, 2 * bleed + 1), np.uint8)
    bled = cv2.dilate(obj.astype(np.uint8), kernel) > 0
    kept = depth_consistent(bled, depth)
    rim = bled & ~obj
    assert kept[rim].mean() < 0.1  # the wall's pixels go (a few at the rim's corners stay)
    assert kept[obj].mean() > 0.9  # the box's pixels stay but for a few at its corners


def test_a_slanted_surface_and_pixels_without_depth() -> None:
    depth = np.tile(np.linspace(1.0, 4.0, 200, dtype=np.float32), (150, 1))  # a floor-like ramp
    mask = np.zeros((150, 200), bool)
    mask[20:130, 10:190] = True
    depth[60:70, 60:70] = 0.0  # no measurement
    kept = depth_consistent(mask, depth)
    assert np.array_equal(kept, mask & (depth > 0))
    assert not depth_consistent(np.zeros_like(mask), depth).any()
