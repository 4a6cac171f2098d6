"""Frontiers on hand-built occupancy grids, and the waypoint rule that picks among them."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import ndimage

from glmap_tools.errors import InvalidInputError
from glmap_tools.map.occupancy import FREE, OBSTACLE, UNKNOWN, DenseOccupancy
from glmap_tools.nav import (
    GoalMatch,
    NavConfig,
    ValueMap,
    choose_waypoint,
    frontiers,
    traversable,
)
from glmap_tools.nav.footprint import distances_to_cells
from glmap_tools.nav.planner import agent_field
from glmap_tools.nav.value import gaussian_kernel_1d

CELL = 0.05
RADIUS = 0.18


def room_with_door(door_cells: int) -> DenseOccupancy:
    """A 2 m x 2 m free room (walls all round) in unknown space; a door in the right wall.

    Rows 10..50, columns 10..50 (walls on the border rows/columns); the door is centred
    on row 30 of column 50; beyond it everything is unknown.
    """
    state = np.full((61, 81), UNKNOWN, dtype=np.int8)
    state[10:51, 10:51] = OBSTACLE
    state[11:50, 11:50] = FREE
    half = door_cells // 2
    state[30 - half : 30 - half + door_cells, 50] = FREE
    return DenseOccupancy(state, (0, 0), CELL)


def centre(occ: DenseOccupancy) -> tuple[float, float]:
    return occ.index_to_world(30, 30)


def test_a_room_with_a_door_to_unknown_space_has_one_frontier_in_the_doorway() -> None:
    occ = room_with_door(20)  # a 1 m door
    fronts = frontiers(occ, centre(occ), RADIUS, min_size=3)
    assert len(fronts) == 1
    f = fronts[0]
    door = occ.index_to_world(30, 50)
    assert math.dist(f.centroid, door) < 0.1
    # 20 door cells less the inflation of the door posts on both sides (3 cells each).
    assert f.size == 20 - 2 * 3
    assert np.all(f.cells[:, 1] == 50)
    assert f.distance == pytest.approx(math.dist(centre(occ), door), rel=0.05)
    assert math.dist(f.target, f.centroid) <= CELL


def test_a_door_narrower_than_the_agent_is_closed_by_inflation() -> None:
    wide, narrow = room_with_door(10), room_with_door(6)  # 0.5 m and 0.3 m doors
    assert len(frontiers(wide, centre(wide), RADIUS, min_size=1)) == 1
    assert frontiers(narrow, centre(narrow), RADIUS, min_size=1) == []
    # The same narrow door is open to a thinner agent.
    assert len(frontiers(narrow, centre(narrow), 0.1, min_size=1)) == 1


def test_a_frontier_behind_a_wall_is_not_reachable_and_is_left_out() -> None:
    occ = room_with_door(20)
    state = occ.state.copy()
    state[30, 50] = state[20:41, 50] = OBSTACLE  # close the door
    state[20:40, 60:75] = FREE  # a seen patch beyond the wall, with unknown all round it
    closed = DenseOccupancy(state, occ.origin, CELL)
    assert frontiers(closed, centre(closed), RADIUS, min_size=1) == []
    inside = closed.index_to_world(30, 67)
    assert len(frontiers(closed, inside, RADIUS, min_size=1)) == 1


def test_clusters_smaller_than_min_size_are_dropped() -> None:
    occ = room_with_door(20)
    assert frontiers(occ, centre(occ), RADIUS, min_size=15) == []
    # The doorway's cluster has 14 cells: min_size 14 keeps it, 15 drops it.
    assert [f.size for f in frontiers(occ, centre(occ), RADIUS, min_size=14)] == [14]


def test_a_diagonal_pinch_is_no_way_through() -> None:
    """Reachability is 4-connected, as the FMM marches: two rooms touching at a corner cell
    are two places."""
    state = np.full((40, 40), UNKNOWN, dtype=np.int8)
    state[5:35, 5:35] = OBSTACLE
    state[6:19, 6:19] = FREE  # room A
    state[19:34, 19:34] = FREE  # room B, touching A only at the corner (18, 18)-(19, 19)
    state[19:34, 34] = UNKNOWN  # B's right wall is unseen
    occ = DenseOccupancy(state, (0, 0), CELL)
    a, b = occ.index_to_world(12, 12), occ.index_to_world(26, 26)
    assert frontiers(occ, a, 0.0, min_size=1) == []  # B's frontier is behind the pinch
    assert [f.size for f in frontiers(occ, b, 0.0, min_size=1)] == [15]


def two_door_room() -> DenseOccupancy:
    """The room with a 1 m door on the right (row 30) and one on the top wall (column 20)."""
    occ = room_with_door(20)
    state = occ.state.copy()
    state[50, 10:31] = FREE
    state[50, 10] = OBSTACLE
    return DenseOccupancy(state, occ.origin, CELL)


def value_peak_at(occ: DenseOccupancy, row: int, col: int, sigma: float = 0.5) -> ValueMap:
    """Eq. 7's map of one unit on one cell: the kernel K_sigma around it, peak 1."""
    values = np.zeros(occ.state.shape)
    values[row, col] = 1.0
    k = gaussian_kernel_1d(sigma / CELL)
    values = ndimage.convolve1d(ndimage.convolve1d(values, k, 0, mode="constant"), k, 1)
    return ValueMap(values / values.max(), occ.origin, CELL, 1.0, sigma)


