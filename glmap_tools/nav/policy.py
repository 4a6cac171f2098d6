"""`decide`: one step of a navigation policy over a GLMap (value map -> waypoint -> FMM plan).

Policies (the rows of the paper's Table 1): 'glmap' (instance and region units in Eq. 7),
'glmap-instance', 'glmap-region', 'egocentric' (VLFM-like: per-frame scores in the view
cone, no unit memory), 'frontier' (nearest frontier, FBE). All share the goal detector:
an instance whose score reaches `stop_threshold` after `min_observations` frames.

A step reads as the method: perceive (bump marks, surroundings, unit scores and the goal
match), the value map, choose a waypoint and plan to it (`nav/choose.py`), act, and only
then write what the step learnt into the episode's `NavState`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.map.occupancy import DenseOccupancy
from glmap_tools.nav.approach import Approach, approach, stop_would_count, unit_reach
from glmap_tools.nav.choose import (
    PROGRESS,
    Choice,
    PlanRequest,
    choose_and_plan,
    goal_progress,
    look_around,
)
from glmap_tools.nav.choose import progress as progress_of
from glmap_tools.nav.config import NavConfig, check_policy
from glmap_tools.nav.egocentric import EgocentricValueMap
from glmap_tools.nav.footprint import GoalMatch
from glmap_tools.nav.frontiers import Frontier
from glmap_tools.nav.motion import bump_cells, marks_near
from glmap_tools.nav.perceive import (
    FORGET_NEAR,
    SHORT_MOVE,
    Bump,
    Surroundings,
    bump_marks,
    find_goal_match,
    surroundings_of,
    unfit_goals,
    walls_of,
)
from glmap_tools.nav.planner import Plan
from glmap_tools.nav.scorers import EmbeddingScorer, Scorer, UnitText, check_goal, map_units
from glmap_tools.nav.state import NavState
from glmap_tools.nav.value import ValueMap, evidence_scores, value_map_from_scores
from glmap_tools.nav.verify import outvoted, outvoted_units, seen_share
from glmap_tools.nav.waypoint import Waypoint

if TYPE_CHECKING:
    from glmap_tools.map.glmap import GLMap

__all__ = [
    "PROGRESS",
    "Approach",
    "NavDecision",
    "NavState",
    "Surroundings",
    "approach",
    "decide",
    "stop_would_count",
    "surroundings",
    "unit_reach",
    "walls_of",
]

POLICY_UNITS = {"glmap": "both", "glmap-instance": "instances", "glmap-region": "regions"}
UNIT_KINDS = {"both": ("instance", "region"), "instances": ("instance",), "regions": ("region",)}


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
        evidence: what Eq. 7 stood on: 'units', 'region hint' or 'none'
            (`value.evidence_scores`); '' for the policies without Eq. 7.
    """

    action: str
    waypoint: Waypoint
    plan: Plan
    value: ValueMap | None
    frontiers: list[Frontier]
    matched_unit: int | None
    occupancy: DenseOccupancy
    scores: dict[int, float]
    evidence: str = ""


def surroundings(
    glmap: GLMap,
    xy: tuple[float, float],
    state: NavState,
    config: NavConfig,
    with_frontiers: bool = True,
) -> Surroundings:
    """The `Surroundings` of the agent at `xy`, the episode's bump marks as obstacles."""
    return surroundings_of(glmap, xy, state.blocked, config, with_frontiers)


@dataclass(frozen=True)
class Scored:
    """The map's units scored against the goal, the goal match among them, and the
    instances ruled out as goals (given up, unfit, or outvoted at their place)."""

    units: list[UnitText]
    by_id: dict[int, float]
    match: GoalMatch | None
    ruled_out: frozenset[int] = frozenset()


def _checked_pose(agent_xy: tuple[float, float], heading: float) -> tuple[float, float]:
    x, y = float(agent_xy[0]), float(agent_xy[1])
    if not all(math.isfinite(v) for v in (x, y, heading)):
        raise InvalidInputError(f"agent pose ({agent_xy!r}, heading {heading!r}) must be finite.")
    return x, y


