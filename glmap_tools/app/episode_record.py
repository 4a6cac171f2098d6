"""The simulator episode of `glmap-mcp --map` as a JSON record, and its replay.

The record says how the episode began (task, scene or benchmark id, image size, step
limit, seed, goal), which actions followed, and the navigator's memory (NavState less what
the replay rebuilds). The env is deterministic for a seed, so replaying the record in a new
process gives the same pose, steps, collisions and observation; no pickle is involved.
Imported before the handshake: the simulator modules are imported inside the functions.
"""

from __future__ import annotations

import dataclasses
import json
import math
from typing import TYPE_CHECKING, Any

from glmap_tools.app import nav_steps, simulator
from glmap_tools.errors import StoreError
from glmap_tools.language.backends import make_scorer

if TYPE_CHECKING:
    from glmap_tools.app.config import ServerConfig
    from glmap_tools.app.session import Session
    from glmap_tools.language.embed import Embedder

# Imports inside functions stay there: gaussians, language.embed, scipy, numba load on first use:
# build_server stays light (test_server_startup): the server loads them in the background or on
# first use; the tools load before these do, in the server and the in-process toolset alike.

RECORD_FORMAT = "glmap-tools episode"
RECORD_VERSION = 1
# NavState fields rebuilt by the replay, or not data.
NAV_REBUILT = ("egocentric", "scorer")


def episode_record(session: Session) -> str | None:
    """The session's simulator episode as record text (JSON), or None without one."""
    sim = session.sim
    if sim is None or sim.started is None:
        return None
    wh, max_steps = sim.key[-2], sim.key[-1]
    nav = session.nav
    record = {
        "format": RECORD_FORMAT,
        "version": RECORD_VERSION,
        "task": sim.task,
        "scene": sim.scene,
        "episode": sim.bench.episode_id if sim.bench is not None else None,
        "size": list(wh),
        "max_steps": max_steps,
        "seed": sim.started[0],
        "goal": sim.started[1],
        "actions": "".join(str(a) for a in sim.actions),
        "nav": nav_memory(nav.state) if nav is not None else None,
    }
    if nav is not None and nav.client is not None and not nav.client.empty:
        record["client_scores"] = {  # set_goal_scores: the client's f_S
            "units": sorted([uid, s] for uid, s in nav.client.units.items()),
            "priors": sorted([k, s] for k, s in nav.client.priors.items()),
        }
    return json.dumps(record, sort_keys=True, separators=(",", ":"))


def _plain(value: Any) -> Any:
    """A JSON value for a NavState field (sets sorted, tuples as lists, inf as null)."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, set):
        return sorted(_plain(v) for v in value)
    if isinstance(value, dict):
        return sorted([_plain(k), _plain(v)] for k, v in value.items())
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: _plain(getattr(value, f.name)) for f in dataclasses.fields(value)}
    return value


def nav_memory(state: Any) -> dict[str, Any]:
    """The NavState fields a replay does not rebuild, as JSON values."""
    return {
        f.name: _plain(getattr(state, f.name))
        for f in dataclasses.fields(state)
        if f.name not in NAV_REBUILT
    }


def _tuple(v: Any) -> tuple[Any, ...]:
    return tuple(_tuple(x) if isinstance(x, list) else x for x in v)


def apply_memory(state: Any, memory: dict[str, Any]) -> None:
    """Set the NavState fields of `memory` (the inverse of `nav_memory`)."""
    from glmap_tools.nav.waypoint import Waypoint

    for f in dataclasses.fields(state):
        if f.name in NAV_REBUILT or f.name not in memory:
            continue
        value = memory[f.name]
        current = getattr(state, f.name)
        if f.name == "last_waypoint" and value is not None:
            value = Waypoint(**{**value, "xy": _tuple(value["xy"]) if value["xy"] else None})
        elif (
            isinstance(value, dict)
            and dataclasses.is_dataclass(current)
            and not isinstance(current, type)
        ):
            # A small record of plain fields (nav.choose.GoalProgress): inf was written as None.
            value = dataclasses.replace(
                current,
                **{
                    k: math.inf if v is None and isinstance(getattr(current, k), float) else v
                    for k, v in value.items()
                },
            )
        elif isinstance(current, set):
            value = {_tuple(v) if isinstance(v, list) else v for v in value}
        elif isinstance(current, dict):
            value = {(_tuple(k) if isinstance(k, list) else k): v for k, v in value}
        elif isinstance(current, list):
            value = [_tuple(v) if isinstance(v, list) else v for v in value]
        elif value is None and isinstance(current, float):
            value = math.inf
        elif isinstance(value, list):
            value = _tuple(value)
        setattr(state, f.name, value)


def restore_episode(session: Session, text: str, config: ServerConfig, embedder: Embedder) -> None:
    """Replay the episode record `text` into `session` (env, navigation memory; not the map).

    `config` and `embedder` are the server's (map name, scene folders, scorer settings).

    Raises:
        StoreError: the record cannot be read or replayed.
    """
    from glmap_tools.nav.config import ACTIONS

    try:
        rec = json.loads(text)
        if rec.get("format") != RECORD_FORMAT or rec.get("version") != RECORD_VERSION:
            raise ValueError(f"format {rec.get('format')!r} version {rec.get('version')!r}")
        task, scene, episode_id = rec["task"], int(rec["scene"]), rec["episode"]
        size = (int(rec["size"][0]), int(rec["size"][1]))
        max_steps, seed, goal = int(rec["max_steps"]), int(rec["seed"]), rec["goal"]
        actions = [ACTIONS[int(c)] for c in rec["actions"]]
    except (ValueError, KeyError, TypeError, IndexError, AttributeError) as exc:
        raise StoreError(
            f"the simulator episode kept in map {config.map_name!r} cannot be read "
            f"({exc}); call sim_reset to start a new one."
        ) from None
    bench = simulator.bench_episode(episode_id, config.scene_dirs) if episode_id else None
    if bench is not None:
        key: tuple[Any, ...] = ("bench", str(bench.layout_path), bench.task, size, max_steps)
    else:
        key = (task, scene, size, max_steps)
    sim = session.sim
    if sim is None or sim.key != key:
        if bench is not None:
            fresh = simulator.open_bench(bench, size, max_steps, config.sim_perception)
        else:
            fresh = simulator.open_episode(task, scene, size, max_steps, config.sim_perception)
        if sim is not None:
            sim.close()
        sim = session.sim = fresh
    sim.bench = bench
    simulator.reset(sim, seed, goal)
    scorer = None
    if config.llm.scorer != "embedding":
        scorer = make_scorer(config.llm, embedder)
    nav = nav_steps.start(session, sim, embedder, scorer)
    glmap = session.live.glmap
    nav_steps.follow(nav, sim, glmap)
    for action in actions:
        simulator.step(sim, action)
        nav_steps.follow(nav, sim, glmap)
    if rec.get("nav"):
        apply_memory(nav.state, rec["nav"])
    client = rec.get("client_scores")
    if client:
        from glmap_tools.nav.scorers import ClientScores

        nav.client = ClientScores(
            nav.goal,
            {int(u): float(s) for u, s in client.get("units", [])},
            {str(k): float(s) for k, s in client.get("priors", [])},
        )
