"""Navigation tools: value_map, frontiers, navigate_to, look_around, nav_step.

The policy and the planner are `glmap_tools.nav` (value map of Eq. 7, frontiers, waypoint,
FMM plan); these tools run them on the session's map and, in the simulator, act on them.
No `from __future__ import annotations` here: the MCP face reads these signatures at runtime.
"""

import math
from collections.abc import Callable
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import Field

from glmap_tools.app import navsession, simulator
from glmap_tools.app.inputs import SessionArg
from glmap_tools.app.navdraw import contact_sheet, jpeg, nav_image
from glmap_tools.app.results import ImageResult, Picture
from glmap_tools.app.runtime import ADDS, READ_ONLY, Call, ToolSpec, in_thread, session_of
from glmap_tools.app.session import Session, locked
from glmap_tools.errors import InvalidInputError

Units = Literal["both", "instances", "regions"]
Policy = Literal["glmap", "glmap-instance", "glmap-region", "egocentric", "frontier"]
POLICY_OF_UNITS = {"both": "glmap", "instances": "glmap-instance", "regions": "glmap-region"}
Goal = Annotated[str, Field(max_length=256, description="what to find; omit: the episode's")]


def in_episode(session: Session, fn: Callable[[], ImageResult]) -> ImageResult:
    """Run a tool that acts in the simulator holding the session's episode lock, so a
    sim_reset from another call waits for it (and it never acts on a replaced episode)."""
    with session.sim_lock:
        return fn()


def _goal(session: Session, goal: str) -> str:
    if goal.strip():
        return goal.strip()
    nav = navsession.of(session)
    if nav is None:
        raise InvalidInputError(
            "no goal: pass goal='a sofa' (or start a simulator episode with sim_reset, whose "
            "goal is used by default)."
        )
    return str(nav.goal)


def _agent(session: Session) -> tuple[float, float, float]:
    with locked(session) as glmap:
        agent = navsession.agent_pose(session, glmap)
    if agent is None:
        raise InvalidInputError(
            "the map is empty: observe a frame (observe_frame) or start sim_reset first."
        )
    return agent


def _decide(session: Session, goal: str, policy: str) -> tuple[Any, tuple[float, float, float]]:
    """Run the policy on the session's map (the episode's NavState, or a fresh one)."""
    from glmap_tools.nav import EmbeddingScorer, NavConfig, NavState, decide

    agent = _agent(session)
    nav = navsession.of(session)
    with locked(session) as glmap:
        if nav is not None:
            state, scorer, config = nav.state, nav.scorer, nav.config
            # Count every step taken since sim_reset (look_around, navigate_to, sim_step
            # included), so a full turn already taken counts as the policy's initial spin.
            state.steps = max(state.steps, len(nav.path) - 1)
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
    if nav is not None:
        nav.decision = decision
    return decision, agent


def _waypoint(decision: Any, agent: tuple[float, float, float]) -> dict[str, Any]:
    w = decision.waypoint
    out: dict[str, Any] = {"kind": w.kind}
    if w.xy is not None:
        out["xy"] = [round(float(v), 2) for v in w.xy]
    if w.unit_id is not None:
        out["unit_id"] = int(w.unit_id)
    out["score"] = round(float(w.score), 3)
    if w.xy is not None:
        out.update(navsession.relative(agent, (float(w.xy[0]), float(w.xy[1]))))
    out["reason"] = w.reason
    return out


def _nav_png(session: Session, decision: Any, agent: tuple[float, float, float]) -> bytes:
    with locked(session) as glmap:
        image = nav_image(
            glmap,
            agent,
            decision.value,
            decision.frontiers,
            tuple(decision.waypoint.xy) if decision.waypoint.xy is not None else None,
            decision.plan.path if decision.plan is not None else None,
        )
    return image.to_png()


async def value_map(
    call: Call, goal: Goal = "", units: Units = "both", session: SessionArg = ""
) -> ImageResult:
    """Where the goal likely is: the Eq. 7 value map of the chosen units, frontiers, the
    waypoint and its path."""
    target = session_of(call, session)

    def run() -> ImageResult:
        wanted = _goal(target, goal)
        decision, agent = _decide(target, wanted, POLICY_OF_UNITS[units])
        top = decision.value.top_cells(5) if decision.value is not None else []
        info = {
            "goal": wanted,
            "units": units,
            "agent": [round(agent[0], 2), round(agent[1], 2), round(math.degrees(agent[2]))],
            "waypoint": _waypoint(decision, agent),
            "matched_unit": decision.matched_unit,
            "top_cells": [[round(x, 2), round(y, 2), round(v, 3)] for x, y, v in top],
            "frontiers": len(decision.frontiers),
        }
        png = _nav_png(target, decision, agent)
        return ImageResult(data=info, images=[Picture(format="png", data=png)])

    return await in_thread(run)


