"""Stop, approach and the success rule agree (issue 40): an agent beside its matched goal
stops for it instead of giving up, on hand-built occupancy windows.

The scene is a lamp in the middle of a wide table (a real room's desk lamp, a ceiling-high
plant on a counter): the map holds the lamp's cells, the table's cells are obstacles round
it, so no free cell lies within the stop distance (0.75 m) of the lamp.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from glmap_tools.map.occupancy import FREE, OBSTACLE, DenseOccupancy
from glmap_tools.nav import GoalMatch, NavConfig, choose_waypoint
from glmap_tools.nav.choose import (
    GOAL_PATIENCE,
    GoalProgress,
    PlanRequest,
    choose_and_plan,
    goal_progress,
)
from glmap_tools.nav.footprint import ROOM_WALL, distance_to_cells
from glmap_tools.nav.grid import agent_rc
from glmap_tools.nav.motion import clearance, masks
from glmap_tools.nav.perceive import Surroundings
from glmap_tools.nav.planner import distance_field

CELL = 0.05
CONFIG = NavConfig()
LAMP = np.array([(i, j) for i in range(58, 62) for j in range(58, 62)])  # 20 cm, centre (3, 3)


def table_room(table_half: float) -> DenseOccupancy:
    """A 6 m x 6 m walled room, fully seen; a square table `table_half` m beyond the lamp's
    cells on each side, the lamp on it."""
    state = np.full((121, 121), OBSTACLE, dtype=np.int8)
    state[1:120, 1:120] = FREE
    k = round(table_half / CELL)
    state[58 - k : 62 + k, 58 - k : 62 + k] = OBSTACLE
    return DenseOccupancy(state, (0, 0), CELL)


def surroundings(occ: DenseOccupancy, xy: tuple[float, float]) -> Surroundings:
    clear = clearance(occ)
    rc = agent_rc(occ, xy)
    trav, ok, speed = masks(occ, clear, rc, CONFIG)
    field = distance_field(occ, ok, rc, CONFIG.plan_stride, CONFIG.optimistic, speed)
    return Surroundings(occ, clear, trav, (ok, speed), field, [])


def nearest_free(sur: Surroundings, match: GoalMatch) -> tuple[float, float]:
    """The traversable cell centre nearest the lamp, straight along -x from it."""
    row = 60
    cols = [c for c in range(0, 60) if sur.trav[row, c]]
    return sur.occ.index_to_world(row, max(cols))


def test_with_no_free_cell_within_the_stop_distance_the_agent_stops_where_a_stop_counts() -> None:
    occ = table_room(0.65)
    match = GoalMatch(5, 0.9, 3, LAMP)
    furniture = np.zeros(occ.state.shape, dtype=bool)  # no structure wall in the room
    here = nearest_free(surroundings(occ, (1.0, 3.0)), match)
    sur = surroundings(occ, here)
    d = distance_to_cells(LAMP, here, CELL)
    assert CONFIG.stop_distance < d <= CONFIG.success_radius  # within reach, not within stop
    wp = choose_waypoint(
        None, [], sur.trav, here, match, CONFIG, occ=occ, distance=sur.field.metres, walls=furniture
    )
    assert wp.kind == "goal" and wp.xy == here, wp.reason
    assert "success radius" in wp.reason
    req = PlanRequest(None, sur, here, 0.0, match, furniture, CONFIG, None, 0, ())
    choice = choose_and_plan(req)
    assert choice.plan.action == "stop" and choice.waypoint.kind == "goal"
    assert choice.rejected == frozenset()


def test_with_no_free_cell_within_the_stop_distance_the_agent_heads_to_the_nearest_one() -> None:
    occ = table_room(0.65)
    match = GoalMatch(5, 0.9, 3, LAMP)
    furniture = np.zeros(occ.state.shape, dtype=bool)
    far = (1.0, 3.0)  # 1.9 m from the lamp, the table between
    sur = surroundings(occ, far)
    wp = choose_waypoint(
        None, [], sur.trav, far, match, CONFIG, occ=occ, distance=sur.field.metres, walls=furniture
    )
    assert wp.kind == "goal" and wp.xy is not None and wp.xy != far, wp.reason
    assert distance_to_cells(LAMP, wp.xy, CELL) <= CONFIG.success_radius
    there = choose_waypoint(
        None, [], sur.trav, wp.xy, match, CONFIG, occ=occ, distance=None, walls=furniture
    )
    assert there.xy == wp.xy  # and there it stops


def test_a_matched_unit_within_one_and_a_half_metres_is_never_left_for_a_give_up_stop() -> None:
    # A table so wide that no free cell is within the success radius: the agent stands at
    # the nearest free cell, 1.2 m from the lamp, with nothing left to explore.
    occ = table_room(0.95)
    match = GoalMatch(5, 0.9, 3, LAMP)
    furniture = np.zeros(occ.state.shape, dtype=bool)
    here = nearest_free(surroundings(occ, (1.0, 3.0)), match)
    assert CONFIG.success_radius < distance_to_cells(LAMP, here, CELL) <= 1.5
    sur = surroundings(occ, here)
    choice = choose_and_plan(
        PlanRequest(None, sur, here, 0.0, match, furniture, CONFIG, None, 0, ())
    )
    assert choice.plan.action == "stop"
    assert choice.waypoint.kind == "goal" and choice.waypoint.unit_id == 5
    # Farther than 1.5 m, with nothing to do, it is a plain stop (no match held).
    wide = table_room(1.5)
    there = nearest_free(surroundings(wide, (0.3, 3.0)), match)
    assert distance_to_cells(LAMP, there, CELL) > 1.5
    sur = surroundings(wide, there)
    choice = choose_and_plan(
        PlanRequest(None, sur, there, 0.0, match, furniture, CONFIG, None, 0, ())
    )
    assert choice.waypoint.kind == "none" and math.isinf(choice.plan.length)


def test_an_agent_that_comes_no_closer_to_its_match_stops_where_a_stop_would_count() -> None:
    # A small table: cells within the stop distance exist, the way to them is what fails (two
    # unseen boxes closing a pocket swap the goal cell from side to side at every bump).
    occ = table_room(0.3)
    match = GoalMatch(5, 0.9, 3, LAMP)
    furniture = np.zeros(occ.state.shape, dtype=bool)
    here, far = (2.0, 3.0), (1.5, 3.0)
    assert CONFIG.stop_distance < distance_to_cells(LAMP, here, CELL) <= CONFIG.success_radius
    assert distance_to_cells(LAMP, far, CELL) > CONFIG.success_radius

    def choice(xy: tuple[float, float], stuck: bool):
        req = PlanRequest(
            None, surroundings(occ, xy), xy, 0.0, match, furniture, CONFIG, None, 0, ()
        )
        return choose_and_plan(replace(req, goal_stuck=stuck))

    assert choice(here, stuck=False).plan.action != "stop"  # it heads for a cell within stop
    stopped = choice(here, stuck=True)
    assert stopped.plan.action == "stop" and stopped.waypoint.unit_id == 5
    assert "came no closer" in stopped.waypoint.reason
    assert choice(far, stuck=True).plan.action != "stop"  # a stop there would not count
    # Stuck, sight is read on room walls alone: the table as structure (furniture the
    # detector missed) does not hide the lamp, the table as a room's wall does.
    table = np.zeros(occ.state.shape, dtype=bool)
    table[1:120, 1:120] = occ.state[1:120, 1:120] == OBSTACLE  # inside the room's walls
    for level, stops in ((1, True), (ROOM_WALL, False)):
        furniture = np.where(table, level, 0)
        reason = choice(here, stuck=True).waypoint.reason
        assert ("came no closer" in reason) is stops, (level, reason)


def test_goal_progress_counts_the_steps_since_the_agent_last_closed_in_on_the_match() -> None:
    match = GoalMatch(5, 0.9, 3, LAMP)
    p = goal_progress(GoalProgress(), match, (2.0, 3.0), CELL)
    assert (p.unit_id, p.since_progress) == (5, 0)
    for _ in range(GOAL_PATIENCE * CONFIG.stuck_steps):
        assert not p.stuck(CONFIG)
        p = goal_progress(p, match, (2.1, 3.0), CELL)  # 0.1 m closer: not progress
    assert p.stuck(CONFIG)
    assert goal_progress(p, match, (2.3, 3.0), CELL).since_progress == 0  # 0.3 m closer
    other = GoalMatch(6, 0.9, 3, LAMP)
    assert goal_progress(p, other, (2.1, 3.0), CELL).since_progress == 0  # a new match
    assert goal_progress(p, None, (2.1, 3.0), CELL) == GoalProgress()