def _perceive_surroundings(
    glmap: GLMap,
    xy: tuple[float, float],
    old: set[tuple[int, int]],
    bump: Bump,
    config: NavConfig,
) -> tuple[Surroundings, set[tuple[int, int]]]:
    """(surroundings, bump marks kept): bumps may have sealed the only way on (a doorway
    the map already draws narrow, a hall a bump's segment spans). The marks are let go a
    kind at a time before concluding there is nothing left to explore: the older ones, then
    this bump's segment (its contact cell kept), then all. Forgetting a fresh bump at once
    sent the agent into the same obstacle again and again (house-tune s01-006: 24 bumps in
    a row into a box below the camera's view)."""
    tries = [old | bump.cells, bump.cells, bump.contact, set()]
    for marks in dict.fromkeys(frozenset(t) for t in tries):  # each distinct set, in order
        sur = surroundings_of(glmap, xy, set(marks), config)
        if sur.fronts or not marks:
            break
    return sur, set(marks)


def _score_units(
    glmap: GLMap,
    goal: str,
    policy: str,
    scorer: Scorer,
    rejected: set[int],
    config: NavConfig,
    prefer: int | None = None,
    missed: dict[int, int] | None = None,
) -> Scored:
    """f_S of the units the policy reads, and the goal match among the instances (units
    the agent cannot be expected to recognise as goals left out; ties to `prefer`, the
    previous match, else to the lowest id). The glmap policies verify the match over the
    views the map fused (`nav/verify.py`): an outvoted candidate gives way to the next."""
    units = map_units(glmap, "instances" if policy not in ("glmap", "glmap-region") else "both")
    scores = scorer.score(goal, units) if units else np.zeros(0)
    unfit = set(unfit_goals(glmap)) if units else set()
    skip = set(unfit)
    match = find_goal_match(glmap, units, scores, rejected | skip, config, scorer, goal, prefer)
    while (
        policy in POLICY_UNITS
        and match is not None
        and _doubted(glmap, match, missed or {}, held=match.unit_id == prefer)
    ):
        skip.add(match.unit_id)
        match = find_goal_match(glmap, units, scores, rejected | skip, config, scorer, goal, prefer)
    by_id = {u.unit_id: float(v) for u, v in zip(units, scores, strict=True)}
    ruled_out = set(rejected) | unfit
    if policy in POLICY_UNITS:
        least = config.min_instance_score
        ruled_out |= outvoted_units(
            glmap,
            [
                u.unit_id
                for u in units
                if u.kind == "instance" and by_id[u.unit_id] >= least and u.unit_id not in ruled_out
            ],
        )
    return Scored(units, by_id, match, frozenset(ruled_out))


# The share of looks that must have seen a match; the one the agent already heads for keeps
# its place down to the lower share, so a unit seen in every other look while the agent turns
# does not swap with a frontier at each step (tune s02-006: 182 seen, 182 missed, the agent
# turned left and right for 300 steps beside the sofa).
SEEN_SHARE = 0.5
SEEN_SHARE_HELD = 0.4


def _doubted(glmap: GLMap, match: GoalMatch, missed: dict[int, int], held: bool = False) -> bool:
    """Whether a goal match fails the verification over fused views (`nav/verify.py`):
    outvoted at its place, or missed by most of the looks at it (`held`: the match the
    agent already heads for, by `SEEN_SHARE_HELD`)."""
    seen = seen_share(match.observations, missed.get(match.unit_id, 0))
    return seen < (SEEN_SHARE_HELD if held else SEEN_SHARE) or outvoted(glmap, match.unit_id)


