"""Navigation tools: value_map (and the client's f_S), frontiers, navigate_to, look_around,
nav_step.

The policy and the planner are `glmap_tools.nav` (value map of Eq. 7, frontiers, waypoint,
FMM plan); these tools run them on the session's map and, in the simulator, act on them.
No `from __future__ import annotations` here: the MCP face reads these signatures at runtime.
"""

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Annotated, Literal, TypeVar

import anyio.from_thread
import numpy as np
from pydantic import Field

from glmap_tools.app import nav_steps, simulator
from glmap_tools.app.arguments import SessionArg
from glmap_tools.app.client_scores import held_scores, set_client_scores
from glmap_tools.app.nav_decision import (
    current_agent,
    decide_on_map,
    goal_text,
    matched_goal_unit,
    nav_png,
    top_units,
    unit_score,
    waypoint_result,
)
from glmap_tools.app.nav_session import NavSession
from glmap_tools.app.navdraw import contact_sheet, jpeg
from glmap_tools.app.results import ImageResult, Picture
from glmap_tools.app.runtime import ADDS, READ_ONLY, REPLACES, Call, ToolSpec, in_thread, session_of
from glmap_tools.app.session import Session, locked
from glmap_tools.app.sim_results import (
    ClientScoreCounts,
    Decision,
    Frontier,
    FrontiersResult,
    LookAroundResult,
    MapCounts,
    NavigateResult,
    NavStepResult,
    StepTaken,
    UnitScore,
    ValueMapResult,
)
from glmap_tools.errors import InvalidInputError

if TYPE_CHECKING:
    from glmap_tools.nav import NavDecision

# Imports inside functions stay there: language.embed, scipy, numba load on first use: the tools
# load before these do, in the server and the in-process toolset alike.

Units = Literal["both", "instances", "regions"]
Policy = Literal["glmap", "glmap-instance", "glmap-region", "egocentric", "frontier"]
StepOutcome = Literal["actions done", "policy would stop here", "episode over"]
POLICY_OF_UNITS = {"both": "glmap", "instances": "glmap-instance", "regions": "glmap-region"}
Goal = Annotated[str, Field(max_length=256, description="omit: the episode's")]


T = TypeVar("T")


def in_episode(session: Session, fn: Callable[[], T]) -> T:
    """Run a tool that acts in the simulator holding the session's episode lock, so a
    sim_reset from another call waits for it (and it never acts on a replaced episode)."""
    with session.sim_lock:
        return fn()


def progress_from_thread(call: Call) -> Callable[[float, float | None, str], None]:
    """Report progress from a worker thread (`in_thread`) as MCP progress notifications."""

    def report(done: float, total: float | None, message: str) -> None:
        if call.progress is not None:
            anyio.from_thread.run(call.report_progress, done, total, message)

    return report


async def value_map(
    call: Call,
    goal: Goal = "",
    units: Units = "both",
    scores: dict[int, float] | None = None,
    priors: dict[str, float] | None = None,
    clear: bool = False,
    session: SessionArg = "",
) -> ImageResult[ValueMapResult]:
    """Eq. 7: where the goal likely is, frontiers, waypoint, path; top_units: [id, kind,
    s_u, by]. scores (unit id), priors (region kind, 'kitchen'): your f_S 0..1 of the
    episode's goal, until clear or sim_reset."""
    target = session_of(call, session)

    def run() -> ImageResult[ValueMapResult]:
        wanted = goal_text(target, goal)
        from glmap_tools.nav.scorers import same_goal

        client = None
        if scores or priors or clear:
            nav = nav_steps.of(target)
            if nav is not None and goal.strip() and not same_goal(goal, nav.goal):
                raise InvalidInputError(
                    f"scores and priors are for the episode's goal {nav.goal!r}, not {goal!r}; "
                    "leave goal out to give them."
                )
            client = set_client_scores(target, scores, priors, clear)
        decision, agent = decide_on_map(target, wanted, POLICY_OF_UNITS[units], act=False)
        top = decision.value.top_cells(5) if decision.value is not None else []
        info = ValueMapResult(
            goal=wanted,
            units=units,
            agent=(round(agent[0], 2), round(agent[1], 2), round(math.degrees(agent[2]))),
            waypoint=waypoint_result(decision, agent),
            matched_unit=decision.matched_unit,
            top_cells=[(round(x, 2), round(y, 2), round(v, 3)) for x, y, v in top],
            top_units=top_units(target, wanted, decision.scores),
            evidence=decision.evidence,
            frontiers=len(decision.frontiers),
        )
        nav = nav_steps.of(target)
        if client is None and nav is not None and nav.client is not None:
            with locked(target) as glmap:
                client = held_scores(glmap, nav.client)
        if client is not None and (client.scores or client.priors):
            info.client = client
        png = nav_png(target, decision, agent)
        return ImageResult(data=info, images=[Picture(format="png", data=png)])

    return await in_thread(run)