async def frontiers(
    call: Call,
    top_k: Annotated[int, Field(ge=1, le=50)] = 8,
    session: SessionArg = "",
) -> ImageResult:
    """Reachable edges of explored space, nearest first: xy, path_m (walk to the nearest
    cell), distance_m, bearing_deg (straight to xy)."""
    from glmap_tools.nav import NavConfig, NavState
    from glmap_tools.nav.policy import surroundings

    target = session_of(call, session)

    def run() -> ImageResult:
        agent = _agent(target)
        nav = navsession.of(target)
        config = nav.config if nav is not None else NavConfig()
        state = nav.state if nav is not None else NavState()
        with locked(target) as glmap:
            found = surroundings(glmap, agent[:2], state, config).fronts
        rows = []
        for f in found[:top_k]:
            row = {"xy": [round(float(v), 2) for v in f.target], "cells": int(f.size)}
            row["path_m"] = round(float(f.distance), 2) if math.isfinite(f.distance) else None
            row.update(navsession.relative(agent, f.target))
            rows.append(row)
        info = {"agent": [round(agent[0], 2), round(agent[1], 2)], "frontiers": rows}
        info["total"] = len(found)
        return ImageResult(data=info)

    return await in_thread(run)


async def navigate_to(
    call: Call,
    x: Annotated[float | None, Field(ge=-1e4, le=1e4)] = None,
    y: Annotated[float | None, Field(ge=-1e4, le=1e4)] = None,
    unit_id: Annotated[int | None, Field(ge=1, le=2**62)] = None,
    max_steps: Annotated[int, Field(ge=1, le=500)] = 100,
    session: SessionArg = "",
) -> ImageResult:
    """Walk (simulator) to (x, y), or within 0.75 m of unit_id in clear sight, round
    collisions. would_succeed: stop here counts if the unit is the goal."""
    target = session_of(call, session)
    if (unit_id is None) == (x is None or y is None) or (x is None) != (y is None):
        raise InvalidInputError("give either x and y, or unit_id (not both, not neither).")

    def run() -> ImageResult:
        sim, nav = navsession.running(target)
        if unit_id is not None:
            with locked(target) as glmap:
                unit = glmap.unit(unit_id)  # raises UnknownIdError with a suggestion
                ids = list(getattr(unit, "instance_ids", None) or [unit_id])
                cells = sorted(set().union(*(glmap.grid.cells_of_unit(i) for i in ids)))
                centroid = glmap.unit_details(unit_id).centroid
            goal = navsession.Target(
                (float(centroid[0]), float(centroid[1])),
                int(unit_id),
                np.array(cells, np.int64).reshape(-1, 2),
            )
        else:
            goal = navsession.Target((float(x), float(y)))  # type: ignore[arg-type]
        with locked(target):
            walk = navsession.walk_to(target, sim, goal, max_steps, nav.config)
        info = {**walk, **simulator.status(sim)}
        info.pop("camera_pose", None)
        return ImageResult(data=info, images=[Picture(format="jpeg", data=jpeg(sim.obs["rgb"]))])

    return await in_thread(lambda: in_episode(target, run))


async def look_around(call: Call, session: SessionArg = "") -> ImageResult:
    """Turn a full circle in place (simulator), adding every frame to the map."""
    target = session_of(call, session)

    def run() -> ImageResult:
        sim, _ = navsession.running(target)
        turns = round(2 * math.pi / sim.env.motion.turn_angle)
        frames, labels = [], []
        with locked(target):
            for _ in range(turns):
                simulator.step(sim, "turn_left")
                navsession.integrate(target, sim)
                frames.append(sim.obs["rgb"])
                heading = math.degrees(simulator.agent_pose(sim)[2])
                labels.append(f"step {sim.info['steps']}  {heading:.0f} deg")
                if sim.over:
                    break
        info = simulator.status(sim)
        info.pop("camera_pose", None)
        with locked(target) as glmap:
            info["map"] = glmap.summary().model_dump(include={"instances", "regions"})
        sheet = contact_sheet(frames, labels, cols=4)
        return ImageResult(data=info, images=[Picture(format="jpeg", data=jpeg(sheet))])

    return await in_thread(lambda: in_episode(target, run))


