"""The policy's decision on a session's map, and what the navigation tools report of it:
the waypoint, the evidence the value map stands on, the best-scored units, the matched goal
unit, one unit's score, the drawing."""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

from glmap_tools.app import nav_steps
from glmap_tools.app.nav_session import NavSession
from glmap_tools.app.navdraw import nav_image
from glmap_tools.app.session import Session, locked
from glmap_tools.app.sim_results import GoalUnit, UnitScore, Waypoint
from glmap_tools.errors import InvalidInputError

if TYPE_CHECKING:
    from glmap_tools.nav import NavConfig, NavDecision

# Imports inside functions stay there: language.embed, scipy, numba load on first use: the tools
# load before these do, in the server and the in-process toolset alike.


def episode_config(session: Session) -> NavConfig:
    """The episode's NavConfig, or the defaults without an episode."""
    from glmap_tools.nav import NavConfig

    nav = nav_steps.of(session)
    return nav.config if nav is not None else NavConfig()


def goal_text(session: Session, goal: str) -> str:
    if goal.strip():
        return goal.strip()
    nav = nav_steps.of(session)
    if nav is None:
        raise InvalidInputError(
            "no goal: pass goal='a sofa' (or start a simulator episode with sim_reset, whose "
            "goal is used by default)."
        )
    return str(nav.goal)


def current_agent(session: Session) -> tuple[float, float, float]:
    with locked(session) as glmap:
        agent = nav_steps.agent_pose(session, glmap)
    if agent is None:
        raise InvalidInputError(
            "the map is empty: observe a frame (observe_frame) or start sim_reset first."
        )
    return agent


def decide_on_map(
    session: Session, goal: str, policy: str, *, act: bool = True
) -> tuple[NavDecision, tuple[float, float, float]]:
    """Run the policy on the session's map (the episode's NavState, or a fresh one).
    act=False decides on a copy of the episode's NavState: a tool that only shows the
    decision (value_map) leaves the policy's memory as it was."""

    from glmap_tools.nav import EmbeddingScorer, NavConfig, NavState, decide

    agent = current_agent(session)
    nav = nav_steps.of(session)
    with locked(session) as glmap:
        if nav is not None:
            state, config = nav.state, nav.config
            scorer = nav.goal_scorer(glmap.fused_into)
            # Count every step taken since sim_reset (look_around, navigate_to, sim_step
            # included), so a full turn already taken counts as the policy's initial spin.
            state.steps = max(state.steps, len(nav.path) - 1)
            if not act:
                state = replace(
                    state,
                    avoid=list(state.avoid),
                    rejected_units=set(state.rejected_units),
                    blocked=set(state.blocked),
                    missed=dict(state.missed),
                )
        else:
            state, scorer, config = NavState(), EmbeddingScorer(glmap.embedder), NavConfig()
        decision = decide(
            glmap,
            agent[:2],
            agent[2],
            goal,
            policy=policy,
            scorer=scorer,
            state=state,
            config=config,
        )
    if nav is not None and act:
        nav.decision = decision
    return decision, agent


def waypoint_result(decision: NavDecision, agent: tuple[float, float, float]) -> Waypoint:
    w = decision.waypoint
    out = Waypoint(kind=w.kind, score=round(float(w.score), 3), reason=w.reason)
    # Optional fields are set only when they apply: one not set is left out of the text.
    if w.xy is not None:
        x, y = float(w.xy[0]), float(w.xy[1])
        out.xy = (round(x, 2), round(y, 2))
        where = nav_steps.relative(agent, (x, y))
        out.distance_m, out.bearing_deg = where["distance_m"], where["bearing_deg"]
    if w.unit_id is not None:
        out.unit_id = int(w.unit_id)
    return out


def top_units(
    session: Session, goal: str, scores: dict[int, float], k: int = 5
) -> list[tuple[int, str, float, str]]:
    """The k best-scored units: [id, kind, s_u, by] (by: 'client', 'prior' or 'scorer')."""
    from glmap_tools.nav.scorers import ClientScorer, map_units

    nav = nav_steps.of(session)
    with locked(session) as glmap:
        units = [u for u in map_units(glmap) if scores.get(u.unit_id, 0.0) > 0]
        scorer = nav.goal_scorer() if nav is not None else None
    units.sort(key=lambda u: (-scores[u.unit_id], u.unit_id))
    units = units[:k]
    by = (
        scorer.sources(goal, units) if isinstance(scorer, ClientScorer) else ["scorer"] * len(units)
    )
    return [
        (u.unit_id, u.kind, round(scores[u.unit_id], 3), b) for u, b in zip(units, by, strict=True)
    ]


def nav_png(session: Session, decision: NavDecision, agent: tuple[float, float, float]) -> bytes:
    xy = decision.waypoint.xy
    with locked(session) as glmap:
        image = nav_image(
            glmap,
            agent,
            decision.value,
            decision.frontiers,
            (xy[0], xy[1]) if xy is not None else None,
            decision.plan.path if decision.plan is not None else None,
        )
    return image.to_png()


def unit_score(session: Session, nav: NavSession, unit_id: int) -> UnitScore:
    """The score of one unit for the episode's goal (by 'client', 'prior' or 'scorer')."""
    from glmap_tools.nav.scorers import ClientScorer, UnitText, map_units

    with locked(session) as glmap:
        kind = glmap.unit(unit_id).kind
        units: list[UnitText] = [u for u in map_units(glmap, kind + "s") if u.unit_id == unit_id]
        scorer = nav.goal_scorer(glmap.fused_into)
        score = float(scorer.score(nav.goal, units)[0]) if units else 0.0
    by = (
        scorer.sources(nav.goal, units)[0]
        if isinstance(scorer, ClientScorer) and units
        else "scorer"
    )
    return UnitScore(goal_score=round(score, 3), score_by=by)


def matched_goal_unit(
    session: Session,
    decision: NavDecision,
    agent: tuple[float, float, float],
    config: NavConfig,
) -> GoalUnit | None:
    """The matched goal unit of `decision` and whether stopping at `agent` would count."""
    from glmap_tools.nav import GoalMatch
    from glmap_tools.nav.policy import stop_would_count, unit_reach, walls_of
    from glmap_tools.nav.value import unit_core_cells

    unit_id = decision.matched_unit
    if unit_id is None:
        return None
    with locked(session) as glmap:
        cells = unit_core_cells(glmap, unit_id, config.footprint_core)
        occ = decision.occupancy
        here, sight = unit_reach(
            occ, GoalMatch(unit_id, 1.0, 0, cells), agent[:2], walls_of(glmap, occ)
        )
    return GoalUnit(
        id=int(unit_id),
        score=round(float(decision.waypoint.score), 3),
        unit_distance_m=round(here, 2),
        in_sight=sight,
        would_succeed=stop_would_count(here, sight, config),
    )