async def frontiers(
    call: Call,
    top_k: Annotated[int, Field(ge=1, le=50)] = 8,
    session: SessionArg = "",
) -> ImageResult[FrontiersResult]:
    """Reachable frontiers, nearest first; bearing_deg: from the heading, + = left."""
    from glmap_tools.nav import NavConfig, NavState
    from glmap_tools.nav.policy import surroundings

    target = session_of(call, session)

    def run() -> ImageResult[FrontiersResult]:
        agent = current_agent(target)
        nav = nav_steps.of(target)
        config = nav.config if nav is not None else NavConfig()
        state = nav.state if nav is not None else NavState()
        with locked(target) as glmap:
            found = surroundings(glmap, agent[:2], state, config).fronts
        rows = [
            Frontier(
                xy=(round(float(f.target[0]), 2), round(float(f.target[1]), 2)),
                cells=int(f.size),
                path_m=round(float(f.distance), 2) if math.isfinite(f.distance) else None,
                **nav_steps.relative(agent, f.target),
            )
            for f in found[:top_k]
        ]
        info = FrontiersResult(
            agent=(round(agent[0], 2), round(agent[1], 2)), frontiers=rows, total=len(found)
        )
        return ImageResult(data=info)

    return await in_thread(run)


async def navigate_to(
    call: Call,
    x: Annotated[float | None, Field(ge=-1e4, le=1e4)] = None,
    y: Annotated[float | None, Field(ge=-1e4, le=1e4)] = None,
    unit_id: Annotated[int | None, Field(ge=1, le=2**62)] = None,
    max_steps: Annotated[int, Field(ge=1, le=500)] = 100,
    session: SessionArg = "",
) -> ImageResult[NavigateResult]:
    """Walk (simulator) to (x, y), or within 0.75 m of unit_id in clear sight
    (would_succeed: a stop would count)."""
    target = session_of(call, session)
    report = progress_from_thread(call)
    if (unit_id is None) == (x is None or y is None) or (x is None) != (y is None):
        raise InvalidInputError("give either x and y, or unit_id (not both, not neither).")

    def run() -> ImageResult[NavigateResult]:
        sim, nav = nav_steps.running(target)
        if unit_id is not None:
            with locked(target) as glmap:
                unit = glmap.unit(unit_id)  # raises UnknownIdError with a suggestion
                ids = list(getattr(unit, "instance_ids", None) or [unit_id])
                cells = sorted(set().union(*(glmap.grid.cells_of_unit(i) for i in ids)))
                centroid = glmap.unit_details(unit_id).centroid
            goal = nav_steps.Target(
                (float(centroid[0]), float(centroid[1])),
                int(unit_id),
                np.array(cells, np.int64).reshape(-1, 2),
            )
        else:
            goal = nav_steps.Target((float(x), float(y)))  # type: ignore[arg-type]
        with locked(target):
            walk = nav_steps.walk_to(
                target,
                sim,
                goal,
                max_steps,
                nav.config,
                lambda k, n: report(k, n, f"navigate_to step {k + 1}"),
            )
            scored = unit_score(target, nav, int(unit_id)) if unit_id is not None else UnitScore()
        report(max_steps, max_steps, walk.outcome)
        info = NavigateResult(
            **walk.given(), **scored.given(), **simulator.status(sim, camera_pose=False).given()
        )
        return ImageResult(data=info, images=[Picture(format="jpeg", data=jpeg(sim.obs["rgb"]))])

    return await in_thread(lambda: in_episode(target, run))


async def look_around(call: Call, session: SessionArg = "") -> ImageResult[LookAroundResult]:
    """Turn a full circle (simulator), every frame into the map."""
    target = session_of(call, session)
    report = progress_from_thread(call)

    def run() -> ImageResult[LookAroundResult]:
        sim, _ = nav_steps.running(target)
        turns = round(2 * math.pi / sim.env.motion.turn_angle)
        frames, labels = [], []
        with locked(target):
            for k in range(turns):
                report(k, turns, f"turn {k + 1}/{turns}")
                simulator.step(sim, "turn_left")
                nav_steps.integrate(target, sim)
                frames.append(sim.obs["rgb"])
                heading = math.degrees(simulator.agent_pose(sim)[2])
                labels.append(f"step {sim.info['steps']}  {heading:.0f} deg")
                if sim.over:
                    break
        report(turns, turns, "done")
        with locked(target) as glmap:
            summary = glmap.summary()
        info = LookAroundResult(
            **simulator.status(sim, camera_pose=False).given(),
            map=MapCounts(instances=summary.instances, regions=summary.regions),
        )
        sheet = contact_sheet(frames, labels, cols=4)
        return ImageResult(data=info, images=[Picture(format="jpeg", data=jpeg(sheet))])

    return await in_thread(lambda: in_episode(target, run))


