"""`build_server(config)`: the GLMap MCP server; slow start-up work runs in the background."""

from __future__ import annotations

import inspect
import logging
import os
from collections.abc import AsyncIterator, Awaitable, Callable, Iterator
from contextlib import asynccontextmanager, contextmanager
from typing import Any

from mcp.server.mcpserver import Context, Image, MCPServer
from mcp.server.mcpserver.exceptions import ToolError
from mcp.types import CallToolResult, InputRequiredResult, TextContent, Tool
from pydantic import BaseModel, ValidationError

from glmap_tools import __version__
from glmap_tools.app.background import (
    EMBEDDER,
    HANDSHAKE_HOLD_S,
    KERNELS,
    WHAT,
    Background,
    BackgroundEmbedder,
    load_embedder,
    warm_kernels,
)
from glmap_tools.app.config import ServerConfig
from glmap_tools.app.inputs import tidy_arguments, validation_message
from glmap_tools.app.results import (
    ImageResult,
    compact_description,
    compact_json,
    compact_schema,
    compact_text,
    pictures_of,
    strip_descriptions,
)
from glmap_tools.app.runtime import AppState, PerceptionBackend, ToolSpec, app_state
from glmap_tools.app.state import SessionRegistry
from glmap_tools.app.threads import limited_threads
from glmap_tools.errors import GLMapError
from glmap_tools.server import resources

logger = logging.getLogger(__name__)

INSTRUCTIONS = """\
GLMap keeps a 3D map of a place built from posed RGB-D frames: instances (objects, with
3D Gaussians and descriptions) and regions (described groups of objects), indexed on a 2D
floor-plan grid. World frame: metres, z up. Feed frames with observe_frame (or walk the
simulator with sim_reset / sim_step), then ask: find_instance and find_region by words,
what_is_at by position, describe_unit by id, render_view to see, map_summary for counts
and a top-down image. Maps can be saved and reopened by name (save_map, load_map), and
exported as 3D Gaussian Splatting PLY files (export_ply). In the simulator: sim_reset, then
nav_step(actions=150) until it says the policy would stop (its goal_unit.would_succeed says
whether stopping counts), then sim_step('stop'); or steer yourself with look_around,
find_instance, value_map and navigate_to (its would_succeed likewise). Results are
compact text (key: value lines, floats rounded to 3 decimals) with the exact values as
structured content."""

# Tools that render or integrate also wait for the kernels; every tool that may embed text
# waits for the embedder. These read files and stored numbers only: they never wait.
NO_WAIT_TOOLS = ("list_maps", "map_summary", "describe_unit", "what_is_at")
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


def needed_tasks(name: str) -> tuple[str, ...]:
    """The start-up tasks a call of tool `name` waits for."""
    if name in NO_WAIT_TOOLS:
        return ()
    return (EMBEDDER, KERNELS) if name in KERNEL_TOOLS else (EMBEDDER,)


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
        tools = lean_tools(await super().list_tools())
        self.background.release()  # handshake done: the start-up work may take the CPU
        return tools

    async def call_tool(
        self,
        name: str,
        arguments: dict[str, Any],
        context: Context[AppState, Any] | None = None,
    ) -> CallToolResult | InputRequiredResult:
        tool = self._tool_manager.get_tool(name)
        if tool is not None:  # unknown names: the SDK's error
            try:
                arguments = tidy_arguments(
                    name, arguments, list(tool.fn_metadata.arg_model.model_fields)
                )
                tool.fn_metadata.validate_arguments(arguments)
            except (GLMapError, ValidationError) as exc:
                text = (
                    validation_message(name, exc) if isinstance(exc, ValidationError) else str(exc)
                )
                return CallToolResult(content=[TextContent(type="text", text=text)], is_error=True)
        self.background.release()
        pending = self.background.pending(needed_tasks(name))
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


def lean_tools(tools: list[Tool]) -> list[Tool]:
    """The tools/list a model reads (see GLMapServer): compact descriptions and schemas,
    a shared model or argument description given once, no output schemas."""
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


