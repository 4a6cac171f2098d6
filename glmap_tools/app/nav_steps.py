"""A session's navigation state (goal, NavState, path walked) and walking to a target.

Every simulator frame goes through `integrate`: into the session's map, and (scored
against the goal) into the egocentric baseline's accumulator of the NavState. `walk_to`
is navigate_to's loop: the policy's motion (`nav.policy.approach`) towards a point or a
unit, one action and one integrated frame at a time, until arrived, blocked or out of steps.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from glmap_tools.app import simulator
from glmap_tools.app.nav_session import NavSession
from glmap_tools.app.results import FromAgent
from glmap_tools.app.session import Session, locked
from glmap_tools.app.sim_results import Walk
from glmap_tools.errors import InvalidInputError
from glmap_tools.geometry import Pose

if TYPE_CHECKING:
    from glmap_tools.language.embed import Embedder
    from glmap_tools.map import GLMap
    from glmap_tools.map.occupancy import DenseOccupancy
    from glmap_tools.map.report import UnitInfo
    from glmap_tools.nav import GoalMatch, NavConfig, Scorer
    from glmap_tools.nav.approach import Approach

# Imports inside functions stay there: gaussians, language.embed, scipy, numba load on first use:
# build_server stays light (test_server_startup): the server loads them in the background or on
# first use; the tools load before these do, in the server and the in-process toolset alike.

# Per-call clients (a server process per tool call, e.g. LangChain's get_tools()) lose the
# episode between calls; the message names both ways to keep it (docs/frameworks/langchain.md).
NO_EPISODE = (
    "no simulator episode in this session; call sim_reset first. A client that starts a "
    "server per tool call keeps no episode between calls: launch glmap-mcp with --map NAME, "
    "or keep one session open (e.g. LangChain's client.session(...))."
)


# Below the evidence gate, the regions within this share of the best region's score may
# guide exploration (`NavConfig.region_hint`). Off: at 0.8, 2 of the 7 chat-client episodes
# of tests/test_server_nav.py failed (bench s00-000 through nav_step, tune s03-013 steered
# with value_map) that pass without it; to be measured on the tune split before it is used.
# value_map says why its map is empty (evidence 'none'); a client guides by regions with priors.
REGION_HINT = 0.0


def start(
    session: Session, sim: simulator.SimEpisode, embedder: Embedder, scorer: Scorer | None = None
) -> NavSession:
    """A fresh NavSession for the episode `sim` just reset to (kept as `session.nav`).

    `scorer`: f_S for the value map; default embedding cosine on `embedder`.
    """
    from glmap_tools.nav import EmbeddingScorer, NavConfig, NavState
    from glmap_tools.nav.perceive import TextVectors

    config = NavConfig.for_task(
        sim.task,
        forward_step=sim.env.motion.forward_step,
        turn_angle_deg=math.degrees(sim.env.motion.turn_angle),
        region_hint=REGION_HINT,
    )
    scorer = scorer if scorer is not None else EmbeddingScorer(embedder)
    if sim.task == "instnav":  # the goal's "next to ..." decides between look-alikes
        from glmap_tools.nav.scorers import RelationScorer

        scorer = RelationScorer(scorer, lambda: session.live.glmap)
    nav = NavSession(
        str(sim.obs["goal"]), NavState(scorer=scorer), config, scorer, TextVectors(embedder)
    )
    session.nav = nav
    return nav


def of(session: Session) -> NavSession | None:
    """The session's NavSession, or None before any sim_reset."""
    return session.nav


def active_sim(session: Session) -> simulator.SimEpisode:
    """The session's simulator episode, or raise saying to call sim_reset."""
    sim = session.sim
    if sim is None:
        raise InvalidInputError(NO_EPISODE)
    return sim


def running(session: Session) -> tuple[simulator.SimEpisode, NavSession]:
    """The session's episode and its navigation state, or raise if there is none or it ended."""
    sim = active_sim(session)
    nav = of(session)
    if nav is None:
        raise InvalidInputError(NO_EPISODE)
    if sim.over:
        raise InvalidInputError("the episode is over; call sim_reset to start another.")
    return sim, nav


def integrate(session: Session, sim: simulator.SimEpisode) -> str:
    """The episode step's `observe` of the latest frame, under the session's lock: into the
    map and the navigation state; return the map update line.

    With `glmap-mcp --map` the episode record goes into the frame's transaction.
    """
    from glmap_tools.nav.episode import observe  # nav loads scipy: not at start

    frame, semantics = simulator.frame(sim)
    nav = of(session)
    recorder = session.recorder
    with locked(session) as glmap:
        staged = recorder.stage(session) if recorder is not None else None
        if nav is None:
            report = glmap.integrate(frame, semantics)
        else:
            report = observe(glmap, frame, semantics, nav.state, nav.goal, nav.scorer, nav.texts)
            nav.path.append(simulator.agent_pose(sim)[:2])
        if recorder is not None:
            recorder.committed(staged)
    return report.summary()


