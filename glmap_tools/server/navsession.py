"""A session's navigation state (goal, NavState, path walked) and walking to a point.

Every simulator frame goes through `integrate`: into the session's map, and (scored
against the goal) into the egocentric baseline's accumulator of the NavState. `walk_to`
is navigate_to's loop: plan with the FMM planner on the map's occupancy, take the next
action, integrate the new frame, replan, until arrived, blocked or out of steps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.geometry import Pose
from glmap_tools.server import simulator
from glmap_tools.server.state import PIN_KEY, Session, locked

if TYPE_CHECKING:
    from glmap_tools.language.embed import Embedder
    from glmap_tools.map import GLMap
    from glmap_tools.perception.semantics import FrameSemantics

NAV_KEY = "nav"
BLOCKED_AFTER = 3  # consecutive collisions that end a walk as blocked
ARRIVE_SLACK = 0.15  # metres beyond `Target.near` still counted as next to a unit
MAX_BUMPS = 10  # collisions in one walk that end it as blocked


@dataclass
class NavSession:
    """Navigation state of one simulator episode.

    Attributes:
        goal: the episode's goal text.
        state: `glmap_tools.nav.NavState` (egocentric accumulator, stuck memory, last waypoint).
        config: `glmap_tools.nav.NavConfig`.
        scorer: `glmap_tools.nav.EmbeddingScorer` on the server's embedder.
        embedder: the text embedder (frame scores of the egocentric baseline).
        path: [(x, y)] agent positions, one per integrated frame.
        decision: the latest `NavDecision` (drawn by value_map), or None.
    """

    goal: str
    state: Any
    config: Any
    scorer: Any
    embedder: Any
    path: list[tuple[float, float]] = field(default_factory=list)
    decision: Any = None
    _text_vecs: dict[str, np.ndarray] = field(default_factory=dict)

    def frame_score(self, semantics: FrameSemantics) -> float:
        """What the frame shows scored against the goal (f_S of its best object or group).

        The egocentric (VLFM-like) baseline's per-frame score; text embeddings are cached,
        since the same objects are seen frame after frame.
        """
        from glmap_tools.nav import UnitText

        texts = [o.description or o.label for o in semantics.objects]
        texts = [t for t in texts + [g.description for g in semantics.groups] if t.strip()]
        if not texts:
            return 0.0
        todo = [t for t in dict.fromkeys(texts) if t not in self._text_vecs]
        if todo:
            for t, v in zip(todo, np.asarray(self.embedder.embed(todo)), strict=True):
                self._text_vecs[t] = v
        units = [UnitText(-1, "instance", t, self._text_vecs[t]) for t in texts]
        return float(np.max(self.scorer.score(self.goal, units)))


def start(
    session: Session, sim: simulator.SimEpisode, embedder: Embedder, scorer: Any = None
) -> NavSession:
    """A fresh NavSession for the episode `sim` just reset to (kept in session.extras).

    `scorer`: f_S for the value map; default embedding cosine on `embedder`.
    """
    from glmap_tools.nav import EmbeddingScorer, NavConfig, NavState

    config = NavConfig.for_task(
        sim.task,
        forward_step=sim.env.motion.forward_step,
        turn_angle_deg=math.degrees(sim.env.motion.turn_angle),
    )
    scorer = scorer if scorer is not None else EmbeddingScorer(embedder)
    nav = NavSession(str(sim.obs["goal"]), NavState(scorer=scorer), config, scorer, embedder)
    session.extras[NAV_KEY] = nav
    return nav


def of(session: Session) -> NavSession | None:
    """The session's NavSession, or None before any sim_reset."""
    return session.extras.get(NAV_KEY)


def active_sim(session: Session) -> simulator.SimEpisode:
    """The session's simulator episode, or raise saying to call sim_reset."""
    sim = session.extras.get(simulator.SIM_KEY)
    if sim is None:
        raise InvalidInputError("no simulator episode in this session; call sim_reset first.")
    return sim


def running(session: Session) -> tuple[simulator.SimEpisode, NavSession]:
    """The session's episode and its navigation state, or raise if there is none or it ended."""
    sim = active_sim(session)
    nav = of(session)
    if nav is None:
        raise InvalidInputError("no simulator episode in this session; call sim_reset first.")
    if sim.over:
        raise InvalidInputError("the episode is over; call sim_reset to start another.")
    return sim, nav


