"""Situated views: front, back, left and right of a position, at the agent's height."""

from __future__ import annotations

import math

import numpy as np
import pytest

from glmap_tools.errors import GLMapError, InvalidInputError
from glmap_tools.views import situated_poses, situated_views, view_intrinsics
from tests.test_views_fixtures import CHAIR_XY, build_wall_scene, empty_map


@pytest.fixture(scope="module")
def scene():
    return build_wall_scene()


def red_fraction(rgb: np.ndarray) -> float:
    return float(((rgb[..., 0] > 150) & (rgb[..., 1] < 100)).mean())


def test_the_four_views_turn_by_quarter_turns_from_the_heading(scene):
    heading = 0.4
    poses = dict(situated_poses(scene.glmap, 1.0, 2.0, heading))
    assert list(poses) == ["front", "back", "left", "right"]
    for label, turn in (("front", 0), ("back", math.pi), ("left", math.pi / 2)):
        diff = (poses[label].heading - heading - turn + math.pi) % (2 * math.pi) - math.pi
        assert abs(diff) < 1e-9, label
    for pose in poses.values():
        assert pose.translation == pytest.approx([1.0, 2.0, 0.0 + 0.88])
        assert abs(pose.rotation[2, 2]) < 1e-12  # level: the optical axis is horizontal


def test_an_object_on_the_agents_right_appears_in_the_right_view_only(scene):
    # Standing at (0, 1.8) facing +x, the chair at (0, 0.7) is on the right (-y).
    views = situated_views(scene.glmap, CHAIR_XY[0], 1.8, 0.0, view_intrinsics(64, 48))
    red = {label: red_fraction(v.rgb) for label, v in views.by_direction().items()}
    assert red["right"] > 0.05
    assert red["front"] < 0.005 and red["back"] < 0.005 and red["left"] < 0.005
    assert views.cell_state == "free"
    assert [v.rgb.shape for v in views.views] == [(48, 64, 3)] * 4


def test_a_spot_inside_the_wall_is_reported_as_an_obstacle(scene):
    views = situated_views(scene.glmap, 0.5, 0.0, 0.0, view_intrinsics(16, 12))
    assert views.cell_state == "obstacle"


def test_bad_positions_and_an_empty_map_raise_glmap_errors(scene):
    for x, y, heading in ((math.nan, 0.0, 0.0), (0.0, math.inf, 0.0), (0.0, 0.0, 1e9)):
        with pytest.raises(InvalidInputError, match="finite"):
            situated_views(scene.glmap, x, y, heading)
    with pytest.raises(InvalidInputError, match="number"):
        situated_views(scene.glmap, "here", 0.0, 0.0)  # type: ignore[arg-type]
    with pytest.raises(InvalidInputError, match="pixels"):
        situated_views(scene.glmap, 0.0, 0.0, 0.0, view_intrinsics(0, 10))
    with pytest.raises(GLMapError, match="empty"):
        situated_views(empty_map(), 0.0, 0.0, 0.0)
