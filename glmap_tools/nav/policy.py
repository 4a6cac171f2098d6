"""`decide`: one step of a navigation policy over a GLMap (value map -> waypoint -> FMM plan).

Policies (the rows of the paper's Table 1): 'glmap' (instance and region units in Eq. 7),
'glmap-instance', 'glmap-region', 'egocentric' (VLFM-like: per-frame scores in the view
cone, no unit memory), 'frontier' (nearest frontier, FBE). All share the goal detector:
an instance whose score reaches `stop_threshold` after `min_observations` frames.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.map.occupancy import OBSTACLE, DenseOccupancy
from glmap_tools.nav.config import NavConfig, check_policy
from glmap_tools.nav.egocentric import EgocentricValueMap
from glmap_tools.nav.frontiers import Frontier, frontiers
from glmap_tools.nav.grid import agent_rc, known_window, reframe, structure_walls
from glmap_tools.nav.motion import bump_cells, clearance, forget_marks_near, masks
from glmap_tools.nav.planner import DistanceField, Plan, distance_field, plan_on_field
from glmap_tools.nav.scorers import EmbeddingScorer, Scorer, UnitText, check_goal, map_units
from glmap_tools.nav.value import ValueMap, unit_cell_array, value_map_from_scores
from glmap_tools.nav.waypoint import GoalMatch, Waypoint, choose_waypoint

if TYPE_CHECKING:
    from glmap_tools.geometry.frame import RGBDFrame
    from glmap_tools.map.glmap import GLMap
    from glmap_tools.perception.semantics import FrameSemantics

POLICY_UNITS = {"glmap": "both", "glmap-instance": "instances", "glmap-region": "regions"}
PROGRESS = 0.25  # metres of progress toward the waypoint that reset the stuck counter
SHORT_MOVE = 0.0125  # metres: a move_forward this much short of a full step was stopped
FORGET_NEAR = 0.5  # metres: bump marks this close are forgotten when no step is open
HOLD_AFTER_TURNS = 6  # turns in place after which the waypoint is held until the agent moves


@dataclass
class NavState:
    """Per-episode memory of a policy: the egocentric map, given-up waypoints, bump marks.

    Attributes:
        egocentric: the VLFM-like accumulator (policy 'egocentric' only).
        avoid: (x, y) of waypoints given up (stuck, or reached without clearing them).
        rejected_units: matched instances given up (no way to reach them).
        blocked: (i, j) cells where a forward move was stopped (obstacles the map missed);
            they stay obstacles for the episode (`nav.motion.bump_cells`).
        last_waypoint: the previous step's waypoint.
        turns_in_place: turns in a row without moving, after the initial look around.
        steps: decisions taken.
    """

    egocentric: EgocentricValueMap | None = None
    avoid: list[tuple[float, float]] = field(default_factory=list)
    rejected_units: set[int] = field(default_factory=set)
    blocked: set[tuple[int, int]] = field(default_factory=set)
    last_waypoint: Waypoint | None = None
    last_action: str | None = None
    last_xy: tuple[float, float] | None = None
    last_heading: float = 0.0
    best_distance: float = math.inf
    since_progress: int = 0
    turns_in_place: int = 0
    steps: int = 0
    scorer: Scorer | None = None


@dataclass(frozen=True)
class NavDecision:
    """What `decide` chose, with everything it looked at (for reports and tools).

    Attributes:
        action: 'move_forward' | 'turn_left' | 'turn_right' | 'stop'.
        waypoint: the chosen waypoint.
        plan: the FMM plan to it.
        value: the value map used (None for 'frontier').
        frontiers: reachable frontiers, nearest first.
        matched_unit: the instance matching the goal, if any.
        occupancy: the occupancy window everything is over.
        scores: unit id -> s_u of the units scored this step.
    """

    action: str
    waypoint: Waypoint
    plan: Plan
    value: ValueMap | None
    frontiers: list[Frontier]
    matched_unit: int | None
    occupancy: DenseOccupancy
    scores: dict[int, float]


def _bump(state: NavState, occ: DenseOccupancy, xy: tuple[float, float], config: NavConfig) -> bool:
    """After a forward move the simulator stopped short, mark where the body touched
    (`nav.motion.bump_cells`); True when cells were added."""
    if state.last_action != "move_forward" or state.last_xy is None:
        return False
    moved = math.dist(xy, state.last_xy)
    if moved >= config.forward_step - SHORT_MOVE:
        return False
    before = len(state.blocked)
    state.blocked.update(bump_cells(occ, xy, state.last_heading, config))
    return len(state.blocked) > before


def _window(
    glmap: GLMap, agent_xy: tuple[float, float], state: NavState, config: NavConfig
) -> DenseOccupancy:
    dense = glmap.occupancy.to_dense()
    margin = math.ceil(config.window_margin / dense.cell_size)
    occ = reframe(dense, known_window(dense, margin, agent_xy))
    if state.blocked:
        cells = np.array(sorted(state.blocked), dtype=np.int64)
        r, c = cells[:, 1] - occ.origin[1], cells[:, 0] - occ.origin[0]
        h, w = occ.state.shape
        keep = (r >= 0) & (r < h) & (c >= 0) & (c < w)
        occ.state[r[keep], c[keep]] = OBSTACLE
    return occ


@dataclass(frozen=True)
class Surroundings:
    """The occupancy window (bump marks included) around the agent and what is derived
    from it: clearance, traversable cells, (plannable, speed), distance field, frontiers."""

    occ: DenseOccupancy
    clear: np.ndarray
    trav: np.ndarray
    plannable: tuple[np.ndarray, np.ndarray]
    field: DistanceField
    fronts: list[Frontier]


def surroundings(
    glmap: GLMap,
    xy: tuple[float, float],
    state: NavState,
    config: NavConfig,
    with_frontiers: bool = True,
) -> Surroundings:
    """The `Surroundings` of the agent at `xy` (no frontiers unless `with_frontiers`)."""
    occ = _window(glmap, xy, state, config)
    clear = clearance(occ)
    rc = agent_rc(occ, xy)
    trav, ok, speed = masks(occ, clear, rc, config)
    field = distance_field(occ, ok, rc, config.plan_stride, config.optimistic, speed)
    fronts = (
        frontiers(occ, xy, config.agent_radius, config.min_frontier_size, field.metres, trav=trav)
        if with_frontiers
        else []
    )
    return Surroundings(occ, clear, trav, (ok, speed), field, fronts)


def find_goal_match(
    glmap: GLMap,
    units: list[UnitText],
    scores: np.ndarray,
    state: NavState,
    config: NavConfig,
    scorer: Scorer | None = None,
    goal: str = "",
) -> GoalMatch | None:
    """The best-scoring instance at or above the stop threshold with enough observations.

    With `config.category_margin` set and a scorer that has `category_margins`, a candidate
    must instead score `config.category_threshold` and be closer to the goal than to any
    other label of the map by that margin (a category goal: "cabinet", not "kitchen cabinet").
    """
    margins = getattr(scorer, "category_margins", None)
    by_category = config.category_margin is not None and margins is not None
    threshold = config.category_threshold if by_category else config.stop_threshold
    cand = [
        (u, float(s))
        for u, s in zip(units, scores, strict=True)
        if u.kind == "instance"
        and u.unit_id not in state.rejected_units
        and s >= threshold
        and u.observations >= config.min_observations
    ]
    if cand and by_category:
        assert margins is not None and config.category_margin is not None
        vocabulary = [u.label for u in units if u.kind == "instance"]
        m = margins(goal, [u for u, _ in cand], vocabulary)
        cand = [c for c, v in zip(cand, m, strict=True) if v >= config.category_margin]
    best: GoalMatch | None = None
    for u, s in cand:
        if best is None or s > best.score:
            best = GoalMatch(
                u.unit_id, float(s), u.observations, unit_cell_array(glmap.grid, u.unit_id)
            )
    return best


def _frame_score(
    glmap: GLMap, goal: str, scorer: Scorer, semantics: FrameSemantics | None
) -> float:
    """What the current frame shows, scored against the goal: the best of its objects/groups."""
    if semantics is not None:
        texts = [o.description or o.label for o in semantics.objects]
        texts += [g.description for g in semantics.groups]
        units = [UnitText(-1, "instance", t) for t in texts if t.strip()]
    else:
        last = len(glmap.trajectory) - 1
        units = [
            u
            for u in map_units(glmap, "instances")
            if glmap.instances[u.unit_id].last_frame == last
        ]
    if not units:
        return 0.0
    return float(np.max(scorer.score(goal, units)))


def decide(
    glmap: GLMap,
    agent_xy: tuple[float, float],
    heading: float,
    goal: str,
    *,
    policy: str = "glmap",
    scorer: Scorer | None = None,
    state: NavState | None = None,
    config: NavConfig | None = None,
    frame: RGBDFrame | None = None,
    semantics: FrameSemantics | None = None,
) -> NavDecision:
    """One step of `policy`: the next discrete action for the agent at `agent_xy`, `heading`.

    Args:
        glmap: the map built so far (this step's frame already integrated).
        agent_xy: (x, y) metres.
        heading: radians, counter-clockwise from +x.
        goal: goal description T_g.
        policy: one of POLICIES.
        scorer: f_S; default `EmbeddingScorer(glmap.embedder)` (kept in `state`).
        state: per-episode state; pass the same object every step (a fresh one if None).
        config: navigation settings.
        frame: this step's frame (policy 'egocentric' projects it into its view cone).
        semantics: this frame's semantics, scored for the egocentric frame score (default:
            the instances the latest frame observed).

    Raises:
        InvalidInputError: empty goal, unknown policy, non-finite pose.
    """
    goal = check_goal(goal)
    check_policy(policy)
    config = config or NavConfig()
    state = state if state is not None else NavState()
    x, y = float(agent_xy[0]), float(agent_xy[1])
    if not all(math.isfinite(v) for v in (x, y, heading)):
        raise InvalidInputError(f"agent pose ({agent_xy!r}, heading {heading!r}) must be finite.")
    xy = (x, y)
    if scorer is None:
        if state.scorer is None:
            state.scorer = EmbeddingScorer(glmap.embedder)
        scorer = state.scorer
    s = glmap.grid.cell_size
    if state.last_action == "move_forward":
        _bump(state, _window(glmap, xy, NavState(), config), xy, config)

    sur = surroundings(glmap, xy, state, config)
    if not sur.fronts and state.blocked:
        # Bumps may have sealed the only way on (a doorway the map already draws narrow):
        # forget them before concluding there is nothing left to explore.
        state.blocked.clear()
        sur = surroundings(glmap, xy, state, config)
    occ = sur.occ

    units = map_units(glmap, "instances" if policy not in ("glmap", "glmap-region") else "both")
    scores = scorer.score(goal, units) if units else np.zeros(0)
    match = find_goal_match(glmap, units, scores, state, config, scorer, goal)
    by_id = {u.unit_id: float(v) for u, v in zip(units, scores, strict=True)}

    value: ValueMap | None = None
    if policy in POLICY_UNITS:
        kinds = {"both": ("instance", "region"), "instances": ("instance",), "regions": ("region",)}
        keep = kinds[POLICY_UNITS[policy]]
        least = {"instance": config.min_instance_score, "region": config.min_region_score}
        used = {
            u.unit_id: by_id[u.unit_id]
            for u in units
            if u.kind in keep and by_id[u.unit_id] >= least[u.kind]
        }
        value = value_map_from_scores(
            used, glmap.grid, occ, config.value_sigma, unit_mass=config.unit_mass
        )
    elif policy == "egocentric":
        if state.egocentric is None:
            state.egocentric = EgocentricValueMap(s, glmap.config.max_range)
        if frame is not None:
            state.egocentric.add_frame(frame, _frame_score(glmap, goal, scorer, semantics))
        value = state.egocentric.as_value_map(occ)

    if state.steps < config.initial_spin and match is None:
        # A full turn first: the camera sees nothing closer than ~1.5 m of floor ahead and
        # nothing behind, so the first map is a narrow cone.
        waypoint = Waypoint(xy, "explore", None, 0.0, "looking around before the first move.")
        out = Plan(np.array([xy]), 0.0, "turn_left", False, xy)
    else:
        walls = None
        if config.stop_in_sight and match is not None:
            walls = walls_of(glmap, occ)
        waypoint, out = _choose_and_plan(value, sur, xy, heading, match, state, config, walls)
        if out.boxed and forget_marks_near(state.blocked, xy, s, FORGET_NEAR):
            # No step is open: bump marks close by box the agent in; forget them and replan.
            sur = surroundings(glmap, xy, state, config)
            waypoint, out = _choose_and_plan(value, sur, xy, heading, match, state, config, walls)
    _track_progress(state, waypoint, out, config)
    spinning = state.steps >= config.initial_spin and out.action in ("turn_left", "turn_right")
    stayed = state.last_xy is not None and math.dist(xy, state.last_xy) < SHORT_MOVE
    state.turns_in_place = state.turns_in_place + 1 if spinning and stayed else 0
    state.last_waypoint, state.last_action = waypoint, out.action
    state.last_xy, state.last_heading = xy, heading
    state.steps += 1
    return NavDecision(
        out.action,
        waypoint,
        out,
        value,
        sur.fronts,
        match.unit_id if match is not None and waypoint.kind == "goal" else None,
        sur.occ,
        by_id,
    )


def walls_of(glmap: GLMap, occ: DenseOccupancy) -> np.ndarray | None:
    """The structure obstacle cells over `occ` (None: the map keeps no structure, so every
    obstacle cell counts as a wall)."""
    if len(glmap.structure) == 0 or glmap.floor_z is None:
        return None
    means = glmap.structure.gaussians().means
    return structure_walls(means, glmap.floor_z, glmap.config.obstacle_band, occ)


def _plan(
    sur: Surroundings,
    xy: tuple[float, float],
    heading: float,
    goal: tuple[float, float],
    config: NavConfig,
) -> Plan:
    return plan_on_field(sur.occ, sur.field, xy, heading, goal, config, sur.clear, sur.plannable)


def _choose_and_plan(
    value: ValueMap | None,
    sur: Surroundings,
    xy: tuple[float, float],
    heading: float,
    match: GoalMatch | None,
    state: NavState,
    config: NavConfig,
    walls: np.ndarray | None = None,
) -> tuple[Waypoint, Plan]:
    """Choose a waypoint and plan to it; a frontier reached without effect is given up.

    After `HOLD_AFTER_TURNS` turns in place with no match, the previous frontier waypoint is
    kept while it can be reached: a value map that changes with every view (the egocentric
    one, or units seen for the first time while turning) must not turn the agent round
    for ever (tune s03-019, egocentric: 477 turns in a row).
    """
    last = state.last_waypoint
    if (
        state.turns_in_place >= HOLD_AFTER_TURNS
        and match is None
        and last is not None
        and last.kind == "frontier"
        and last.xy is not None
    ):
        held = _plan(sur, xy, heading, last.xy, config)
        if held.reachable and held.action != "stop":
            return last, held
    for _ in range(8):
        wp = choose_waypoint(
            value,
            sur.fronts,
            sur.trav,
            xy,
            match,
            config,
            occ=sur.occ,
            distance=sur.field.metres,
            avoid=state.avoid,
            walls=walls,
        )
        if wp.xy is None and state.avoid and sur.fronts:
            state.avoid.clear()  # every frontier was given up once: give them another chance
            continue
        if wp.xy is None and sur.fronts:
            # Frontiers the planner cannot reach yet (a pinch left by bumps): look around.
            look = Waypoint(xy, "explore", None, 0.0, "no frontier can be reached: look around.")
            return look, Plan(np.array([xy]), 0.0, "turn_left", False, xy)
        if wp.xy is None:
            return wp, Plan(np.zeros((0, 2)), math.inf, "stop", False, xy)
        if wp.kind == "goal" and wp.xy == xy:
            return wp, Plan(np.array([xy]), 0.0, "stop", True, xy)
        out = _plan(sur, xy, heading, wp.xy, config)
        if wp.kind == "goal" and not out.reachable:
            assert match is not None
            state.rejected_units.add(match.unit_id)
            match = None
            continue
        if out.action == "stop" and wp.kind != "goal":
            state.avoid.append(wp.xy)  # reached, yet still a frontier: look elsewhere
            continue
        return wp, out
    look = Waypoint(xy, "explore", None, 0.0, "every nearby waypoint was given up: look around.")
    return look, Plan(np.array([xy]), 0.0, "turn_left", False, xy)


def _track_progress(state: NavState, wp: Waypoint, out: Plan, config: NavConfig) -> None:
    """Give up a waypoint the agent has not come `PROGRESS` m closer to in `stuck_steps` steps."""
    last = state.last_waypoint
    same = (
        last is not None
        and wp.xy is not None
        and last.xy is not None
        and math.hypot(wp.xy[0] - last.xy[0], wp.xy[1] - last.xy[1]) < config.stop_distance
    )
    if not same or out.length < state.best_distance - PROGRESS:
        state.best_distance = out.length
        state.since_progress = 0
        return
    state.since_progress += 1
    if state.since_progress >= config.stuck_steps and wp.xy is not None and wp.kind != "goal":
        state.avoid.append(wp.xy)
        state.since_progress = 0
        state.best_distance = math.inf


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
    if state.last_action == "move_forward":
        _bump(state, _window(glmap, xy, NavState(), config), xy, config)
    sur = surroundings(glmap, xy, state, config, with_frontiers=False)
    step = _approach(glmap, sur, xy, heading, target, config)
    if step.plan.boxed and forget_marks_near(state.blocked, xy, sur.occ.cell_size, FORGET_NEAR):
        sur = surroundings(glmap, xy, state, config, with_frontiers=False)
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
    from glmap_tools.nav.waypoint import distance_to_cells, in_clear_sight

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
        out = _plan(sur, xy, heading, target, config)
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
        out = _plan(sur, xy, heading, wp.xy, config)
        if out.reachable:
            return Approach(out.action, out, out.goal_xy, False, here, in_sight, wp.reason)
    # No cell near the unit can be reached yet: head for its nearest reachable point.
    centre = (target.cells.mean(axis=0) + 0.5) * sur.occ.cell_size
    out = _plan(sur, xy, heading, (float(centre[0]), float(centre[1])), config)
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
