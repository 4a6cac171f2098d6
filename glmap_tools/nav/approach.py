"""`approach`: walk to a unit or a point with the policy's motion, the goal fixed by the caller."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from glmap_tools.map.occupancy import DenseOccupancy
from glmap_tools.nav.choose import plan_to, plan_to_goal_cell
from glmap_tools.nav.config import NavConfig
from glmap_tools.nav.footprint import GoalMatch, distance_to_cells, in_clear_sight
from glmap_tools.nav.grid import agent_rc
from glmap_tools.nav.motion import forget_marks_near
from glmap_tools.nav.perceive import (
    FORGET_NEAR,
    Surroundings,
    bump_marks,
    surroundings_of,
    walls_of,
)
from glmap_tools.nav.planner import Plan
from glmap_tools.nav.waypoint import choose_waypoint

if TYPE_CHECKING:
    from glmap_tools.map.glmap import GLMap
    from glmap_tools.nav.state import NavState


@dataclass(frozen=True)
class Approach:
    """One step of walking to a unit or a point (`approach`).

    Attributes:
        action: the next action; 'stop' when arrived or when no step leads closer.
        plan: the plan to `aim`.
        aim: (x, y) the plan heads for: for a unit, a free cell within `stop_distance` of
            its cells in clear sight of it (the success rule with a margin); for a point,
            the point; either way its nearest reachable cell when it cannot be reached.
        arrived: the agent stands where it was sent (a unit: within `stop_distance` of its
            cells and in clear sight of them; a point: within one forward step).
        unit_distance: planar metres from the agent to the unit's cells (nan for a point).
        in_sight: no wall of the map on the straight line to the unit (True for a point).
        reason: one sentence saying where the walk heads and why.
    """

    action: str
    plan: Plan
    aim: tuple[float, float] | None
    arrived: bool
    unit_distance: float
    in_sight: bool
    reason: str


def approach(
    glmap: GLMap,
    agent_xy: tuple[float, float],
    heading: float,
    target: GoalMatch | tuple[float, float],
    state: NavState,
    config: NavConfig,
) -> Approach:
    """The next action towards `target`: a unit (as a `GoalMatch`) or a point (x, y).

    The same motion as `decide` (bump marks, clearance cost, the `drive` controller) with
    the goal fixed by the caller: a unit is approached as the policy approaches a matched
    goal, to a cell within `stop_distance` of it in clear sight; when none can be reached
    yet, the plan heads for the unit's nearest reachable point.
    """
    xy = (float(agent_xy[0]), float(agent_xy[1]))
    state.blocked |= bump_marks(
        glmap, xy, state.last_action, state.last_xy, state.last_heading, config
    ).cells
    sur = surroundings_of(glmap, xy, state.blocked, config, with_frontiers=False)
    step = _approach(glmap, sur, xy, heading, target, config)
    if step.plan.boxed and forget_marks_near(state.blocked, xy, sur.occ.cell_size, FORGET_NEAR):
        sur = surroundings_of(glmap, xy, state.blocked, config, with_frontiers=False)
        step = _approach(glmap, sur, xy, heading, target, config)
    state.last_action, state.last_xy, state.last_heading = step.action, xy, heading
    return step


def unit_reach(
    occ: DenseOccupancy, unit: GoalMatch, xy: tuple[float, float], walls: np.ndarray | None
) -> tuple[float, bool]:
    """(planar metres from `xy` to the unit's cells, no wall on the straight line to them):
    what the simulator's success rule asks of a stop, read on the map.

    `walls`: `walls_of(glmap, occ)` (None: every obstacle cell blocks the line).
    """
    here = distance_to_cells(unit.cells, xy, occ.cell_size)
    sight = in_clear_sight(unit, occ, np.array([agent_rc(occ, xy)]), walls)
    return here, bool(sight[0])


def stop_would_count(unit_distance: float, in_sight: bool, config: NavConfig) -> bool:
    """The simulator's success rule read on the map: within `success_radius` of the unit's
    cells, with no wall on the line to them."""
    return bool(unit_distance <= config.success_radius and in_sight)


def _approach(
    glmap: GLMap,
    sur: Surroundings,
    xy: tuple[float, float],
    heading: float,
    target: GoalMatch | tuple[float, float],
    config: NavConfig,
) -> Approach:
    if not isinstance(target, GoalMatch):
        out = plan_to(sur, xy, heading, target, config)
        # Within one step is there: 30-degree turns and 0.25 m steps cannot always land
        # closer, and circling to try costs more than the step it saves.
        arrived = math.dist(xy, target) <= config.forward_step
        near_end = math.dist(xy, out.goal_xy) <= config.forward_step
        why = "the point" if out.reachable else "the nearest reachable point of the point"
        return Approach(
            "stop" if arrived or near_end else out.action,
            out,
            out.goal_xy,
            arrived,
            math.nan,
            True,
            f"heading to {why}.",
        )
    walls = walls_of(glmap, sur.occ) if config.stop_in_sight else None
    here, in_sight = unit_reach(sur.occ, target, xy, walls)
    wp = choose_waypoint(
        None, [], sur.trav, xy, target, config, occ=sur.occ, distance=sur.field.metres, walls=walls
    )
    if wp.kind == "goal" and wp.xy == xy:
        return Approach(
            "stop", Plan(np.array([xy]), 0.0, "stop", True, xy), xy, True, here, in_sight, wp.reason
        )
    if wp.kind == "goal" and wp.xy is not None:
        out = plan_to_goal_cell(sur, xy, heading, wp, config)
        if out.reachable:
            return Approach(out.action, out, out.goal_xy, False, here, in_sight, wp.reason)
    # No cell near the unit can be reached yet: head for its nearest reachable point.
    centre = (target.cells.mean(axis=0) + 0.5) * sur.occ.cell_size
    out = plan_to(sur, xy, heading, (float(centre[0]), float(centre[1])), config)
    return Approach(
        out.action,
        out,
        out.goal_xy if len(out.path) else None,
        False,
        here,
        in_sight,
        f"no free cell within {config.stop_distance:.2f} m of unit {target.unit_id} in clear "
        "sight of it can be reached on the map yet: heading for its nearest reachable point.",
    )
