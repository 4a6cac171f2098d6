"""An MCP request's context as the app's `Call`: its app state, transport, progress, and the
client's model (MCP sampling) when the client declares the sampling capability."""

from __future__ import annotations

import base64
from collections.abc import Mapping, Sequence
from typing import Any, Literal

import anyio
from mcp import types
from mcp.server.mcpserver import Context
from mcp.shared.exceptions import MCPError, NoBackChannelError
from mcp.shared.message import ServerMessageMetadata

from glmap_tools.app.runtime import AppState, Call
from glmap_tools.errors import LLMError, LLMUnavailableError
from glmap_tools.language.llm import LLMReply
from glmap_tools.language.sampling import DEFAULT_MAX_TOKENS, DEFAULT_TIMEOUT_S

SESSION_HEADER = "mcp-session-id"
SAMPLING = types.ClientCapabilities(sampling=types.SamplingCapability())


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


def _image_type(data: bytes) -> str:
    return "image/png" if data[:8] == b"\x89PNG\r\n\x1a\n" else "image/jpeg"


def sampling_messages(messages: Sequence[Mapping[str, Any]]) -> list[types.SamplingMessage]:
    """`LLMClient` messages as MCP sampling messages: text, then each image as its own
    image message (a sampling message holds one content block)."""
    out: list[types.SamplingMessage] = []
    for m in messages:
        role: Literal["user", "assistant"] = "assistant" if m.get("role") == "assistant" else "user"
        for image in m.get("images") or []:
            raw = image if isinstance(image, bytes) else base64.b64decode(image)
            block = types.ImageContent(
                type="image", data=base64.b64encode(raw).decode(), mime_type=_image_type(raw)
            )
            out.append(types.SamplingMessage(role=role, content=block))
        text = str(m.get("content") or "")
        if text:
            out.append(
                types.SamplingMessage(role=role, content=types.TextContent(type="text", text=text))
            )
    return out


class SessionSampler:
    """A `glmap_tools.language.sampling.Sampler` on the request's MCP session.

    The request goes out as related to the tool call (the SDK routes it on that call's
    stream). A client that answers with an error, a connection without a back-channel
    (e.g. a 2026-07-28 stateless connection) and a timeout all raise `LLMError`.
    """

    def __init__(self, session: Any, request_id: Any) -> None:
        self.session = session
        self.request_id = request_id

    async def __call__(
        self,
        messages: Sequence[Mapping[str, Any]],
        *,
        system: str | None = None,
        max_tokens: int = DEFAULT_MAX_TOKENS,
        timeout: float = DEFAULT_TIMEOUT_S,
    ) -> LLMReply:
        request = types.CreateMessageRequest(
            params=types.CreateMessageRequestParams(
                messages=sampling_messages(messages),
                system_prompt=system,
                max_tokens=max_tokens,
                temperature=0.0,
            )
        )
        try:
            with anyio.fail_after(timeout):
                result = await self.session.send_request(
                    request,
                    types.CreateMessageResult,
                    request_read_timeout_seconds=timeout,
                    metadata=ServerMessageMetadata(related_request_id=self.request_id),
                )
        except NoBackChannelError:
            version = getattr(self.session, "protocol_version", "?")
            raise LLMUnavailableError(
                f"this connection (protocol {version}) has no back-channel for sampling requests"
            ) from None
        except TimeoutError:
            raise LLMError(f"the client's model gave no answer within {timeout:g} s") from None
        except MCPError as exc:
            raise LLMError(f"the client refused the sampling request: {exc}") from None
        except Exception as exc:  # no back-channel, a closed stream, an invalid result
            name = type(exc).__name__
            raise LLMUnavailableError(f"sampling is not possible here ({name}: {exc})") from None
        content = result.content
        text = content.text if isinstance(content, types.TextContent) else ""
        if not text:
            raise LLMError(f"the client's model answered with {content.type} content, not text")
        return LLMReply(content=text, model=str(result.model or ""))


def sampler_of(ctx: Context[Any, Any]) -> SessionSampler | None:
    """The client's model through MCP sampling, if the client declared the capability."""
    try:
        session = ctx.request_context.session
        if not session.check_client_capability(SAMPLING):
            return None
        return SessionSampler(session, ctx.request_id)
    except (AttributeError, ValueError, LookupError):
        return None


def call_of(ctx: Context[Any, Any]) -> Call:
    """The `Call` a tool function gets for this request; progress goes to the client, and
    the client's model (sampling) to the model parts that are set to use it."""
    transport_id, over_http = transport_of(ctx)
    state = app_state(ctx)
    sampler = sampler_of(ctx) if state.config.llm.uses_sampling else None
    return Call(state, transport_id, over_http, ctx.report_progress, sampler)
