"""The labelled top-down image: footprints, free space, region hulls, agent, heat map."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from glmap_tools.errors import GLMapError, InvalidInputError
from glmap_tools.views import HeatMap, draw_topdown
from glmap_tools.views.topdown import AGENT_RGB, FREE_RGB, MAX_SIDE, palette
from tests.test_views_fixtures import build_wall_scene, empty_map


@pytest.fixture(scope="module")
def scene():
    return build_wall_scene()


@pytest.fixture(scope="module")
def plain(scene):
    return draw_topdown(scene.glmap, labels=False, trajectory=False, regions=False)


def pixel(image, x: float, y: float) -> np.ndarray:
    col, row = image.world_to_pixel(x, y)
    return image.rgb[int(row), int(col)]


def test_each_instance_footprint_is_drawn_in_its_colour_where_its_cells_are(scene, plain):
    cell = scene.glmap.config.cell_size
    for uid in (scene.chair, *scene.walls):
        cells = sorted(scene.glmap.grid.cells_of_unit(uid))
        colours = [pixel(plain, (i + 0.5) * cell, (j + 0.5) * cell) for i, j in cells]
        share = np.mean([tuple(c) == palette(uid) for c in colours])
        # The smaller chair is drawn over the walls; each wall keeps most of its cells.
        assert share > (0.95 if uid == scene.chair else 0.6), uid


def test_seen_free_space_is_white_and_the_image_is_oriented_x_right_y_up(scene, plain):
    assert tuple(pixel(plain, 0.0, 2.0)) == FREE_RGB  # in front of the open-side cameras
    assert tuple(pixel(plain, 0.0, -1.5)) == FREE_RGB  # behind the wall
    col_a, row_a = plain.world_to_pixel(0.0, 1.0)
    col_b, row_b = plain.world_to_pixel(1.0, 2.0)
    assert col_b > col_a and row_b < row_a
    x, y = plain.pixel_to_world(*plain.world_to_pixel(0.37, -1.2))
    assert (x, y) == pytest.approx((0.37, -1.2))


def test_region_hulls_and_labels_are_drawn(scene, plain):
    full = draw_topdown(scene.glmap)
    assert scene.region is not None
    hull = np.all(full.rgb == palette(scene.region), axis=2)
    assert hull.sum() > 20
    assert not np.all(plain.rgb == palette(scene.region), axis=2).any()
    assert any("R<id>" in line for line in full.legend)
    assert (np.abs(full.rgb.astype(int) - plain.rgb.astype(int)).sum(axis=2) > 0).sum() > 100


def test_the_agent_pose_is_drawn_as_an_arrow_at_its_position(scene, plain):
    image = draw_topdown(
        scene.glmap, agent=(1.0, 2.0, np.pi / 2), labels=False, trajectory=False, regions=False
    )
    agent = np.all(image.rgb == AGENT_RGB, axis=2)
    assert not np.all(plain.rgb == AGENT_RGB, axis=2).any()
    rows, cols = np.nonzero(agent)
    col, row = image.world_to_pixel(1.0, 2.0)
    assert np.hypot(cols - col, rows - row).min() < 3
    assert rows.min() < row - 5  # facing +y: the arrow points up the image
    with pytest.raises(InvalidInputError, match="agent"):
        draw_topdown(scene.glmap, agent=(1.0, 2.0))  # type: ignore[arg-type]


def test_a_heat_map_overlay_colours_cold_and_hot_cells_differently(scene, plain):
    # A ramp along x over the open side: cold at x = -1.5, hot at x = +1.5 (10 cm cells).
    values = np.tile(np.linspace(0.0, 1.0, 30), (10, 1))
    heat = HeatMap(values, origin=(-15, 10), cell_size=0.1)
    image = draw_topdown(scene.glmap, heatmap=heat, labels=False, trajectory=False, regions=False)
    cold, hot = pixel(image, -1.45, 1.5).astype(int), pixel(image, 1.45, 1.5).astype(int)
    assert cold[2] > cold[0] and hot[0] > hot[2]
    assert tuple(pixel(image, 0.0, -1.5)) == FREE_RGB  # outside the heat map: untouched
    with pytest.raises(InvalidInputError, match="shape"):
        HeatMap(np.zeros(5), (0, 0), 0.05)
    with pytest.raises(InvalidInputError, match="HeatMap"):
        draw_topdown(scene.glmap, heatmap=values)  # type: ignore[arg-type]


def test_the_image_size_is_capped_and_the_png_decodes_to_it(scene):
    small = draw_topdown(scene.glmap, max_side=100)
    assert max(small.rgb.shape[:2]) <= 100
    decoded = cv2.imdecode(np.frombuffer(small.to_png(), np.uint8), cv2.IMREAD_COLOR)
    assert decoded is not None
    np.testing.assert_array_equal(cv2.cvtColor(decoded, cv2.COLOR_BGR2RGB), small.rgb)
    for bad in (10, MAX_SIDE + 1, 1.5):
        with pytest.raises(InvalidInputError, match="max_side"):
            draw_topdown(scene.glmap, max_side=bad)  # type: ignore[arg-type]
    assert "cm per pixel" in small.describe()


def test_an_empty_map_has_nothing_to_draw():
    with pytest.raises(GLMapError, match="empty"):
        draw_topdown(empty_map())


def test_a_window_crops_the_map_to_it_and_labels_only_what_it_shows(scene):
    glmap = scene.glmap
    whole = draw_topdown(glmap, regions=False, trajectory=False)
    cx, cy = next(iter(glmap.instances.values())).centroid[:2]
    window = (cx - 1, cy - 1, cx + 1, cy + 1)
    crop = draw_topdown(glmap, regions=False, trajectory=False, max_side=256, window=window)
    assert max(crop.rgb.shape[:2]) <= 256
    assert crop.x0 <= cx - 1 + 1e-9 and crop.y1 >= cy + 1 - 1e-9
    assert crop.x0 >= cx - 1.5 and crop.y1 <= cy + 1.5  # the window, not the whole map
    assert len(crop.label_boxes) < len(whole.label_boxes) or len(glmap.instances) == 1
    for bad in ((1.0, 1.0, 0.0, 0.0), (0.0, 0.0, float("nan"), 1.0), (0.0, 0.0, 1.0)):
        with pytest.raises(InvalidInputError, match="window"):
            draw_topdown(glmap, window=bad)
