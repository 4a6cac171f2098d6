"""`build_server(config)`: the GLMap MCP server; slow start-up work runs in the background."""

from __future__ import annotations

import inspect
import logging
import os
from collections.abc import AsyncIterator, Awaitable, Callable
from contextlib import asynccontextmanager
from pathlib import Path
from typing import Any

import anyio
from mcp.server.mcpserver import Context, Image, MCPServer
from mcp.server.mcpserver.exceptions import ToolError, UnexpectedToolError
from mcp.shared.exceptions import MCPError
from mcp.types import CallToolResult, InputRequiredResult, TextContent, Tool, ToolAnnotations
from pydantic import BaseModel, ValidationError

from glmap_tools import __version__
from glmap_tools.app.arguments import tidy_arguments, validation_message
from glmap_tools.app.background import EMBEDDER, HANDSHAKE_HOLD_S, WHAT, Background, Task
from glmap_tools.app.config import ServerConfig
from glmap_tools.app.lifespan import needed_tasks, opened_state
from glmap_tools.app.listing import lean_listing
from glmap_tools.app.results import ImageResult, compact_json, compact_text, pictures_of
from glmap_tools.app.runtime import CALL_PARAMETER, AppState, Call, PerceptionBackend, ToolSpec
from glmap_tools.errors import GLMapError
from glmap_tools.server import resources
from glmap_tools.server.context import app_state, call_of

# Imports inside functions stay there: language.embed load on first use: build_server stays light
# (test_server_startup): the server loads them in the background or on first use.

logger = logging.getLogger(__name__)

BUG_NOTE = "This is a bug in glmap-tools"  # in every crash's message (the property test's mark)
CRASH_TEXT_CHARS = 500  # of the exception's text shown to the client

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
    pinned: bool = False  # --map: every call holds the saved map's lock (guard_calls)
    state: AppState | None = None  # the lifespan's state while it runs
    _turns: anyio.Lock | None = None  # --map: this process's calls, one at a time

    def streamable_http_app(self, **kwargs: Any) -> Any:
        """The SDK's streamable HTTP app, whose ended sessions (DELETE, idle timeout) end
        their GLMap sessions too: pending frames and the unsaved map go (`end_transport`)."""
        app = super().streamable_http_app(**kwargs)
        manager = self._lowlevel_server.session_manager
        discard = manager._discard_session  # the SDK's one exit for every ended session

        async def discard_and_end(session_id: str, transport: Any) -> None:
            try:
                await discard(session_id, transport)
            finally:
                await self._transport_ended(session_id)

        manager._discard_session = discard_and_end  # type: ignore[method-assign]
        return app

    async def _transport_ended(self, transport_id: str) -> None:

        state = self.state
        if state is None:
            return
        with anyio.CancelScope(shield=True):  # a cancelled request still lets go
            await anyio.to_thread.run_sync(lambda: state.registry.end_transport(transport_id))

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
        """Run one tool call; an unexpected exception becomes a clear tool error.

        No call ends in the SDK's bare "Error executing tool X": a crash (any exception
        but a ToolError or a protocol error) is logged once with its own traceback and
        answered with `crash_message` (the tool, the exception's type and text, and that
        it is a bug to report).
        """
        try:
            return await self._pinned_call(name, arguments, context)
        except MCPError:
            raise
        except UnexpectedToolError as exc:
            raise self._crashed(name, unwrapped(exc), context) from None
        except ToolError:
            raise
        except Exception as exc:
            raise self._crashed(name, exc, context) from None

    def _crashed(
        self, name: str, exc: BaseException, context: Context[AppState, Any] | None
    ) -> ToolError:
        logger.error(
            "glmap-mcp: tool %r crashed (a bug in glmap-tools): %s: %s",
            name,
            type(exc).__name__,
            exc,
            exc_info=(type(exc), exc, exc.__traceback__),
        )
        folder = None
        if context is not None:
            try:
                folder = app_state(context).registry.maps_dir
            except Exception:  # no lifespan state (a crash before it): nothing to hide
                folder = None
        return ToolError(crash_message(name, exc, folder))

    async def _pinned_call(
        self, name: str, arguments: dict[str, Any], context: Context[AppState, Any] | None
    ) -> CallToolResult | InputRequiredResult:
        """`_call`, bracketed by the pinned map's enter/exit with `--map` (app.persist);
        a failure to lock or open the map is the call's tool error."""

        pin = app_state(context).registry.pin if self.pinned and context is not None else None
        if pin is None:
            return await self._call(name, arguments, context)
        # The calls of one process take turns on the map as those of two processes do (the
        # file lock), so two at once never interleave their steps (`--linger` serves every
        # client's calls in one process).
        if self._turns is None:
            self._turns = anyio.Lock()
        try:
            with anyio.fail_after(pin.lock.wait_s):
                await self._turns.acquire()
        except TimeoutError:
            raise ToolError(
                f"map {pin.name!r} is in use by another call to this server and stayed busy "
                f"for {pin.lock.wait_s:g} s; try the call again when it is done, or start the "
                "server with a longer --map-wait."
            ) from None
        try:
            try:
                await anyio.to_thread.run_sync(pin.enter)
            except GLMapError as exc:
                raise ToolError(str(exc)) from exc
            try:
                return await self._call(name, arguments, context)
            finally:
                await anyio.to_thread.run_sync(pin.exit)
        finally:
            self._turns.release()

    async def _call(
        self, name: str, arguments: dict[str, Any], context: Context[AppState, Any] | None
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
        self, name: str, pending: list[Task], context: Context[AppState, Any] | None
    ) -> None:

        what = " and ".join(WHAT[t.name] for t in pending)
        message = f"{name} waits: the server is still {what} (first calls after start only)"
        logger.warning("glmap-mcp: %s", message)
        if context is not None:
            await context.report_progress(0, None, message)
        await anyio.to_thread.run_sync(lambda: self.background.wait([t.name for t in pending]))
        if context is not None:
            await context.report_progress(1, None, f"{what}: done")