def _goal_unit(
    session: Session, decision: Any, agent: tuple[float, float, float], config: Any
) -> dict[str, Any] | None:
    """The matched goal unit of `decision` and whether stopping at `agent` would count."""
    from glmap_tools.nav import GoalMatch
    from glmap_tools.nav.policy import stop_would_count, unit_reach, walls_of
    from glmap_tools.nav.value import unit_cell_array

    unit_id = decision.matched_unit
    if unit_id is None:
        return None
    with locked(session) as glmap:
        cells = unit_cell_array(glmap.grid, unit_id)
        occ = decision.occupancy
        here, sight = unit_reach(
            occ, GoalMatch(unit_id, 1.0, 0, cells), agent[:2], walls_of(glmap, occ)
        )
    return {
        "id": int(unit_id),
        "score": round(float(decision.waypoint.score), 3),
        "unit_distance_m": round(here, 2),
        "in_sight": sight,
        "would_succeed": stop_would_count(here, sight, config),
    }


async def nav_step(
    call: Call,
    policy: Policy = "glmap",
    actions: Annotated[int, Field(ge=1, le=200)] = 1,
    execute_stop: bool = False,
    details: bool = False,
    images: bool = False,
    session: SessionArg = "",
) -> ImageResult:
    """A policy takes up to `actions` steps (simulator; glmap*: Eq. 7, egocentric: VLFM-like,
    frontier: nearest). Returns before the policy's stop (see goal_unit) unless
    execute_stop."""
    target = session_of(call, session)

    def run() -> ImageResult:
        sim, nav = navsession.running(target)
        decisions = []
        decision: Any = None
        agent = start = simulator.agent_pose(sim)
        collisions = sim.collisions
        outcome = "actions done"
        with locked(target):
            for _ in range(actions):
                decision, agent = _decide(target, nav.goal, policy)
                if decision.action == "stop" and not execute_stop:
                    outcome = "policy would stop here"
                    break
                simulator.step(sim, decision.action)
                navsession.integrate(target, sim)
                after = simulator.agent_pose(sim)
                decisions.append(
                    {
                        "step": int(sim.info["steps"]),
                        "action": decision.action,
                        "position": [round(after[0], 2), round(after[1], 2)],
                        "heading_deg": round(math.degrees(after[2])),
                        "waypoint": _waypoint(decision, agent),
                    }
                )
                if sim.over:
                    outcome = "episode over"
                    break
        counts: dict[str, int] = {}
        for d in decisions:
            counts[d["action"]] = counts.get(d["action"], 0) + 1
        end = simulator.agent_pose(sim)
        info: dict[str, Any] = {
            "outcome": outcome,
            "actions": counts,
            "moved_m": round(math.dist(start[:2], end[:2]), 2),
            "new_collisions": sim.collisions - collisions,
            "waypoint": _waypoint(decision, agent) if decision is not None else None,
        }
        goal_unit = _goal_unit(target, decision, end, nav.config) if decision is not None else None
        if goal_unit is not None and not sim.over:
            info["goal_unit"] = goal_unit
        if details:
            info["decisions"] = decisions
        else:
            info["last"] = [
                {k: d[k] for k in ("step", "action", "position", "heading_deg")}
                for d in decisions[-3:]
            ]
        info.update(simulator.status(sim))
        info.pop("camera_pose", None)
        pictures = (
            [
                Picture(format="jpeg", data=jpeg(sim.obs["rgb"])),
                Picture(format="png", data=_nav_png(target, decision, agent)),
            ]
            if images and decision is not None
            else []
        )
        return ImageResult(data=info, images=pictures)

    return await in_thread(lambda: in_episode(target, run))


TOOLS = [
    ToolSpec(value_map, READ_ONLY),
    ToolSpec(frontiers, READ_ONLY),
    ToolSpec(navigate_to, ADDS),
    ToolSpec(look_around, ADDS),
    ToolSpec(nav_step, ADDS),
]