def integrate(session: Session, sim: simulator.SimEpisode) -> str:
    """Add the latest frame to the map and to the navigation state; return the map update line.

    With `glmap-mcp --map` the episode record goes into the frame's transaction.
    """
    frame, semantics = simulator.frame(sim)
    nav = of(session)
    pin = session.extras.get(PIN_KEY)
    with locked(session) as glmap:
        staged = pin.stage(session) if pin is not None else None
        summary = glmap.integrate(frame, semantics).summary()
        if pin is not None:
            pin.committed(staged)
        if nav is not None:
            _follow(nav, sim, frame, semantics, glmap.grid.cell_size, glmap.config.max_range)
    return summary


def follow(nav: NavSession, sim: simulator.SimEpisode, cell: float, reach: float) -> None:
    """Add the latest frame to the navigation state only (replaying a kept episode)."""
    frame, semantics = simulator.frame(sim)
    _follow(nav, sim, frame, semantics, cell, reach)


def _follow(
    nav: NavSession,
    sim: simulator.SimEpisode,
    frame: Any,
    semantics: FrameSemantics,
    cell: float,
    reach: float,
) -> None:
    x, y, _ = simulator.agent_pose(sim)
    nav.path.append((x, y))
    if nav.state.egocentric is None:
        from glmap_tools.nav import EgocentricValueMap

        nav.state.egocentric = EgocentricValueMap(cell, reach)
    nav.state.egocentric.add_frame(frame, nav.frame_score(semantics))


def agent_pose(session: Session, glmap: GLMap) -> tuple[float, float, float] | None:
    """(x, y, heading) of the simulator agent, else of the map's latest camera, else None."""
    sim = session.extras.get(simulator.SIM_KEY)
    if sim is not None and sim.info:
        return simulator.agent_pose(sim)
    if not glmap.trajectory:
        return None
    pose = Pose(np.asarray(glmap.trajectory[-1], np.float64))
    forward = pose.matrix[:3, 2]  # OpenCV camera: +z looks forward
    return (
        float(pose.matrix[0, 3]),
        float(pose.matrix[1, 3]),
        math.atan2(float(forward[1]), float(forward[0])),
    )


def relative(agent: tuple[float, float, float], xy: tuple[float, float]) -> dict[str, float]:
    """Straight-line distance (m) and bearing (degrees, + = to the agent's left) of `xy`."""
    dx, dy = xy[0] - agent[0], xy[1] - agent[1]
    bearing = math.degrees(math.atan2(dy, dx) - agent[2])
    bearing = (bearing + 180.0) % 360.0 - 180.0
    return {"distance_m": round(math.hypot(dx, dy), 2), "bearing_deg": round(bearing, 1)}


# ---------------------------------------------------------------------- walking


@dataclass(frozen=True)
class Target:
    """Where navigate_to goes: a point, or the cells of a unit (arrive within `near` of them).

    Attributes:
        xy: the point (m), or the unit's centroid.
        unit_cells: [K, 2] (i, j) index-grid cells of the unit, or None for a point.
        near: metres from the point / the unit's cells that count as arrived.
    """

    xy: tuple[float, float]
    unit_cells: np.ndarray | None
    near: float


def window(glmap: GLMap, config: Any, blocked: set[tuple[int, int]] | None = None) -> Any:
    """The map's occupancy as one dense window with `config.window_margin` unknown around it.

    Args:
        glmap: the map.
        config: NavConfig (window_margin).
        blocked: (i, j) cells where the agent bumped into something the map missed; they
            are marked as obstacles.
    """
    from glmap_tools.map.occupancy import OBSTACLE

    margin = int(math.ceil(config.window_margin / glmap.occupancy.cell_size))
    occ = glmap.occupancy.to_dense(margin=margin)
    if blocked:
        cells = np.array(sorted(blocked), np.int64)
        r, c = cells[:, 1] - occ.origin[1], cells[:, 0] - occ.origin[0]
        h, w = occ.state.shape
        keep = (r >= 0) & (r < h) & (c >= 0) & (c < w)
        occ.state[r[keep], c[keep]] = OBSTACLE
    return occ


