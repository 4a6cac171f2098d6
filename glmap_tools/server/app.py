"""`build_server(config)`: the GLMap MCP server, with its heavy state built in the lifespan."""

from __future__ import annotations

import logging
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager

from mcp.server.mcpserver import MCPServer

from glmap_tools import __version__
from glmap_tools.server import (
    resources,
    tools_export,
    tools_map,
    tools_nav,
    tools_sim,
    tools_store,
    tools_view,
)
from glmap_tools.server.config import ServerConfig
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
exported as 3D Gaussian Splatting PLY files (export_ply)."""


def _load_embedder(config: ServerConfig):  # type: ignore[no-untyped-def]
    from glmap_tools.language import embed

    if config.embedder == "hashing":
        return embed.HashingEmbedder()
    return embed.default_embedder()


def build_server(
    config: ServerConfig | None = None, perception: PerceptionBackend | None = None
) -> MCPServer[AppState]:
    """Build the GLMap MCP server.

    Args:
        config: server settings; default `ServerConfig()`.
        perception: turns a frame into semantics when observe_frame gets no annotations;
            None = annotations are required.

    Returns:
        An MCPServer; run it with `.run()` (stdio) or serve `.streamable_http_app()`.
    """
    config = config or ServerConfig()

    @asynccontextmanager
    async def lifespan(_: MCPServer[AppState]) -> AsyncIterator[AppState]:
        import anyio.to_thread

        embedder = await anyio.to_thread.run_sync(lambda: _load_embedder(config))
        config.maps_dir.mkdir(parents=True, exist_ok=True)
        if config.warm_up:
            from glmap_tools.server.views import warm_up

            await anyio.to_thread.run_sync(warm_up)
        registry = SessionRegistry(config, embedder)
        state = AppState(config, embedder, registry, perception)
        with limited_threads(config.compute_threads):
            try:
                yield state
            finally:
                registry.close()

    server: MCPServer[AppState] = MCPServer(
        "glmap",
        title="GLMap: Gaussian-Language Map",
        instructions=INSTRUCTIONS,
        version=__version__,
        lifespan=lifespan,
        log_level="WARNING",
    )
    tools_map.register(server)
    tools_store.register(server)
    tools_view.register(server)
    tools_export.register(server)
    tools_sim.register(server)
    tools_nav.register(server)
    resources.register(server, config)
    return server
