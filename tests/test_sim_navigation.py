"""Navigable grid and geodesic distances."""

from __future__ import annotations

import math

import numpy as np
import pytest

from glmap_tools.sim.geodesic import geodesic_distance, geodesic_distance_reference
from glmap_tools.sim.layout_io import layout_from_dict
from glmap_tools.sim.navgrid import AGENT_RADIUS, build_nav_grid


def _two_rooms(door_width: float, objects: list | None = None):
    return layout_from_dict(
        {
            "rooms": [
                {"id": 1, "type": "kitchen", "polygon": [[0, 0], [4, 0], [4, 3], [0, 3]]},
                {"id": 2, "type": "office", "polygon": [[4, 0], [8, 0], [8, 3], [4, 3]]},
            ],
            "openings": [{"id": 1, "rooms": [1, 2], "center": [4, 1.5], "width": door_width}],
            "objects": objects or [],
        }
    )


@pytest.mark.parametrize(("shape", "seed"), [((7, 9), 0), ((30, 40), 1), ((64, 50), 2)])
def test_numba_dijkstra_matches_the_relaxation_reference(shape, seed) -> None:
    rng = np.random.default_rng(seed)
    nav = rng.random(shape) > 0.3
    sources = rng.random(shape) > 0.97
    fast = geodesic_distance(nav, sources, 0.05)
    slow = geodesic_distance_reference(nav, sources, 0.05)
    np.testing.assert_array_equal(np.isinf(fast), np.isinf(slow))
    finite = np.isfinite(slow)
    np.testing.assert_allclose(fast[finite], slow[finite], rtol=0, atol=1e-9)


def test_geodesic_distance_on_an_open_grid_is_the_octile_distance() -> None:
    nav = np.ones((20, 30), dtype=bool)
    src = np.zeros_like(nav)
    src[2, 3] = True
    d = geodesic_distance(nav, src, 0.1)
    dr, dc = 15 - 2, 25 - 3
    expected = (min(dr, dc) * math.sqrt(2) + abs(dr - dc)) * 0.1
    assert d[15, 25] == pytest.approx(expected)


def test_a_wall_makes_the_geodesic_go_around_it() -> None:
    nav = np.ones((10, 10), dtype=bool)
    nav[1:, 5] = False  # wall with a gap in the top row
    src = np.zeros_like(nav)
    src[9, 0] = True
    d = geodesic_distance(nav, src, 1.0)
    octile_via_gap = (5 * math.sqrt(2) + 4) + (4 * math.sqrt(2) + 5)
    assert d[9, 9] >= octile_via_gap - 1e-9  # up, across the gap, down
    assert np.isinf(geodesic_distance(nav & (np.arange(10)[:, None] > 0), src, 1.0)[9, 9])


def test_the_agent_centre_stays_a_radius_away_from_walls_and_furniture() -> None:
    box = {"id": 1, "category": "box", "mesh": "primitive/box", "position": [2, 1.5, 0],
           "size": [0.6, 0.6, 0.6]}  # fmt: skip
    grid = build_nav_grid(_two_rooms(0.9, [box]))
    xs, ys = grid.cell_centers()
    pts = np.column_stack([xs[grid.navigable], ys[grid.navigable]])
    wall_inner = 0.05  # each room's wall stands 5 cm inside its polygon
    assert pts[:, 1].min() >= wall_inner + AGENT_RADIUS - 1e-9
    # Cell centres clear of the box by the radius, up to half a cell of rasterisation.
    box_object = _two_rooms(0.9, [box]).objects[0]
    assert box_object.distance_to(pts).min() >= AGENT_RADIUS - grid.cell / 2
    assert grid.is_navigable(np.array([[1.0, 1.5], [6.0, 1.5]])).all()


def test_a_door_narrower_than_the_agent_leaves_only_one_room_navigable() -> None:
    wide = build_nav_grid(_two_rooms(0.9))
    narrow = build_nav_grid(_two_rooms(0.3))
    both = np.array([[1.0, 1.5], [6.0, 1.5]])
    assert wide.is_navigable(both).all()
    assert narrow.is_navigable(both).sum() == 1
    d = wide.distance_field(_cell_mask(wide, 6.0, 1.5))
    start = wide.to_cell(np.array([[1.0, 1.5]]))[0]
    assert 5.0 <= d[start[0], start[1]] < 5.3


def _cell_mask(grid, x: float, y: float) -> np.ndarray:
    mask = np.zeros(grid.shape, dtype=bool)
    r, c = grid.to_cell(np.array([[x, y]]))[0]
    mask[r, c] = True
    return mask
