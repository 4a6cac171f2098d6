"""`build_server(config)`: the GLMap MCP server; slow start-up work runs in the background."""

from __future__ import annotations

import logging
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from typing import Any

from mcp.server.mcpserver import Context, MCPServer
from mcp.types import CallToolResult, InputRequiredResult, TextContent, Tool

from glmap_tools import __version__
from glmap_tools.server import (
    resources,
    tools_export,
    tools_map,
    tools_nav,
    tools_perception,
    tools_sim,
    tools_sqa,
    tools_store,
    tools_view,
)
from glmap_tools.server.background import (
    EMBEDDER,
    KERNELS,
    WHAT,
    Background,
    BackgroundEmbedder,
    load_embedder,
    warm_kernels,
)
from glmap_tools.server.config import ServerConfig
from glmap_tools.server.results import (
    compact_description,
    compact_schema,
    compact_text,
    strip_descriptions,
)
from glmap_tools.server.runtime import AppState, PerceptionBackend
from glmap_tools.server.state import SessionRegistry
from glmap_tools.server.threads import limited_threads

logger = logging.getLogger(__name__)

INSTRUCTIONS = """\
GLMap keeps a 3D map of a place built from posed RGB-D frames: instances (objects, with
3D Gaussians and descriptions) and regions (described groups of objects), indexed on a 2D
floor-plan grid. World frame: metres, z up. Feed frames with observe_frame (or walk the
simulator with sim_reset / sim_step), then ask: find_instance and find_region by words,
what_is_at by position, describe_unit by id, render_view to see, map_summary for counts
and a top-down image. Maps can be saved and reopened by name (save_map, load_map), and
exported as 3D Gaussian Splatting PLY files (export_ply). In the simulator: sim_reset, then
look_around, value_map and navigate_to (or nav_step, or sim_step), and sim_step('stop') at
the goal. Results are compact text (key: value lines, floats rounded to 3 decimals) with
the exact values as structured content."""

# Tools that render or integrate also wait for the kernels; every tool waits for the embedder.
KERNEL_TOOLS = (
    "observe_frame",
    "render_view",
    "sim_reset",
    "sim_step",
    "navigate_to",
    "look_around",
    "nav_step",
    "label_segments",
)


class GLMapServer(MCPServer[AppState]):
    """MCPServer with a lean tools/list and calls that wait for the start-up work.

    tools/list carries each tool's description with its line breaks folded and its input
    schema without pydantic's titles and nullable unions (an optional argument is simply
    not required); a model shared by several tools, and an argument described the same
    way in several (session, query, name), are described in the first only; output schemas
    are left out. Results keep their structured content, and
    their text block is a compact rendering of it (see `compact_text`), not a JSON copy.

    Attributes:
        background: the start-up tasks (embedder, kernels) the lifespan starts.
    """

    background: Background

    async def list_tools(self) -> list[Tool]:
        tools = await super().list_tools()
        seen: dict[str, str] = {}  # $defs name -> the first tool that describes it
        said: set[tuple[str, str]] = set()  # (argument, description) already given
        out = []
        for t in tools:
            schema = compact_schema(t.input_schema)
            for arg, prop in schema.get("properties", {}).items():
                text = prop.get("description")
                if text is not None and (arg, text) in said:
                    del prop["description"]  # described in an earlier tool
                elif text is not None:
                    said.add((arg, text))
            for name, model in schema.get("$defs", {}).items():
                if name in seen:
                    schema["$defs"][name] = {
                        **strip_descriptions(model),
                        "description": f"as in {seen[name]}",
                    }
                else:
                    seen[name] = t.name
            update = {
                "description": compact_description(t.description or ""),
                "input_schema": schema,
                "output_schema": None,
            }
            out.append(t.model_copy(update=update))
        return out

    async def call_tool(
        self,
        name: str,
        arguments: dict[str, Any],
        context: Context[AppState, Any] | None = None,
    ) -> CallToolResult | InputRequiredResult:
        needs = (EMBEDDER, KERNELS) if name in KERNEL_TOOLS else (EMBEDDER,)
        pending = self.background.pending(needs)
        if pending:
            await self._wait_for(name, pending, context)
        failed = self.background.failure(EMBEDDER)  # kernels that failed compile on use
        if failed is not None:
            return CallToolResult(
                content=[TextContent(type="text", text=f"{failed}; restart the server.")],
                is_error=True,
            )
        result = await super().call_tool(name, arguments, context)
        if isinstance(result, CallToolResult) and result.structured_content is not None:
            text = compact_text(result.structured_content)
            images = [c for c in result.content if c.type != "text"]
            result = result.model_copy(
                update={"content": [TextContent(type="text", text=text), *images]}
            )
        return result

    async def _wait_for(
        self, name: str, pending: list[Any], context: Context[AppState, Any] | None
    ) -> None:
        import anyio.to_thread

        what = " and ".join(WHAT[t.name] for t in pending)
        message = f"{name} waits: the server is still {what} (first calls after start only)"
        logger.warning("glmap-mcp: %s", message)
        if context is not None:
            await context.report_progress(0, None, message)
        await anyio.to_thread.run_sync(lambda: self.background.wait([t.name for t in pending]))
        if context is not None:
            await context.report_progress(1, None, f"{what}: done")


def build_server(
    config: ServerConfig | None = None, perception: PerceptionBackend | None = None
) -> GLMapServer:
    """Build the GLMap MCP server.

    The lifespan starts loading the embedder and the kernels on background threads and
    returns at once: the server answers initialize and tools/list while they load, and the
    first tool calls wait for them (saying so in a progress notification and on stderr).

    Args:
        config: server settings; default `ServerConfig()`.
        perception: turns a frame into semantics when observe_frame gets no annotations;
            None = annotations are required.

    Returns:
        A GLMapServer; run it with `.run()` (stdio) or serve `.streamable_http_app()`.
    """
    config = config or ServerConfig()
    background = Background()

    @asynccontextmanager
    async def lifespan(_: MCPServer[AppState]) -> AsyncIterator[AppState]:
        config.maps_dir.mkdir(parents=True, exist_ok=True)
        with limited_threads(config.compute_threads):
            embedder: Any
            if config.embedder == "hashing":
                embedder = load_embedder("hashing", None)
            else:
                from glmap_tools.language.embed import MiniLMEmbedder

                task = background.start(
                    EMBEDDER, lambda: load_embedder(config.embedder, config.compute_threads)
                )
                embedder = BackgroundEmbedder(
                    task, MiniLMEmbedder.name, MiniLMEmbedder.dim, MiniLMEmbedder.default_tau_s
                )
            if config.warm_up:
                background.start(KERNELS, warm_kernels)
            registry = SessionRegistry(config, embedder)
            state = AppState(config, embedder, registry, perception)
            state.extras["background"] = background
            try:
                yield state
            finally:
                registry.close()

    server = GLMapServer(
        "glmap",
        title="GLMap: Gaussian-Language Map",
        instructions=INSTRUCTIONS,
        version=__version__,
        lifespan=lifespan,
        log_level="WARNING",
    )
    server.background = background
    tools_map.register(server)
    tools_perception.register(server)
    tools_store.register(server)
    tools_view.register(server)
    tools_export.register(server)
    tools_sim.register(server)
    tools_nav.register(server)
    tools_sqa.register(server)
    resources.register(server, config)
    return server
