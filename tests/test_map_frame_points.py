"""The frame's shared points against per-part back-projection (the reference)."""

import numpy as np
import pytest

from glmap_tools import synthetic as scenes
from glmap_tools.geometry.backproject import backproject
from glmap_tools.map import MapConfig
from glmap_tools.map.frame_layers import needed_pixels, structure_mask, structure_stride
from glmap_tools.map.frame_points import frame_points


def _scene(seed: int):
    rng = np.random.default_rng(seed)
    boxes = scenes.floor() + scenes.chair(0.0, 0.0, object_id=1) + scenes.table(1.2, 0.4, 2)
    eye = scenes.orbit_eye((0.4, 0.2), rng.uniform(2.0, 3.5), rng.uniform(0, 360))
    frame, ids = scenes.view(boxes, eye, (0.4, 0.2, 0.3), 160, 120)
    depth = frame.depth.copy()
    depth[rng.random(depth.shape) < 0.05] = np.nan  # holes, as real sensors leave
    return type(frame)(frame.rgb, depth, frame.intrinsics, frame.pose), ids


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("stride", [1, 2, 3])
def test_a_masked_cloud_of_the_shared_points_equals_its_own_back_projection(seed, stride):
    frame, ids = _scene(seed)
    config = MapConfig(occupancy_stride=stride, max_range=4.0)
    sem = scenes.semantics(ids, {1: ("chair", "a chair"), 2: ("table", "a table")})
    points = frame_points(frame, config.max_range, needed_pixels(config, sem, ids.shape))
    parts = [(None, stride)] + [(o.mask, 1) for o in sem.objects]
    parts.append((structure_mask(points.valid, sem), structure_stride(config, ids.shape[1])))
    for mask, s in parts:
        ours = points.cloud(mask, s)
        ref = backproject(
            frame.depth, frame.intrinsics, frame.pose, frame.rgb, mask, config.max_range, s
        )
        assert len(ref) > 0
        np.testing.assert_array_equal(ours.points, ref.points)  # bit for bit
        np.testing.assert_array_equal(ours.colors, ref.colors)


def test_the_shared_points_back_project_only_the_pixels_the_parts_read():
    frame, ids = _scene(0)
    config = MapConfig(occupancy_stride=4, structure_stride=4)
    sem = scenes.semantics(ids, {1: ("chair", "a chair")})
    needed = needed_pixels(config, sem, ids.shape)
    points = frame_points(frame, config.max_range, needed)
    assert len(points.points) == int((needed & points.valid).sum()) < int(points.valid.sum())
