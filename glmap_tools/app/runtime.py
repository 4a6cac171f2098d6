"""What every tool shares: the lifespan state, session lookup, error mapping, worker threads."""

from __future__ import annotations

from collections.abc import Awaitable, Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, TypeVar

import anyio.to_thread
from mcp.server.mcpserver import Context
from mcp.types import ToolAnnotations
from pydantic import PrivateAttr

from glmap_tools.app.config import ServerConfig
from glmap_tools.app.results import compact_json as compact_json  # re-exported
from glmap_tools.app.state import Session, SessionRegistry

if TYPE_CHECKING:
    from glmap_tools.geometry.frame import RGBDFrame
    from glmap_tools.language.embed import Embedder
    from glmap_tools.perception.semantics import FrameSemantics

T = TypeVar("T")

PerceptionBackend = Callable[["RGBDFrame"], "FrameSemantics"]
SESSION_HEADER = "mcp-session-id"


@dataclass
class AppState:
    """Heavy, process-wide state built once in the server lifespan.

    Attributes:
        config: the server settings.
        embedder: the text embedder shared by every map.
        registry: sessions and open maps.
        perception: turns a frame into semantics when no annotations are given; None
            means annotations are required.
        extras: lazily built helpers (simulator factories, caches).
    """

    config: ServerConfig
    embedder: Embedder
    registry: SessionRegistry
    perception: PerceptionBackend | None = None
    extras: dict[str, Any] = field(default_factory=dict)


ProgressCallback = Callable[[float, "float | None", "str | None"], None]


class LocalContext(Context):
    """The Context of an in-process call (glmap_tools.toolset): the app state, no transport.

    Progress goes to an optional callback `(progress, total, message)`.
    """

    _state: AppState = PrivateAttr()
    _on_progress: ProgressCallback | None = PrivateAttr(default=None)

    def __init__(self, state: AppState, on_progress: ProgressCallback | None = None) -> None:
        super().__init__()
        self._state = state
        self._on_progress = on_progress

    @property
    def state(self) -> AppState:
        return self._state

    async def report_progress(
        self, progress: float, total: float | None = None, message: str | None = None
    ) -> None:
        if self._on_progress is not None:
            self._on_progress(progress, total, message)


@dataclass(frozen=True)
class ToolSpec:
    """One tool: an async function over a map session, and its MCP tool annotations.

    The function takes a `ctx: Context` (an MCP request's, or a `LocalContext`) and returns
    a pydantic result or an `ImageResult`; both faces (the MCP server and
    glmap_tools.toolset) are built from these.
    """

    fn: Callable[..., Awaitable[Any]]
    annotations: ToolAnnotations

    @property
    def name(self) -> str:
        return self.fn.__name__


READ_ONLY = ToolAnnotations(read_only_hint=True)
ADDS = ToolAnnotations(destructive_hint=False)  # adds to the map, replaces nothing
REPLACES = ToolAnnotations(idempotent_hint=True)  # overwrites; the same call twice = once
DROPS = ToolAnnotations()  # may drop the current map (destructive, not idempotent)


def app_state(ctx: Context) -> AppState:
    """The lifespan state of the server handling this request (or of an in-process call)."""
    if isinstance(ctx, LocalContext):
        return ctx.state
    state = ctx.request_context.lifespan_context
    assert isinstance(state, AppState), "build the server with build_server()"
    return state


def transport_session_id(ctx: Context) -> tuple[str | None, bool]:
    """(the Mcp-Session-Id of a stateful HTTP connection or None, whether the call is HTTP)."""
    if isinstance(ctx, LocalContext):
        return None, False
    try:
        headers = ctx.headers
    except (ValueError, AttributeError):
        return None, False
    if headers is None:
        return None, False
    return headers.get(SESSION_HEADER), True


def session_of(ctx: Context, handle: str | None) -> Session:
    """The session this call works in (see glmap_tools.app.state)."""
    transport_id, _ = transport_session_id(ctx)
    return app_state(ctx).registry.resolve(handle or None, transport_id)


def session_for_new_map(ctx: Context, handle: str | None) -> Session:
    """The session new_map/load_map act on.

    Over HTTP with no handle (several clients may share the server) a new session is
    started rather than replacing the shared default map: on a stateless call, and on any
    connection when --map pins the default session to a saved map.
    """
    transport_id, is_http = transport_session_id(ctx)
    registry = app_state(ctx).registry
    handle = handle or None
    if handle is None and is_http and (transport_id is None or registry.pin is not None):
        return registry.start_session()
    return registry.resolve(handle, transport_id, restart=True)


async def in_thread(fn: Callable[[], T]) -> T:
    """Run blocking map work on a worker thread, off the event loop."""
    return await anyio.to_thread.run_sync(fn)