def _unit_value_map(
    policy: str,
    glmap: GLMap,
    scored: Scored,
    occ: DenseOccupancy,
    config: NavConfig,
    missed: dict[int, int],
) -> tuple[ValueMap, str]:
    """(H, what it stands on): Eq. 7 over the units the policy keeps, each above its
    kind's least score; an instance's f_S is weighted by the share of the looks at it that
    saw it, and is 0 for an instance ruled out as a goal (`Scored.ruled_out`) or seen in
    fewer than `min_observations` frames."""
    keep = UNIT_KINDS[POLICY_UNITS[policy]]
    least = {"instance": config.min_instance_score, "region": config.min_region_score}
    # An instance ruled out as a goal draws nothing: a 9 cm "tv stand" or one outvoted by a
    # cabinet at its place kept the maximum of H for 400 steps (house-tune s01-000).
    by_id = {uid: (0.0 if uid in scored.ruled_out else s) for uid, s in scored.by_id.items()}
    for u in scored.units:
        # An instance draws only once seen as often as a match needs: one glimpse naming a
        # basket's top "a teal tv stand" pulled the agent to a false stop (house-tune s02-000).
        if u.kind == "instance" and u.observations < config.min_observations:
            by_id[u.unit_id] = 0.0
        elif u.kind == "instance" and u.unit_id in missed:
            by_id[u.unit_id] *= seen_share(u.observations, missed[u.unit_id])
    used, evidence = evidence_scores(scored.units, by_id, keep, least, config.region_hint)
    value = value_map_from_scores(
        used, glmap.grid, occ, config.value_sigma, unit_mass=config.unit_mass
    )
    return value, evidence


def _choose(
    glmap: GLMap,
    req: PlanRequest,
    blocked: set[tuple[int, int]],
    contact: set[tuple[int, int]],
) -> tuple[Choice, Surroundings, set[tuple[int, int]]]:
    """(choice, surroundings, bump marks kept): when no step is open, bump marks close by
    box the agent in: they are forgotten and the choice is made again, the fresh bump's
    `contact` cell last."""
    choice = choose_and_plan(req)
    if not choice.plan.boxed:
        return choice, req.sur, blocked
    near = marks_near(blocked, req.xy, req.sur.occ.cell_size, FORGET_NEAR)
    drops = [near - contact, near] if near & contact else [near]
    drops = [d for d in drops if d]
    sur = req.sur
    for drop in drops:
        kept = blocked - drop
        sur = surroundings_of(glmap, req.xy, kept, req.config)
        again = choose_and_plan(replace(req, sur=sur, avoid=choice.avoid))
        rejected = choice.rejected | again.rejected
        if not again.plan.boxed or drop is drops[-1]:
            return Choice(again.waypoint, again.plan, again.avoid, rejected), sur, kept
    return choice, req.sur, blocked


def _remember(
    state: NavState,
    choice: Choice,
    blocked: set[tuple[int, int]],
    xy: tuple[float, float],
    heading: float,
    config: NavConfig,
) -> None:
    """Write what the step learnt into the episode's state."""
    p = progress_of(
        state.last_waypoint,
        state.best_distance,
        state.since_progress,
        choice.waypoint,
        choice.plan,
        config,
    )
    spinning = state.steps >= config.initial_spin and choice.plan.action in (
        "turn_left",
        "turn_right",
    )
    stayed = state.last_xy is not None and math.dist(xy, state.last_xy) < SHORT_MOVE
    state.blocked = blocked
    state.avoid = list(choice.avoid) + ([p.give_up] if p.give_up is not None else [])
    state.rejected_units |= choice.rejected
    state.best_distance, state.since_progress = p.best_distance, p.since_progress
    state.turns_in_place = state.turns_in_place + 1 if spinning and stayed else 0
    state.last_waypoint, state.last_action = choice.waypoint, choice.plan.action
    state.last_xy, state.last_heading = xy, heading
    state.steps += 1


