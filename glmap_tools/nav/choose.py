"""Choose a waypoint and plan to it; give up waypoints the agent cannot reach or clear.

Pure steps over explicit inputs: `choose_and_plan` returns the choice together with the
waypoints and units it gave up, and `progress` says whether the agent still closes in on
its waypoint; `decide` (nav/policy.py) writes both into the episode's `NavState`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from glmap_tools.nav.config import NavConfig
from glmap_tools.nav.footprint import ROOM_WALL, GoalMatch, distance_to_cells, in_clear_sight
from glmap_tools.nav.perceive import Surroundings
from glmap_tools.nav.planner import Plan, plan_on_field
from glmap_tools.nav.value import ValueMap
from glmap_tools.nav.waypoint import Waypoint, choose_waypoint

PROGRESS = 0.25  # metres of progress toward the waypoint that reset the stuck counter
HOLD_AFTER_TURNS = 6  # turns in place after which the waypoint is held until the agent moves
ATTEMPTS = 8  # waypoints tried in one step before looking around
# Metres: a matched unit this close is never left for a stop with nothing to do; the agent
# stops for it instead (a give-up stop beside the goal lost episodes within reach).
MATCH_NEAR = 1.5
# x stuck_steps: steps without closing in on the matched unit after which the agent stops
# where a stop would count. Its goal cell may swap sides at every bump (two unseen boxes
# closing a pocket, house-tune s01-006: 350 steps 0 m from the goal by the success rule).
GOAL_PATIENCE = 2

XY = tuple[float, float]


@dataclass(frozen=True)
class PlanRequest:
    """Everything one waypoint choice reads.

    Attributes:
        value: the value map (None for policy 'frontier').
        sur: the agent's surroundings (occupancy window, reachability, frontiers).
        xy: the agent's (x, y), metres.
        heading: radians, counter-clockwise from +x.
        match: the instance matching the goal, if any.
        walls: structure wall cells over `sur.occ` (None: every obstacle is a wall).
        config: navigation settings.
        last_waypoint: the previous step's waypoint.
        turns_in_place: turns in a row without moving.
        avoid: (x, y) of waypoints given up so far.
        goal_stuck: the agent has not closed in on the match for `GOAL_PATIENCE` x
            `stuck_steps` steps (`goal_progress`).
    """

    value: ValueMap | None
    sur: Surroundings
    xy: XY
    heading: float
    match: GoalMatch | None
    walls: np.ndarray | None
    config: NavConfig
    last_waypoint: Waypoint | None
    turns_in_place: int
    avoid: tuple[XY, ...]
    goal_stuck: bool = False


@dataclass(frozen=True)
class Choice:
    """A waypoint, the plan to it, and what choosing them gave up.

    Attributes:
        waypoint: where the agent heads.
        plan: the FMM plan to it.
        avoid: the waypoints given up after this choice (replaces the request's).
        rejected: matched instances found unreachable.
    """

    waypoint: Waypoint
    plan: Plan
    avoid: tuple[XY, ...]
    rejected: frozenset[int] = frozenset()


def plan_to(sur: Surroundings, xy: XY, heading: float, goal: XY, config: NavConfig) -> Plan:
    """The FMM plan from `xy` to `goal` over the surroundings' distance field."""
    return plan_on_field(sur.occ, sur.field, xy, heading, goal, config, sur.clear, sur.plannable)


def plan_to_goal_cell(
    sur: Surroundings, xy: XY, heading: float, wp: Waypoint, config: NavConfig
) -> Plan:
    """`plan_to` a goal waypoint away from the agent (the waypoint rule says the agent does
    not stand where a stop counts): arrived within half a step of it, the agent still steps
    on to it rather than stop where the rule said no (tune s00-004: stopped behind a wall
    0.1 m from a cell in sight of the lamp)."""
    assert wp.xy is not None
    out = plan_to(sur, xy, heading, wp.xy, config)
    if out.action != "stop" or wp.xy == xy:
        return out
    return plan_on_field(
        sur.occ, sur.field, xy, heading, wp.xy, config, sur.clear, sur.plannable, arrive=0.0
    )


def look_around(xy: XY, reason: str) -> tuple[Waypoint, Plan]:
    """Turn in place: the waypoint is where the agent stands."""
    return Waypoint(xy, "explore", None, 0.0, reason), Plan(
        np.array([xy]), 0.0, "turn_left", False, xy
    )


def _stop_for(match: GoalMatch, req: PlanRequest, why: str) -> Choice:
    """Stop where the agent stands, for the matched unit."""
    xy = req.xy
    here = distance_to_cells(match.cells, xy, req.sur.occ.cell_size)
    reason = f"instance {match.unit_id} matches the goal and is {here:.2f} m away: {why}"
    wp = Waypoint(xy, "goal", match.unit_id, match.score, reason)
    return Choice(wp, Plan(np.array([xy]), 0.0, "stop", True, xy), req.avoid)


def stop_would_count_here(match: GoalMatch, req: PlanRequest) -> bool:
    """The simulator's success rule read on the map at the agent: within `success_radius`
    of the unit's cells with no wall of the map on the line to them."""
    occ = req.sur.occ
    if distance_to_cells(match.cells, req.xy, occ.cell_size) > req.config.success_radius:
        return False
    rc = np.array(occ.world_to_index(*req.xy))[None]
    return bool(in_clear_sight(match, occ, rc, req.walls)[0])


def _held(req: PlanRequest) -> Choice | None:
    """The previous frontier waypoint, kept after `HOLD_AFTER_TURNS` turns in place with no
    match while it can be reached: a value map that changes with every view (the egocentric
    one, or units seen for the first time while turning) must not turn the agent round for
    ever (tune s03-019, egocentric: 477 turns in a row)."""
    last = req.last_waypoint
    if (
        req.turns_in_place < HOLD_AFTER_TURNS
        or req.match is not None
        or last is None
        or last.kind != "frontier"
        or last.xy is None
    ):
        return None
    held = plan_to(req.sur, req.xy, req.heading, last.xy, req.config)
    if held.reachable and held.action != "stop":
        return Choice(last, held, req.avoid)
    return None


def choose_and_plan(req: PlanRequest) -> Choice:
    """Choose a waypoint and plan to it; a frontier reached without effect is given up.

    Up to `ATTEMPTS` waypoints are tried: an unreachable goal rejects its instance, a
    frontier the plan says is reached is avoided from then on, and when every frontier was
    given up once they all get another chance.
    """
    held = _held(req)
    if held is not None:
        return held
    if req.goal_stuck and req.match is not None:
        # The way to the cells in sight failed: sight is read as when none can be reached,
        # only room walls block (the structure between may be furniture the detector missed).
        rooms = None if req.walls is None else np.where(req.walls >= ROOM_WALL, req.walls, 0)
        if stop_would_count_here(req.match, replace(req, walls=rooms)):
            why = "the agent came no closer to it for a while, and a stop here would count."
            return _stop_for(req.match, req, why)
    sur, xy, config = req.sur, req.xy, req.config
    avoid, rejected, match = list(req.avoid), set[int](), req.match
    for _ in range(ATTEMPTS):
        wp = choose_waypoint(
            req.value,
            sur.fronts,
            sur.trav,
            xy,
            match,
            config,
            occ=sur.occ,
            distance=sur.field.metres,
            avoid=avoid,
            walls=req.walls,
        )
        if wp.xy is None and avoid and sur.fronts:
            avoid.clear()  # every frontier was given up once: give them another chance
            continue
        if wp.xy is None and sur.fronts:
            # Frontiers the planner cannot reach yet (a pinch left by bumps): look around.
            waypoint, plan = look_around(xy, "no frontier can be reached: look around.")
            return Choice(waypoint, plan, tuple(avoid), frozenset(rejected))
        if (
            wp.xy is None
            and req.match is not None
            and (distance_to_cells(req.match.cells, xy, sur.occ.cell_size) <= MATCH_NEAR)
        ):
            done = _stop_for(req.match, req, "nothing else is left to do, so stop here.")
            return replace(done, avoid=tuple(avoid), rejected=frozenset(rejected))
        if wp.xy is None:
            plan = Plan(np.zeros((0, 2)), math.inf, "stop", False, xy)
            return Choice(wp, plan, tuple(avoid), frozenset(rejected))
        if wp.kind == "goal" and wp.xy == xy:
            plan = Plan(np.array([xy]), 0.0, "stop", True, xy)
            return Choice(wp, plan, tuple(avoid), frozenset(rejected))
        if wp.kind == "goal":
            out = plan_to_goal_cell(sur, xy, req.heading, wp, config)
        else:
            out = plan_to(sur, xy, req.heading, wp.xy, config)
        if wp.kind == "goal" and not out.reachable:
            assert match is not None
            if stop_would_count_here(match, req):
                why = "its cells near it cannot be reached, and a stop here would count."
                return replace(_stop_for(match, req, why), avoid=tuple(avoid))
            rejected.add(match.unit_id)
            match = None
            continue
        if out.action == "stop" and wp.kind != "goal":
            avoid.append(wp.xy)  # reached, yet still a frontier: look elsewhere
            continue
        return Choice(wp, out, tuple(avoid), frozenset(rejected))
    waypoint, plan = look_around(xy, "every nearby waypoint was given up: look around.")
    return Choice(waypoint, plan, tuple(avoid), frozenset(rejected))


@dataclass(frozen=True)
class Progress:
    """How the agent closes in on its waypoint.

    Attributes:
        best_distance: the shortest plan length to this waypoint so far, metres.
        since_progress: steps since the plan last got `PROGRESS` m shorter.
        give_up: the waypoint to avoid from now on (stuck), or None.
    """

    best_distance: float
    since_progress: int
    give_up: XY | None = None


def progress(
    last: Waypoint | None,
    best_distance: float,
    since_progress: int,
    wp: Waypoint,
    out: Plan,
    config: NavConfig,
) -> Progress:
    """Give up a waypoint the agent has not come `PROGRESS` m closer to in `stuck_steps` steps.

    Args:
        last: the previous step's waypoint.
        best_distance: the previous `Progress.best_distance`.
        since_progress: the previous `Progress.since_progress`.
        wp: this step's waypoint.
        out: the plan to it.
        config: navigation settings.
    """
    same = (
        last is not None
        and wp.xy is not None
        and last.xy is not None
        and math.hypot(wp.xy[0] - last.xy[0], wp.xy[1] - last.xy[1]) < config.stop_distance
    )
    if not same or out.length < best_distance - PROGRESS:
        return Progress(out.length, 0)
    since_progress += 1
    if since_progress >= config.stuck_steps and wp.xy is not None and wp.kind != "goal":
        return Progress(math.inf, 0, wp.xy)
    return Progress(best_distance, since_progress)


@dataclass(frozen=True)
class GoalProgress:
    """How the agent closes in on the matched unit itself (not on its goal cell, which can
    move to another side of the unit when a bump closes the way).

    Attributes:
        unit_id: the matched instance (None without a match).
        best_distance: the agent's shortest distance to its cells so far, metres.
        since_progress: steps since that distance last shrank by `PROGRESS` m.
    """

    unit_id: int | None = None
    best_distance: float = math.inf
    since_progress: int = 0

    def stuck(self, config: NavConfig) -> bool:
        return self.since_progress >= GOAL_PATIENCE * config.stuck_steps


def goal_progress(
    last: GoalProgress, match: GoalMatch | None, xy: XY, cell_size: float
) -> GoalProgress:
    """`last` brought up to this step: a new match starts afresh, a step `PROGRESS` m closer
    to the match's cells resets the count."""
    if match is None:
        return GoalProgress()
    here = distance_to_cells(match.cells, xy, cell_size)
    if match.unit_id != last.unit_id or here < last.best_distance - PROGRESS:
        return GoalProgress(match.unit_id, here, 0)
    return GoalProgress(match.unit_id, last.best_distance, last.since_progress + 1)
