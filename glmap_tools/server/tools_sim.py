"""sim_reset and sim_step: drive a simulated apartment; every frame goes into the map.

No `from __future__ import annotations` here: the SDK reads these signatures at runtime.
"""

from typing import Annotated, Any, Literal

import cv2
from mcp.server.mcpserver import Context, Image, MCPServer
from mcp.types import TextContent, ToolAnnotations
from pydantic import Field

from glmap_tools.errors import InvalidInputError
from glmap_tools.server import navsession, simulator
from glmap_tools.server.runtime import (
    app_state,
    compact_json,
    in_thread,
    session_of,
    tool_errors,
)
from glmap_tools.server.state import Session, locked
from glmap_tools.server.tools_map import SessionArg

Action = Literal["move_forward", "turn_left", "turn_right", "stop"]
Size = Literal["160x120", "320x240", "640x480"]
SIM_KEY = simulator.SIM_KEY


def _jpeg(rgb: Any) -> bytes:
    ok, buf = cv2.imencode(
        ".jpg", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, 85]
    )
    assert ok
    return buf.tobytes()


def _integrate(session: Session, sim: simulator.SimEpisode) -> str:
    return navsession.integrate(session, sim)


def _reply(
    session: Session, sim: simulator.SimEpisode, updates: list[str]
) -> list[TextContent | Image]:
    info = simulator.status(sim)
    info["session"] = session.handle
    info["map_updates"] = updates
    info["actions"] = list(simulator.ACTIONS)
    text = compact_json(info)
    return [TextContent(type="text", text=text), Image(data=_jpeg(sim.obs["rgb"]), format="jpeg")]


def register(server: MCPServer) -> None:
    """Add the simulator tools to `server`."""

    @server.tool(annotations=ToolAnnotations(destructive_hint=True, open_world_hint=False))
    @tool_errors
    async def sim_reset(
        ctx: Context,
        task: Annotated[
            Literal["objectnav", "instnav"],
            Field(description="objectnav: any object of a category; instnav: one described object"),
        ] = "objectnav",
        scene: Annotated[int, Field(ge=0, le=100_000, description="which generated apartment")] = 0,
        seed: Annotated[int, Field(ge=0, le=2**31 - 1, description="which episode")] = 0,
        goal: Annotated[
            str | None,
            Field(
                max_length=256,
                description="a category or description instead of a random goal",
            ),
        ] = None,
        episode: Annotated[
            str | None,
            Field(max_length=64, description="benchmark id, e.g. tune/objectnav/s00-000"),
        ] = None,
        size: Size | None = None,
        max_steps: Annotated[int | None, Field(ge=1, le=5000)] = None,
        keep_map: Annotated[bool, Field(description="add to the current map")] = False,
        session: SessionArg = None,
    ) -> list[TextContent | Image]:
        """Start a navigation episode in a simulated apartment and show the agent's view.

        A generated apartment or a benchmark episode; the frame goes into a fresh map (or the
        current one with keep_map).
        """
        state = app_state(ctx)
        target = session_of(ctx, session)
        wh = tuple(int(v) for v in size.split("x")) if size else state.config.sim_size
        steps = max_steps or state.config.sim_max_steps
        bench = simulator.bench_episode(episode) if episode else None
        if bench is not None and goal is not None:
            raise InvalidInputError("give episode or goal, not both: an episode has its goal.")

        def run() -> list[TextContent | Image]:
            sim = target.extras.get(SIM_KEY)
            if bench is not None:
                key: tuple[object, ...] = ("bench", str(bench.layout_path), bench.task, wh, steps)
            else:
                key = (task, scene, wh, steps)
            if sim is None or sim.key != key:
                if bench is not None:
                    fresh = simulator.open_bench(bench, wh, steps)  # type: ignore[arg-type]
                else:
                    fresh = simulator.open_episode(task, scene, wh, steps)  # type: ignore[arg-type]
                if sim is not None:
                    sim.close()
                sim = target.extras[SIM_KEY] = fresh
                target.extras["close"] = fresh.close
            sim.bench = bench
            simulator.reset(sim, seed, goal)
            if not keep_map:
                state.registry.new_map(target, None)
            scorer = None
            if state.config.llm.scorer != "embedding":
                from glmap_tools.language.backends import make_scorer

                scorer = make_scorer(state.config.llm, state.embedder)
            navsession.start(target, sim, state.embedder, scorer)
            return _reply(target, sim, [_integrate(target, sim)])

        await ctx.report_progress(0, 1, "building the apartment")
        return await in_thread(run)

    @server.tool(annotations=ToolAnnotations(destructive_hint=False, open_world_hint=False))
    @tool_errors
    async def sim_step(
        action: Annotated[
            Action,
            Field(description="move 0.25 m, turn 30 deg, or stop (success: goal within 1 m)"),
        ],
        ctx: Context,
        repeat: Annotated[
            int, Field(ge=1, le=20, description="take the action this many times")
        ] = 1,
        session: SessionArg = None,
    ) -> list[TextContent | Image]:
        """Act in the simulator; each frame goes into the map.

        Returns the view, pose, collisions and, once the episode ends, success and SPL.
        """
        target = session_of(ctx, session)
        sim = target.extras.get(SIM_KEY)
        if sim is None:
            raise InvalidInputError("no simulator episode in this session; call sim_reset first.")
        updates: list[str] = []
        for i in range(repeat):
            await ctx.report_progress(i, repeat, f"{action} {i + 1}/{repeat}")

            def one() -> str:
                with locked(target):  # one step and its integration at a time per session
                    simulator.step(sim, action)
                    return _integrate(target, sim)

            updates.append(await in_thread(one))
            if sim.over:
                break
        await ctx.report_progress(repeat, repeat, "done")
        return _reply(target, sim, updates)
