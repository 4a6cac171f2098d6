"""What every tool shares: the lifespan state, session lookup, error mapping, worker threads."""

from __future__ import annotations

import functools
import json
from collections.abc import Awaitable, Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ParamSpec, TypeVar

import anyio.to_thread
from mcp.server.mcpserver import Context
from mcp.server.mcpserver.exceptions import ToolError

from glmap_tools.errors import GLMapError
from glmap_tools.server.config import ServerConfig
from glmap_tools.server.state import Session, SessionRegistry

if TYPE_CHECKING:
    from glmap_tools.geometry.frame import RGBDFrame
    from glmap_tools.language.embed import Embedder
    from glmap_tools.perception.semantics import FrameSemantics

P = ParamSpec("P")
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


def app_state(ctx: Context) -> AppState:
    """The lifespan state of the server handling this request."""
    state = ctx.request_context.lifespan_context
    assert isinstance(state, AppState), "build the server with build_server()"
    return state


def transport_session_id(ctx: Context) -> tuple[str | None, bool]:
    """(the Mcp-Session-Id of a stateful HTTP connection or None, whether the call is HTTP)."""
    try:
        headers = ctx.headers
    except (ValueError, AttributeError):
        return None, False
    if headers is None:
        return None, False
    return headers.get(SESSION_HEADER), True


def session_of(ctx: Context, handle: str | None) -> Session:
    """The session this call works in (see glmap_tools.server.state)."""
    transport_id, _ = transport_session_id(ctx)
    return app_state(ctx).registry.resolve(handle, transport_id)


def session_for_new_map(ctx: Context, handle: str | None) -> Session:
    """The session new_map/load_map act on.

    On a stateless HTTP call with no handle (several clients may share the server) a new
    session is started rather than replacing the shared default map.
    """
    transport_id, is_http = transport_session_id(ctx)
    registry = app_state(ctx).registry
    if handle is None and is_http and transport_id is None:
        return registry.start_session()
    return registry.resolve(handle, transport_id, restart=True)


async def in_thread(fn: Callable[[], T]) -> T:
    """Run blocking map work on a worker thread, off the event loop."""
    return await anyio.to_thread.run_sync(fn)


def tool_errors(fn: Callable[P, Awaitable[T]]) -> Callable[P, Awaitable[T]]:
    """Report GLMapError as an MCP tool error (is_error) carrying its message for the model.

    Other exceptions stay crashes: the SDK logs them and the model sees a generic error.
    """

    @functools.wraps(fn)
    async def wrapper(*args: P.args, **kwargs: P.kwargs) -> T:
        try:
            return await fn(*args, **kwargs)
        except GLMapError as exc:
            raise ToolError(str(exc)) from exc

    return wrapper


def compact_json(data: Mapping[str, Any]) -> str:
    """JSON without whitespace (a model pays for every byte)."""
    return json.dumps(data, separators=(",", ":"), ensure_ascii=False)
