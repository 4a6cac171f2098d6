"""An MCP request's context as the app's `Call`: its app state, transport and progress."""

from __future__ import annotations

from typing import Any

from mcp.server.mcpserver import Context

from glmap_tools.app.runtime import AppState, Call

SESSION_HEADER = "mcp-session-id"


def app_state(ctx: Context[Any, Any]) -> AppState:
    """The lifespan state of the server handling this request."""
    state = ctx.request_context.lifespan_context
    assert isinstance(state, AppState), "build the server with build_server()"
    return state


def transport_of(ctx: Context[Any, Any]) -> tuple[str | None, bool]:
    """(the Mcp-Session-Id of a stateful HTTP connection or None, whether the call is HTTP)."""
    try:
        headers = ctx.headers
    except (ValueError, AttributeError):
        return None, False
    if headers is None:
        return None, False
    return headers.get(SESSION_HEADER), True


def call_of(ctx: Context[Any, Any]) -> Call:
    """The `Call` a tool function gets for this request; progress goes to the client."""
    transport_id, over_http = transport_of(ctx)
    return Call(app_state(ctx), transport_id, over_http, ctx.report_progress)