def test_the_waypoint_is_the_frontier_closest_to_the_value_maximum() -> None:
    occ = two_door_room()
    here = occ.index_to_world(35, 40)  # nearer the right door
    config = NavConfig()
    field = agent_field(occ, here, config).metres
    fronts = frontiers(occ, here, RADIUS, min_size=3, distance_field=field)
    assert len(fronts) == 2
    trav = traversable(occ, RADIUS)
    top = value_peak_at(occ, 58, 20)  # beyond the top door
    wp = choose_waypoint(top, fronts, trav, here, None, config, occ=occ, distance=field)
    assert wp.kind == "frontier" and wp.xy is not None
    assert occ.world_to_index(*wp.xy)[0] == 50  # in the top doorway
    right = value_peak_at(occ, 30, 70)
    wp = choose_waypoint(right, fronts, trav, here, None, config, occ=occ, distance=field)
    assert occ.world_to_index(*wp.xy)[1] == 50  # type: ignore[misc]
    # Without a value map: the nearest frontier (the right door).
    wp = choose_waypoint(None, fronts, trav, here, None, config, occ=occ, distance=field)
    assert occ.world_to_index(*wp.xy)[1] == 50  # type: ignore[misc]
    # A frontier the planner cannot reach is skipped for the next best.
    blocked = [f if f.cells[0, 0] != 50 else _unreachable(f) for f in fronts]
    wp = choose_waypoint(top, blocked, trav, here, None, config, occ=occ, distance=field)
    assert occ.world_to_index(*wp.xy)[1] == 50  # type: ignore[misc]


def test_a_value_maximum_that_reaches_no_frontier_leaves_the_nearest_frontier_to_lead() -> None:
    """H is 0 beyond the kernel's reach (3 sigma = 1.5 m) of every unit: a frontier there
    is no closer to the goal for being closer to the peak, so the nearest one leads."""
    occ = two_door_room()
    here = occ.index_to_world(35, 40)  # nearer the right door
    config = NavConfig()
    field = agent_field(occ, here, config).metres
    fronts = frontiers(occ, here, RADIUS, min_size=3, distance_field=field)
    trav = traversable(occ, RADIUS)
    far = value_peak_at(occ, 5, 5)  # below the room's corner, 2.25 m from either doorway
    assert not (far.values[50, 11:31] > 0).any() and not (far.values[20:40, 50] > 0).any()
    wp = choose_waypoint(far, fronts, trav, here, None, config, occ=occ, distance=field)
    assert wp.kind == "frontier" and occ.world_to_index(*wp.xy)[1] == 50  # type: ignore[misc]
    assert "reaches none" in wp.reason
    # A wider kernel reaches both: the paper's rule again (the top door is the closer).
    wide = value_peak_at(occ, 5, 5, sigma=1.0)
    wp = choose_waypoint(wide, fronts, trav, here, None, config, occ=occ, distance=field)
    assert occ.world_to_index(*wp.xy)[0] == 50  # type: ignore[misc]


def _unreachable(f):  # type: ignore[no-untyped-def]
    from dataclasses import replace

    return replace(f, distance=math.inf)


