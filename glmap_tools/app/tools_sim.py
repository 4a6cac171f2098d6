"""sim_reset and sim_step: drive a simulated apartment; every frame goes into the map.

No `from __future__ import annotations` here: the MCP face reads these signatures at runtime.
"""

from typing import Annotated, Literal

from pydantic import Field

from glmap_tools.app import nav_steps, simulator
from glmap_tools.app.arguments import SessionArg
from glmap_tools.app.navdraw import jpeg
from glmap_tools.app.results import ImageResult, Picture
from glmap_tools.app.runtime import ADDS, DROPS, Call, ToolSpec, in_thread, session_of
from glmap_tools.app.session import Session, locked
from glmap_tools.app.sim_results import SimResult, sampling_report
from glmap_tools.errors import InvalidInputError
from glmap_tools.language.backends import make_scorer

# Imports inside functions stay there: language.embed, scipy, numba load on first use: the tools
# load before these do, in the server and the in-process toolset alike.

Action = Literal["move_forward", "turn_left", "turn_right", "stop"]
Size = Literal["160x120", "320x240", "640x480"]


def _integrate(session: Session, sim: simulator.SimEpisode) -> str:
    return nav_steps.integrate(session, sim)


def _reply(
    session: Session, sim: simulator.SimEpisode, updates: list[str]
) -> ImageResult[SimResult]:
    from glmap_tools.nav.config import ACTIONS

    info = SimResult(
        **simulator.status(sim).given(),
        session=session.handle,
        map_updates=updates,
        actions=list(ACTIONS),
    )
    llm = sampling_report()  # the client's model through MCP sampling: calls, tokens, fallbacks
    if llm is not None:
        info.llm = llm
    return ImageResult(data=info, images=[Picture(format="jpeg", data=jpeg(sim.obs["rgb"]))])


async def sim_reset(
    call: Call,
    task: Literal["objectnav", "instnav"] = "objectnav",
    scene: Annotated[int, Field(ge=0, le=100_000)] = 0,
    seed: Annotated[int, Field(ge=0, le=2**31 - 1)] = 0,
    goal: Annotated[str, Field(max_length=256, description="omit: a random goal")] = "",
    episode: Annotated[str, Field(max_length=64, description="e.g. tune/objectnav/s00-000")] = "",
    size: Size | None = None,
    max_steps: Annotated[int | None, Field(ge=1, le=5000)] = None,
    keep_map: bool = False,
    session: SessionArg = "",
) -> ImageResult[SimResult]:
    """Start a simulator episode (`scene` and `seed`, or a benchmark `episode` id): reach
    any object of the goal's category (objectnav) or the described one (instnav)."""
    state = call.state
    target = session_of(call, session)
    wh = tuple(int(v) for v in size.split("x")) if size else state.config.sim_size
    steps = max_steps or state.config.sim_max_steps
    perception = state.config.sim_perception
    bench = simulator.bench_episode(episode, state.config.scene_dirs) if episode else None
    if bench is not None and goal:
        raise InvalidInputError("give episode or goal, not both: an episode has its goal.")

    def run() -> ImageResult[SimResult]:
        with target.sim_lock:  # a sim_step in flight finishes first
            return reset()

    def reset() -> ImageResult[SimResult]:
        sim = target.sim
        if bench is not None:
            key: tuple[object, ...] = ("bench", str(bench.layout_path), bench.task, wh, steps)
        else:
            key = (task, scene, wh, steps)
        fresh = None
        if sim is None or sim.key != key:
            if bench is not None:
                fresh = simulator.open_bench(bench, wh, steps, perception)  # type: ignore[arg-type]
            else:
                fresh = simulator.open_episode(task, scene, wh, steps, perception)  # type: ignore[arg-type]
        # The new episode starts before the running one is let go: a refused goal keeps it.
        playing = fresh or sim
        assert playing is not None
        was_bench, playing.bench = playing.bench, bench
        try:
            simulator.reset(playing, seed, goal or None)
        except BaseException:
            playing.bench = was_bench
            if fresh is not None:
                fresh.close()
            raise
        if fresh is not None:
            if sim is not None:
                sim.close()
            target.sim = fresh
        sim = playing
        if not keep_map:
            state.registry.new_map(target, None)
        scorer = None
        if state.config.llm.scorer != "embedding":
            scorer = make_scorer(state.config.llm, state.embedder)
        nav_steps.start(target, sim, state.embedder, scorer)
        return _reply(target, sim, [_integrate(target, sim)])

    await call.report_progress(0, 1, "building the apartment")
    return await in_thread(run)


async def sim_step(
    action: Action,
    call: Call,
    repeat: Annotated[int, Field(ge=1, le=20)] = 1,
    session: SessionArg = "",
) -> ImageResult[SimResult]:
    """Act `repeat` times: move 0.25 m, turn 30 deg, or stop (success: within 1 m of a goal's
    footprint, no wall between). At the end: success, SPL, distance_to_goal."""
    target = session_of(call, session)
    sim: simulator.SimEpisode | None = target.sim
    if sim is None:
        raise InvalidInputError(nav_steps.NO_EPISODE)
    episode = sim
    resets = sim.resets  # the episode this call acts in; a sim_reset meanwhile refuses it
    updates: list[str] = []
    for i in range(repeat):
        await call.report_progress(i, repeat, f"{action} {i + 1}/{repeat}")

        def one() -> str:
            # One step and its integration at a time per session, never across a sim_reset.
            with target.sim_lock, locked(target):
                if target.sim is not sim:
                    raise InvalidInputError(simulator.EPISODE_RESET)
                simulator.step(episode, action, resets)
                return _integrate(target, episode)

        updates.append(await in_thread(one))
        if sim.over:
            break
    await call.report_progress(repeat, repeat, "done")
    return _reply(target, sim, updates)


TOOLS = [
    ToolSpec(sim_reset, DROPS),
    ToolSpec(sim_step, ADDS),
]