async def nav_step(
    call: Call,
    policy: Policy = "glmap",
    actions: Annotated[int, Field(ge=1, le=200)] = 1,
    execute_stop: bool = False,
    details: bool = False,
    images: bool = False,
    session: SessionArg = "",
) -> ImageResult[NavStepResult]:
    """Up to `actions` policy steps (simulator), short of its stop (goal_unit) unless
    execute_stop."""
    target = session_of(call, session)
    report = progress_from_thread(call)

    def run() -> ImageResult[NavStepResult]:
        sim, nav = nav_steps.running(target)
        collisions = sim.collisions
        decisions, decision, agent, outcome, walked = _walk(
            target, sim, nav, policy, actions, execute_stop, report
        )
        counts: dict[str, int] = {}
        for d in decisions:
            counts[d.action] = counts.get(d.action, 0) + 1
        end = simulator.agent_pose(sim)
        info = NavStepResult(
            outcome=outcome,
            actions=counts,
            walked_m=round(walked, 2),  # path length, as navigate_to's
            new_collisions=sim.collisions - collisions,
            waypoint=waypoint_result(decision, agent) if decision is not None else None,
            **simulator.status(sim, camera_pose=False).given(),
        )
        # Optional fields are set only when they apply: one not set is left out of the text.
        if nav.client is not None and not nav.client.empty:
            info.client_scores = ClientScoreCounts(
                units=len(nav.client.units), priors=len(nav.client.priors)
            )
        report(actions, actions, outcome)
        goal_unit = (
            matched_goal_unit(target, decision, end, nav.config) if decision is not None else None
        )
        if goal_unit is not None and not sim.over:
            info.goal_unit = goal_unit
        if details:
            info.decisions = decisions
        else:
            info.last = [
                StepTaken(
                    step=d.step, action=d.action, position=d.position, heading_deg=d.heading_deg
                )
                for d in decisions[-3:]
            ]
        pictures = (
            [
                Picture(format="jpeg", data=jpeg(sim.obs["rgb"])),
                Picture(format="png", data=nav_png(target, decision, agent)),
            ]
            if images and decision is not None
            else []
        )
        return ImageResult(data=info, images=pictures)

    return await in_thread(lambda: in_episode(target, run))


def _walk(
    target: Session,
    sim: simulator.SimEpisode,
    nav: NavSession,
    policy: Policy,
    actions: int,
    execute_stop: bool,
    report: Callable[[float, float | None, str], None],
) -> tuple[list[Decision], "NavDecision | None", tuple[float, float, float], StepOutcome, float]:
    """Up to `actions` policy steps under the session's lock: (the steps taken, the last
    decision, the agent's pose it was made at, the outcome, metres walked)."""
    decisions: list[Decision] = []
    decision: NavDecision | None = None
    agent = simulator.agent_pose(sim)
    outcome: StepOutcome = "actions done"
    walked = 0.0
    with locked(target):
        for k in range(actions):
            report(k, actions, f"nav_step {k + 1}/{actions}")
            decision, agent = decide_on_map(target, nav.goal, policy)
            if decision.action == "stop" and not execute_stop:
                outcome = "policy would stop here"
                break
            simulator.step(sim, decision.action)
            nav_steps.integrate(target, sim)
            after = simulator.agent_pose(sim)
            walked += math.dist(agent[:2], after[:2])
            decisions.append(
                Decision(
                    step=int(sim.info["steps"]),
                    action=decision.action,
                    position=(round(after[0], 2), round(after[1], 2)),
                    heading_deg=round(math.degrees(after[2])),
                    waypoint=waypoint_result(decision, agent),
                )
            )
            if sim.over:
                outcome = "episode over"
                break
    return decisions, decision, agent, outcome, walked


TOOLS = [
    ToolSpec(value_map, REPLACES),  # keeps the client's scores
    ToolSpec(frontiers, READ_ONLY),
    ToolSpec(navigate_to, ADDS),
    ToolSpec(look_around, ADDS),
    ToolSpec(nav_step, ADDS),
]