def follow(nav: NavSession, sim: simulator.SimEpisode, glmap: GLMap) -> None:
    """Add the latest frame to the navigation state only (replaying a kept episode, whose
    map already holds it): the path and the egocentric accumulator."""
    from glmap_tools.nav.episode import feed_egocentric
    from glmap_tools.nav.perceive import frame_score

    frame, semantics = simulator.frame(sim)
    nav.path.append(simulator.agent_pose(sim)[:2])
    score = frame_score(glmap, nav.goal, nav.scorer, semantics, nav.texts)
    feed_egocentric(nav.state, frame, score, glmap.grid.cell_size, glmap.config.max_range)


def agent_pose(session: Session, glmap: GLMap) -> tuple[float, float, float] | None:
    """(x, y, heading) of the simulator agent, else of the map's latest camera, else None."""
    sim = session.sim
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
    """Where navigate_to goes: a point, or a unit of the map.

    Attributes:
        xy: the point (m), or the unit's centroid.
        unit_id: the unit's id, or None for a point.
        unit_cells: [K, 2] (i, j) index-grid cells of the unit (of its member instances for
            a region), or None for a point.
    """

    xy: tuple[float, float]
    unit_id: int | None = None
    unit_cells: np.ndarray | None = None


def window(
    glmap: GLMap, config: NavConfig, blocked: set[tuple[int, int]] | None = None
) -> DenseOccupancy:
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


def check_inside(occ: DenseOccupancy, xy: tuple[float, float], what: str) -> None:
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


def check_point(
    session: Session, agent: tuple[float, float, float], xy: tuple[float, float], config: NavConfig
) -> None:
    """Raise before any step when the point `xy` is outside the map or cannot be reached.

    Raises:
        OutsideMapError: outside the map (names its extent).
        UnreachableGoalError: nothing leads there (names the nearest reachable point).
    """
    from glmap_tools.nav import plan

    nav = of(session)
    with locked(session) as glmap:
        occ = window(glmap, config, nav.state.blocked if nav is not None else None)
    check_inside(occ, xy, "target")
    plan(occ, agent[:2], agent[2], xy, config, strict=True)


def no_progress_steps(config: NavConfig) -> int:
    """Steps without `PROGRESS` m of progress after which a walk ends as blocked."""
    return 2 * int(config.stuck_steps)


def walk_to(
    session: Session,
    sim: simulator.SimEpisode,
    target: Target,
    max_steps: int,
    config: NavConfig,
    on_step: Callable[[int, int], None] | None = None,
) -> Walk:
    """Walk to `target` until arrived, blocked or `max_steps`; return what happened.

    Each step is `glmap_tools.nav.policy.approach` on the session's map (the policy's own
    motion: bump marks, clearance cost, the drive controller), so a collision marks what the
    map missed and the next step plans round it. A point that is outside the map or cannot
    be reached is refused before any step. A unit is approached to a free cell within
    `stop_distance` of it in clear sight of it, the simulator's success rule with a margin.

    Returns:
        What happened (`Walk`): the outcome ('reached' | 'reached the nearest reachable
        point' | 'blocked' | 'step budget' | 'episode over'), steps, metres walked and
        planned, collisions, the point aimed at; for a unit also its distance, whether it
        is in sight and a stop would count; when not reached, what blocked the walk.

    `on_step(steps, max_steps)` is called before each step (progress notifications).

    Raises:
        OutsideMapError, UnreachableGoalError: a point target, before the first step.
    """
    from glmap_tools.nav.policy import PROGRESS, approach

    nav = of(session)
    assert nav is not None
    agent = simulator.agent_pose(sim)
    goal = _walk_goal(session, agent, target, config)

    def next_step(agent: tuple[float, float, float]) -> Approach:
        with locked(session) as glmap:
            return approach(glmap, agent[:2], agent[2], goal, nav.state, config)

    step = next_step(agent)
    planned = step.plan.length
    tally = _Tally(best=step.plan.length)
    while (outcome := _walk_ends(step, sim, tally, max_steps, config)) is None:
        if on_step is not None:
            on_step(tally.steps, max_steps)
        agent = _take_step(session, sim, step.action, agent, tally)
        if sim.over:
            continue
        step = next_step(agent)
        if step.plan.length < tally.best - PROGRESS:
            tally.best, tally.since = step.plan.length, 0
        else:
            tally.since += 1
    return _walk_result(step, outcome, planned, tally, agent, target, config)