def lean_tools(tools: list[Tool]) -> list[Tool]:
    """The tools/list a model reads (glmap_tools.app.listing): compact descriptions and
    schemas, a shared model or argument description given once, no output schemas."""
    lean = lean_listing([(t.name, t.description, t.input_schema) for t in tools])
    return [
        t.model_copy(update={"description": d, "input_schema": s, "output_schema": None})
        for t, (d, s) in zip(tools, lean, strict=True)
    ]


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
    parameters, its `call` taken from the request's context (`ctx: Context`, which the SDK
    fills in and leaves out of the input schema); a GLMapError becomes a tool error
    carrying its message for the model (any other exception is a crash, which
    `GLMapServer.call_tool` logs and words as a bug to report)."""
    fn = spec.fn
    signature = inspect.signature(fn)
    params = [
        p.replace(name="ctx", annotation=Context) if p.name == CALL_PARAMETER else p
        for p in signature.parameters.values()
    ]
    returned = signature.return_annotation
    images = isinstance(returned, type) and issubclass(returned, ImageResult)
    returns = CallToolResult if images else None

    async def tool(ctx: Context[Any, Any], **kwargs: Any) -> Any:
        call = call_of(ctx)
        try:
            result = await fn(**kwargs, call=call)
        except GLMapError as exc:
            raise ToolError(hide_maps_folder(str(exc), call)) from exc
        return mcp_result(result)

    tool.__name__ = tool.__qualname__ = fn.__name__
    tool.__module__ = fn.__module__
    tool.__doc__ = fn.__doc__
    signature = signature.replace(parameters=params)
    if returns is not None:
        signature = signature.replace(return_annotation=returns)
    tool.__signature__ = signature  # type: ignore[attr-defined]
    hints = {k: v for k, v in fn.__annotations__.items() if k != CALL_PARAMETER}
    tool.__annotations__ = {**hints, "ctx": Context, "return": signature.return_annotation}
    return tool


def hide_maps_folder(message: str, call: Call) -> str:
    """`message` with the server's maps folder cut out (its path is none of a client's
    business), whichever module raised it."""
    folder = str(call.state.registry.maps_dir)
    return message.replace(folder + os.sep, "").replace(folder, "<maps folder>")


def add_tools(server: MCPServer[Any], tools: tuple[ToolSpec, ...] | None = None) -> None:
    """Register `tools` (default: all, glmap_tools.app.catalog) on `server`."""
    if tools is None:
        from glmap_tools.app.catalog import TOOLS  # imports the tools modules

        tools = TOOLS
    for spec in tools:
        hints = ToolAnnotations.model_validate(spec.annotations.said())
        server.add_tool(mcp_tool(spec), name=spec.name, annotations=hints)


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
            server.state = state
            try:
                yield state
            finally:
                server.state = None

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
        guard_calls(server)
    return server


def guard_calls(server: GLMapServer) -> None:
    """Bracket every tool call of `server` with the pinned map's enter/exit (`--map`, see
    glmap_tools.app.persist); a failure to lock or open the map becomes the call's tool error.
    """
    server.pinned = True


def unwrapped(exc: UnexpectedToolError) -> BaseException:
    """What a tool really raised: the SDK wraps a crash (and a nested tool's crash) in
    UnexpectedToolError, whose `__cause__` is the original."""
    inner: BaseException = exc
    while isinstance(inner, UnexpectedToolError) and inner.__cause__ is not None:
        inner = inner.__cause__
    return inner


def crash_message(name: str, exc: BaseException, maps_folder: Path | None = None) -> str:
    """The text a client gets when `name` crashed on `exc`: the tool, the exception's type
    and text (one line, the server's maps folder cut out, at most CRASH_TEXT_CHARS), and
    that it is a bug to report."""
    text = " ".join(str(exc).split())
    if maps_folder is not None:
        folder = str(maps_folder)
        text = text.replace(folder + os.sep, "").replace(folder, "<maps folder>")
    if len(text) > CRASH_TEXT_CHARS:
        text = text[: CRASH_TEXT_CHARS - 3] + "..."
    said = f"{type(exc).__name__}: {text}" if text else type(exc).__name__
    return (
        f"{name} failed with an unexpected {said}. {BUG_NOTE}, not in your call: please "
        "report it to the glmap-tools maintainers with the tool's name, its arguments and "
        "this message (the server logged the traceback)."
    )