def mark_bump(session: Session, nav: NavSession, agent: tuple[float, float, float]) -> None:
    """Remember where a forward move stopped short touched something the map missed
    (`nav.motion.bump_cells`: a cell near a mapped obstacle, else a 0.6 m edge)."""
    from glmap_tools.nav import bump_cells

    with locked(session) as glmap:
        occ = window(glmap, nav.config)
    nav.state.blocked.update(bump_cells(occ, agent[:2], agent[2], nav.config))


def check_inside(occ: Any, xy: tuple[float, float], what: str) -> None:
    """Raise OutsideMapError naming the map's extent when `xy` lies outside the window."""
    from glmap_tools.nav.errors import OutsideMapError

    r, c = occ.world_to_index(*xy)
    h, w = occ.state.shape
    if not (0 <= r < h and 0 <= c < w):
        s, (i0, j0) = occ.cell_size, occ.origin
        raise OutsideMapError(
            f"{what} ({xy[0]:.2f}, {xy[1]:.2f}) is outside the map, which spans x "
            f"{i0 * s:.2f}..{(i0 + w) * s:.2f} and y {j0 * s:.2f}..{(j0 + h) * s:.2f} m; pick a "
            "point inside it (frontiers lists the edges of what was seen)."
        )


def agent_distances(occ: Any, agent: tuple[float, float, float], config: Any) -> np.ndarray:
    """[H, W] FMM geodesic metres from the agent over the cells a plan may cross (inf: none).

    The agent's own footprint counts as crossable, so a pose grazing an obstacle still plans.
    """
    from glmap_tools.nav import geodesic, plannable

    r0, c0 = occ.world_to_index(agent[0], agent[1])
    ok = plannable(occ, config.agent_radius, config.optimistic)
    rr, cc = np.ogrid[: ok.shape[0], : ok.shape[1]]
    ok |= (rr - r0) ** 2 + (cc - c0) ** 2 <= (config.agent_radius / occ.cell_size) ** 2
    return np.asarray(geodesic(ok, (r0, c0), occ.cell_size))


def _unit_goal(occ: Any, field: np.ndarray, target: Target) -> tuple[float, float] | None:
    """The reachable cell within `target.near` of the unit's cells that is closest to the agent."""
    from scipy import ndimage

    assert target.unit_cells is not None
    mask = np.zeros(occ.state.shape, bool)
    rows = target.unit_cells[:, 1] - occ.origin[1]
    cols = target.unit_cells[:, 0] - occ.origin[0]
    ok = (rows >= 0) & (rows < mask.shape[0]) & (cols >= 0) & (cols < mask.shape[1])
    mask[rows[ok], cols[ok]] = True
    if not mask.any():
        return None
    near = ndimage.distance_transform_edt(~mask) * occ.cell_size <= target.near
    cost = np.where(near, field, np.inf)
    if not np.isfinite(cost).any():
        return None
    r, c = np.unravel_index(int(np.argmin(cost)), cost.shape)
    return occ.index_to_world(int(r), int(c))


def _arrived(agent: tuple[float, float, float], target: Target, cell: float) -> bool:
    if target.unit_cells is None:
        return math.hypot(agent[0] - target.xy[0], agent[1] - target.xy[1]) <= target.near
    centres = (target.unit_cells + 0.5) * cell
    d = np.hypot(centres[:, 0] - agent[0], centres[:, 1] - agent[1])
    return bool(d.min() <= target.near + ARRIVE_SLACK)