def _policy_value(
    policy: str,
    glmap: GLMap,
    scored: Scored,
    occ: DenseOccupancy,
    config: NavConfig,
    state: NavState,
) -> tuple[ValueMap | None, str]:
    """(the value map `policy` explores by, what it stands on): Eq. 7 over the units, the
    egocentric accumulator (kept in `state`), or none (frontier)."""
    if policy in POLICY_UNITS:
        return _unit_value_map(policy, glmap, scored, occ, config, state.missed)
    if policy == "egocentric":
        if state.egocentric is None:
            state.egocentric = EgocentricValueMap(glmap.grid.cell_size, glmap.config.max_range)
        return state.egocentric.as_value_map(occ), ""
    return None, ""


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
) -> NavDecision:
    """One step of `policy`: the next discrete action for the agent at `agent_xy`, `heading`.

    Args:
        glmap: the map built so far (this step's frame already integrated, and remembered
            in `state`: `nav.episode.observe`).
        agent_xy: (x, y) metres.
        heading: radians, counter-clockwise from +x.
        goal: goal description T_g.
        policy: one of POLICIES.
        scorer: f_S; default `EmbeddingScorer(glmap.embedder)` (kept in `state`).
        state: per-episode state; pass the same object every step (a fresh one if None).
        config: navigation settings.

    Raises:
        InvalidInputError: empty goal, unknown policy, non-finite pose.
    """
    goal = check_goal(goal)
    check_policy(policy)
    config = config or NavConfig()
    state = state if state is not None else NavState()
    xy = _checked_pose(agent_xy, heading)
    if scorer is None:
        if state.scorer is None:
            state.scorer = EmbeddingScorer(glmap.embedder)
        scorer = state.scorer

    # Perceive: bump marks, surroundings, unit scores and the goal match.
    bump = bump_marks(glmap, xy, state.last_action, state.last_xy, state.last_heading, config)
    sur, blocked = _perceive_surroundings(glmap, xy, state.blocked, bump, config)
    last = state.last_waypoint
    prefer = last.unit_id if last is not None and last.kind == "goal" else None
    missed = state.missed  # `nav.episode.remember` counts the looks
    scored = _score_units(glmap, goal, policy, scorer, state.rejected_units, config, prefer, missed)
    match = scored.match

    value, evidence = _policy_value(policy, glmap, scored, sur.occ, config, state)
    closing_in = goal_progress(state.goal_progress, match, xy, sur.occ.cell_size)

    # Choose a waypoint and plan to it.
    if state.steps < config.initial_spin and match is None:
        # A full turn first: the camera sees nothing closer than ~1.5 m of floor ahead and
        # nothing behind, so the first map is a narrow cone.
        waypoint, plan = look_around(xy, "looking around before the first move.")
        choice = Choice(waypoint, plan, tuple(state.avoid))
    else:
        walls = walls_of(glmap, sur.occ) if config.stop_in_sight and match is not None else None
        request = PlanRequest(
            value, sur, xy, heading, match, walls, config,
            state.last_waypoint, state.turns_in_place, tuple(state.avoid),
            goal_stuck=closing_in.stuck(config),
        )  # fmt: skip
        choice, sur, blocked = _choose(glmap, request, blocked, bump.contact)
        back_off = choice.plan.back_off
        if back_off is not None:
            # The plan leads where the body does not fit: mark it as a bump would, or the
            # agent steps back and the same plan brings it here again (house-tune s01-000:
            # 250 steps between two cells). A way no step can take closes across it
            # (`Plan.back_off_across`): one cell left the plan a way past it (house-tune
            # s02-004: 70 steps between two cells).
            across = choice.plan.back_off_across
            blocked = blocked | set(bump_cells(sur.occ, xy, back_off, config, across=across))

    # Act, and remember.
    state.goal_progress = closing_in
    _remember(state, choice, blocked, xy, heading, config)
    goal_unit = match.unit_id if match is not None and choice.waypoint.kind == "goal" else None
    return NavDecision(
        choice.plan.action,
        choice.waypoint,
        choice.plan,
        value,
        sur.fronts,
        goal_unit,
        sur.occ,
        scored.by_id,
        evidence,
    )