def test_a_matched_unit_gives_the_nearest_navigable_cell_within_the_stop_distance() -> None:
    occ = room_with_door(20)
    config = NavConfig()
    here = occ.index_to_world(20, 20)
    cells = np.array([(i, j) for i in range(38, 42) for j in range(38, 42)])  # a 20 cm box
    match = GoalMatch(7, 0.9, 3, cells)
    trav = traversable(occ, RADIUS)
    field = agent_field(occ, here, config).metres
    wp = choose_waypoint(None, [], trav, here, match, config, occ=occ, distance=field)
    assert wp.kind == "goal" and wp.unit_id == 7 and wp.xy is not None
    assert trav[occ.world_to_index(*wp.xy)]
    box_centre = (40 * CELL, 40 * CELL)
    assert math.dist(wp.xy, box_centre) <= config.stop_distance + 0.1 + 0.001
    assert math.dist(wp.xy, box_centre) >= 0.4  # not further in than it must: the near edge
    # The plan counts the agent arrived within half a step of the waypoint: from anywhere
    # there the unit is within the stop distance, so where it arrives, it stops.
    arc = np.linspace(0, 2 * math.pi, 16, endpoint=False)
    r = config.forward_step / 2
    around = np.stack([wp.xy[0] + r * np.cos(arc), wp.xy[1] + r * np.sin(arc)], axis=1)
    assert distances_to_cells(cells, around, CELL).max() <= config.stop_distance
    # Standing within the stop distance already: the waypoint is where the agent is.
    near = (40 * CELL - 0.5, 40 * CELL)
    wp = choose_waypoint(None, [], trav, near, match, config, occ=occ, distance=field)
    assert wp.kind == "goal" and wp.xy == near


def test_a_stop_within_reach_but_behind_a_wall_moves_to_where_the_unit_is_in_sight() -> None:
    from glmap_tools.nav.footprint import in_clear_sight

    occ = room_with_door(20)
    occ.state[11:39, 34] = OBSTACLE  # a wall stub from the top wall, open below row 38
    cells = np.array([(i, j) for i in range(38, 42) for j in range(20, 24)])  # right of it
    match = GoalMatch(7, 0.9, 3, cells)
    here = occ.index_to_world(21, 29)  # 0.43 m from the unit, the wall in between
    trav = traversable(occ, RADIUS)
    assert trav[21, 29]
    field = agent_field(occ, here, NavConfig()).metres
    sight = NavConfig()  # stop_in_sight is the default
    assert sight.stop_in_sight
    assert not in_clear_sight(match, occ, np.array([[21, 29]]))[0]
    # Only walls block: the same stub counted as furniture (not structure) hides nothing.
    furniture = np.zeros_like(occ.state, dtype=bool)
    assert in_clear_sight(match, occ, np.array([[21, 29]]), furniture)[0]
    assert in_clear_sight(match, occ, np.array([[21, 36], [45, 38], [45, 30]])).tolist() == [
        True,
        True,
        False,  # its line to the unit crosses the stub
    ]
    # Without the check the agent stops here, as the old rule did; with it, it walks round.
    off = NavConfig(stop_in_sight=False)
    stays = choose_waypoint(None, [], trav, here, match, off, occ=occ, distance=field)
    assert stays.xy == here
    wp = choose_waypoint(None, [], trav, here, match, sight, occ=occ, distance=field)
    assert wp.kind == "goal" and wp.xy is not None and wp.xy != here
    assert "out of sight" in wp.reason
    rc = occ.world_to_index(*wp.xy)
    assert trav[rc] and in_clear_sight(match, occ, np.array([rc]))[0]
    assert math.dist(wp.xy, (40 * CELL, 22 * CELL)) <= sight.stop_distance + 0.15
    # Standing there, it stops.
    there = choose_waypoint(None, [], trav, wp.xy, match, sight, occ=occ, distance=field)
    assert there.xy == wp.xy and "within the stop distance" in there.reason
    # With no cell in sight within reach (the unit boxed in), the old rule applies.
    boxed = DenseOccupancy(occ.state.copy(), occ.origin, CELL)
    boxed.state[15:29, 34:46] = OBSTACLE
    boxed.state[18:26, 37:43] = FREE
    trav_b = traversable(boxed, RADIUS)
    field_b = agent_field(boxed, here, NavConfig()).metres
    wp = choose_waypoint(None, [], trav_b, here, match, sight, occ=boxed, distance=field_b)
    assert wp.xy == here
    with pytest.raises(InvalidInputError, match="stop_in_sight='yes' must be true or false"):
        NavConfig(stop_in_sight="yes")  # type: ignore[arg-type]