def mcp_result(result: Any) -> Any:
    """A tool function's result as the MCP server returns it: an ImageResult as text and
    image blocks; a pydantic result with images as structured content plus the images;
    anything else as is (the SDK makes it structured content)."""
    if isinstance(result, ImageResult):
        texts = [TextContent(type="text", text=t) for t in result.texts()]
        images = [Image(data=p.data, format=p.format).to_image_content() for p in result.images]
        return CallToolResult(content=[*texts, *images])
    pictures = pictures_of(result)
    if pictures and isinstance(result, BaseModel):
        data = result.model_dump(mode="json", by_alias=True)
        images = [Image(data=p.data, format=p.format).to_image_content() for p in pictures]
        return CallToolResult(
            content=[TextContent(type="text", text=compact_json(data)), *images],
            structured_content=data,
        )
    return result


def mcp_tool(spec: ToolSpec) -> Callable[..., Awaitable[Any]]:
    """`spec`'s function as the MCP server registers it: the same name, description and
    parameters; a GLMapError becomes a tool error carrying its message for the model (other
    exceptions stay crashes: the SDK logs them and the model sees a generic error)."""
    fn = spec.fn
    signature = inspect.signature(fn)
    returns = CallToolResult if signature.return_annotation is ImageResult else None

    async def call(*args: Any, **kwargs: Any) -> Any:
        try:
            result = await fn(*args, **kwargs)
        except GLMapError as exc:
            raise ToolError(hide_maps_folder(str(exc), [*args, *kwargs.values()])) from exc
        return mcp_result(result)

    call.__name__ = call.__qualname__ = fn.__name__
    call.__module__ = fn.__module__
    call.__doc__ = fn.__doc__
    if returns is not None:
        signature = signature.replace(return_annotation=returns)
    call.__signature__ = signature  # type: ignore[attr-defined]
    call.__annotations__ = {**fn.__annotations__, "return": signature.return_annotation}
    return call


def hide_maps_folder(message: str, arguments: list[Any]) -> str:
    """`message` with the server's maps folder cut out (its path is none of a client's
    business), whichever module raised it; `arguments` are the call's, its Context among
    them."""
    for value in arguments:
        if isinstance(value, Context):
            try:
                folder = str(app_state(value).registry.maps_dir)
            except (AttributeError, AssertionError, ValueError):
                return message
            return message.replace(folder + os.sep, "").replace(folder, "<maps folder>")
    return message


def add_tools(server: MCPServer, tools: tuple[ToolSpec, ...] | None = None) -> None:
    """Register `tools` (default: all, glmap_tools.app.catalog) on `server`."""
    if tools is None:
        from glmap_tools.app.catalog import TOOLS  # imports the tools modules

        tools = TOOLS
    for spec in tools:
        server.add_tool(mcp_tool(spec), name=spec.name, annotations=spec.annotations)


@contextmanager
def opened_state(
    config: ServerConfig, perception: PerceptionBackend | None, background: Background
) -> Iterator[AppState]:
    """The app state (embedder, sessions) for `config`, closed on exit.

    The MiniLM embedder loads on a background task unless it is the hashing one; the
    kernels warm up in the background when `config.warm_up`.
    """
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
            embedder = BackgroundEmbedder(task, MiniLMEmbedder)
        if config.warm_up:
            background.start(KERNELS, warm_kernels)
        registry = SessionRegistry(config, embedder)
        state = AppState(config, embedder, registry, perception)
        state.extras["background"] = background
        try:
            yield state
        finally:
            registry.close()


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
    background = Background(hold_s=HANDSHAKE_HOLD_S)

    @asynccontextmanager
    async def lifespan(_: MCPServer[AppState]) -> AsyncIterator[AppState]:
        with opened_state(config, perception, background) as state:
            yield state

    server = GLMapServer(
        "glmap",
        title="GLMap: Gaussian-Language Map",
        instructions=INSTRUCTIONS,
        version=__version__,
        lifespan=lifespan,
        log_level="WARNING",
    )
    server.background = background
    add_tools(server)
    resources.register(server, config)
    if config.map_name is not None:  # --map: each call holds the saved map's lock
        from glmap_tools.app.persist import guard_calls

        guard_calls(server)
    return server