@dataclass
class _Tally:
    """What a walk has done so far."""

    best: float  # the shortest plan length so far (m)
    steps: int = 0
    bumps: int = 0  # steps that collided
    walked: float = 0.0  # metres
    since: int = 0  # steps since the plan last got `PROGRESS` m shorter


def _walk_goal(
    session: Session, agent: tuple[float, float, float], target: Target, config: NavConfig
) -> tuple[float, float] | GoalMatch:
    """What `approach` walks to: the unit's cells, or the point (refused first when it is
    outside the map or cannot be reached)."""
    from glmap_tools.nav import GoalMatch

    if target.unit_cells is not None:
        return GoalMatch(int(target.unit_id or 0), 1.0, 0, target.unit_cells)
    check_point(session, agent, target.xy, config)
    return target.xy


def _walk_ends(
    step: Approach, sim: simulator.SimEpisode, tally: _Tally, max_steps: int, config: NavConfig
) -> str | None:
    """The walk's outcome when it ends before taking `step`, else None."""
    if step.arrived:
        return "reached"
    if step.action == "stop":
        return "reached the nearest reachable point" if step.aim else "blocked"
    if sim.over:
        return "episode over"
    if tally.steps >= max_steps:
        return "step budget"
    if tally.since >= no_progress_steps(config):
        return "blocked"
    return None


def _take_step(
    session: Session,
    sim: simulator.SimEpisode,
    action: str,
    agent: tuple[float, float, float],
    tally: _Tally,
) -> tuple[float, float, float]:
    """One simulator step, its frame into the map (`integrate`); the agent's new pose."""
    simulator.step(sim, action)
    integrate(session, sim)
    moved = simulator.agent_pose(sim)
    tally.steps += 1
    tally.walked += math.hypot(moved[0] - agent[0], moved[1] - agent[1])
    tally.bumps += bool(sim.info["collided"])
    return moved


def _walk_result(
    step: Approach,
    outcome: str,
    planned: float,
    tally: _Tally,
    agent: tuple[float, float, float],
    target: Target,
    config: NavConfig,
) -> Walk:
    """What happened: the last step's plan, the tally, and for a unit where it stands."""
    from glmap_tools.nav.policy import stop_would_count

    out = Walk(
        outcome=outcome,
        walk_steps=tally.steps,
        walked_m=round(tally.walked, 2),
        walk_collisions=tally.bumps,
        planned_m=_metres(planned),
        aim_xy=(round(float(step.aim[0]), 2), round(float(step.aim[1]), 2)) if step.aim else None,
        remaining_m=0.0 if step.arrived else _metres(step.plan.length),
        reason=step.reason,
    )
    if target.unit_cells is not None:
        out.unit_id = target.unit_id
        out.unit_distance_m = _metres(step.unit_distance)
        out.in_sight = step.in_sight
        out.would_succeed = stop_would_count(step.unit_distance, step.in_sight, config)
    if outcome not in ("reached", "step budget", "episode over"):
        out.blocked_by = _blocked_by(step, outcome, tally.bumps, tally.steps, agent, target, config)
    return out


def _metres(value: float) -> float | None:
    return round(float(value), 2) if math.isfinite(value) else None


def _blocked_by(
    step: Approach,
    outcome: str,
    bumps: int,
    steps: int,
    agent: tuple[float, float, float],
    target: Target,
    config: NavConfig,
) -> str:
    """One sentence: what stopped the walk short of the target, and what to try."""
    what = f"unit {target.unit_id}" if target.unit_id is not None else "the point"
    if step.action == "stop" and step.aim:
        gap = math.dist(step.aim, target.xy)
        return (
            f"no free path on the map leads closer to {what}: this is the nearest reachable "
            f"point, {gap:.2f} m from its centre (obstacles or unmapped space in between). "
            "look_around to map more, or go round through another frontier."
        )
    if step.action == "stop":
        return "no step is open from here: the agent is boxed in by obstacles on the map."
    where = f"({agent[0]:.2f}, {agent[1]:.2f})"
    if bumps:
        return (
            f"no progress in the last {no_progress_steps(config)} steps; {bumps} collisions "
            f"near {where} with something the map does not show (low furniture?). Try another "
            "side of the target or a frontier."
        )
    return (
        f"no progress in the last {no_progress_steps(config)} steps near {where}: the way "
        "changes as the map grows. look_around, then try again."
    )


def from_agent(session: Session, units: list[UnitInfo]) -> list[FromAgent]:
    """Where each of `units` lies from the simulator agent.

    Empty unless the session has a running simulator episode.
    """
    sim = session.sim
    if sim is None or sim.over or not sim.info:
        return []
    agent = simulator.agent_pose(sim)
    return [
        FromAgent(id=u.id, **relative(agent, (float(u.centroid[0]), float(u.centroid[1]))))
        for u in units
    ]