def test_a_unit_against_the_far_side_of_a_room_wall_is_not_stopped_for_from_behind_it() -> None:
    from glmap_tools.nav.footprint import ROOM_WALL, WALL, in_clear_sight

    occ = room_with_door(20)
    occ.state[11:50, 34:36] = OBSTACLE  # a wall, 10 cm thick, splits the room
    walls = np.zeros(occ.state.shape, dtype=np.int8)
    walls[10:51, 10:51] = np.where(occ.state[10:51, 10:51] == OBSTACLE, ROOM_WALL, 0)
    cells = np.array([(i, j) for i in range(36, 40) for j in range(28, 32)])  # against it
    match = GoalMatch(7, 0.9, 3, cells)
    here = occ.index_to_world(30, 29)  # 0.3 m from the unit, on the wall's other side
    trav = traversable(occ, RADIUS)
    field = agent_field(occ, here, NavConfig()).metres
    config = NavConfig()
    # The wall lies within the tolerance the map's own drawing of the unit needs (2 cells),
    # so with every obstacle blocking the line "clears" it; a room's wall blocks from one.
    assert in_clear_sight(match, occ, np.array([[30, 29]]))[0]
    assert not in_clear_sight(match, occ, np.array([[30, 29]]), walls)[0]
    old = choose_waypoint(None, [], trav, here, match, config, occ=occ, distance=field)
    assert old.kind == "goal" and old.xy == here
    # A room's wall blocks from one cell on: no stop and no approach from this side.
    wp = choose_waypoint(None, [], trav, here, match, config, occ=occ, distance=field, walls=walls)
    assert wp.kind != "goal"
    # Structure below a room wall's height (furniture a detector missed, say) blocks only
    # where some cell near the unit is in sight; here none is, so the old rule applies.
    low = np.where(walls > 0, WALL, 0).astype(np.int8)
    wp = choose_waypoint(None, [], trav, here, match, config, occ=occ, distance=field, walls=low)
    assert wp.kind == "goal" and wp.xy == here
    # From the unit's side of the wall it is stopped for as before.
    there = occ.index_to_world(30, 44)
    field = agent_field(occ, there, config).metres
    wp = choose_waypoint(None, [], trav, there, match, config, occ=occ, distance=field, walls=walls)
    assert wp.kind == "goal" and wp.xy == there


def test_no_frontier_no_match_and_no_value_means_no_waypoint() -> None:
    occ = room_with_door(0)  # a closed room: nothing left to explore
    here = centre(occ)
    trav = traversable(occ, RADIUS)
    assert frontiers(occ, here, RADIUS) == []
    wp = choose_waypoint(None, [], trav, here, None, NavConfig(), occ=occ)
    assert (wp.kind, wp.xy) == ("none", None)
    # With a value map the agent heads for its best navigable cell instead.
    wp = choose_waypoint(value_peak_at(occ, 45, 45), [], trav, here, None, NavConfig(), occ=occ)
    assert wp.kind == "explore" and math.dist(wp.xy, occ.index_to_world(45, 45)) < 0.2  # type: ignore[arg-type]


def test_opencv_components_and_dilation_give_ndimages_frontiers(monkeypatch) -> None:
    import importlib

    fr = importlib.import_module("glmap_tools.nav.frontiers")  # `nav.frontiers` is the function

    def ndimage_components(mask: np.ndarray, connectivity: int) -> tuple[np.ndarray, int]:
        structure = None if connectivity == 4 else np.ones((3, 3), dtype=bool)
        labels, n = ndimage.label(mask, structure=structure)
        return labels, int(n)

    def ndimage_mask(occ: DenseOccupancy, trav: np.ndarray) -> np.ndarray:
        unknown = (occ.state == UNKNOWN).view(np.uint8)
        return trav & ndimage.maximum_filter(unknown, size=3, mode="constant").astype(bool)

    rng = np.random.default_rng(7)
    found = 0
    for _ in range(60):
        h, w = (int(v) for v in rng.integers(20, 90, 2))
        state = rng.choice([UNKNOWN, FREE, OBSTACLE], (h, w), p=[0.3, 0.6, 0.1]).astype(np.int8)
        state = ndimage.median_filter(state, size=3)  # blobs, not salt
        occ = DenseOccupancy(state, (int(rng.integers(-20, 20)), int(rng.integers(-20, 20))), CELL)
        xy = occ.index_to_world(int(rng.integers(0, h)), int(rng.integers(0, w)))
        field = rng.uniform(0, 10, (h, w)) if rng.random() < 0.5 else None
        fast = frontiers(occ, xy, RADIUS, 3, field)
        with monkeypatch.context() as m:
            m.setattr(fr, "_components", ndimage_components)
            m.setattr(fr, "frontier_mask", ndimage_mask)
            slow = frontiers(occ, xy, RADIUS, 3, field)
        assert [(f.centroid, f.size, f.distance, f.target) for f in fast] == [
            (f.centroid, f.size, f.distance, f.target) for f in slow
        ]
        for a, b in zip(fast, slow, strict=True):
            np.testing.assert_array_equal(a.cells, b.cells)
        found += len(fast)
    assert found > 100