def plan_to(
    session: Session,
    agent: tuple[float, float, float],
    target: Target,
    config: Any,
    strict: bool = True,
) -> Any:
    """One `glmap_tools.nav.Plan` from the agent to the target on the session's map.

    Args:
        session: the session (its map and NavState's blocked cells).
        agent: (x, y, heading).
        target: where to go.
        config: NavConfig.
        strict: raise when the target cannot be reached; else plan to the nearest
            reachable point (`Plan.reachable` False).

    Raises:
        OutsideMapError: the target point is outside the map.
        UnreachableGoalError: nothing leads there (names the nearest reachable point).
    """
    from glmap_tools.nav import plan
    from glmap_tools.nav.errors import UnreachableGoalError

    nav = of(session)
    with locked(session) as glmap:
        occ = window(glmap, config, nav.state.blocked if nav is not None else None)
    check_inside(occ, target.xy, "target")
    goal: tuple[float, float] | None = target.xy
    if target.unit_cells is not None:
        goal = _unit_goal(occ, agent_distances(occ, agent, config), target)
        if goal is None and strict:
            raise UnreachableGoalError(
                f"no free cell within {target.near} m of the unit can be reached from "
                f"({agent[0]:.2f}, {agent[1]:.2f}); walk towards it (navigate_to its centroid "
                "with the nearest reachable point, look_around) and try again.",
                target.xy,
                None,
            )
    # Not strict: the planner heads for the nearest reachable point of an unreachable goal.
    return plan(occ, agent[:2], agent[2], goal or target.xy, config, strict=strict)


def walk_to(
    session: Session, sim: simulator.SimEpisode, target: Target, max_steps: int, config: Any
) -> dict[str, Any]:
    """Plan, act and integrate until arrived, blocked or `max_steps`; return what happened.

    The first plan is checked before any step, so an unreachable target changes nothing.
    When new frames show the target blocked, the walk goes on to the nearest reachable
    point. A forward move stopped by something the map missed marks the cells ahead as
    obstacles (NavState.blocked) and the walk replans around them.

    Returns:
        {"outcome": 'reached' | 'reached the nearest reachable point' | 'blocked' |
        'step budget' | 'episode over', "walk_steps", "walked_m", "walk_collisions",
        "planned_m" (the first plan's length), "end_xy" (where the last plan ended)}.

    Raises:
        OutsideMapError, UnreachableGoalError: before the first step.
    """
    from glmap_tools.nav.motion import forget_marks_near
    from glmap_tools.nav.policy import FORGET_NEAR

    nav = of(session)
    assert nav is not None
    cell = session.live.glmap.occupancy.cell_size
    agent = simulator.agent_pose(sim)
    plan = plan_to(session, agent, target, config)
    planned = plan.length
    steps = bumps = in_a_row = 0
    walked = 0.0
    outcome = "step budget"
    while True:
        if _arrived(agent, target, cell):
            outcome = "reached"
            break
        if not plan.reachable and plan.action == "stop":
            outcome = "reached the nearest reachable point" if len(plan.path) else "blocked"
            break
        if sim.over:
            outcome = "episode over"
            break
        if steps >= max_steps:
            break
        action = plan.action if plan.action != "stop" else "move_forward"
        simulator.step(sim, action)
        integrate(session, sim)
        steps += 1
        moved = simulator.agent_pose(sim)
        walked += math.hypot(moved[0] - agent[0], moved[1] - agent[1])
        if sim.info["collided"]:
            mark_bump(session, nav, moved)
            bumps += 1
            in_a_row += 1
            if in_a_row >= BLOCKED_AFTER or bumps >= MAX_BUMPS:
                outcome = "blocked"
                break
        else:
            in_a_row = 0
        agent = moved
        if not sim.over:
            plan = plan_to(session, agent, target, config, strict=False)
            if plan.boxed and forget_marks_near(nav.state.blocked, agent[:2], cell, FORGET_NEAR):
                plan = plan_to(session, agent, target, config, strict=False)
    return {
        "outcome": outcome,
        "walk_steps": steps,
        "walked_m": round(walked, 2),
        "walk_collisions": bumps,
        "planned_m": round(float(planned), 2),
        "end_xy": [round(float(v), 2) for v in plan.goal_xy],
    }


def from_agent(session: Session, units: list[Any]) -> list[dict[str, Any]]:
    """[{id, distance_m, bearing_deg}] of `units` (UnitInfo) from the simulator agent.

    Empty unless the session has a running simulator episode.
    """
    sim = session.extras.get(simulator.SIM_KEY)
    if sim is None or sim.over or not sim.info:
        return []
    agent = simulator.agent_pose(sim)
    return [
        {"id": u.id, **relative(agent, (float(u.centroid[0]), float(u.centroid[1])))} for u in units
    ]
