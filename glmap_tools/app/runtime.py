"""What every tool shares: the app state, the call, session lookup, worker threads.

A tool is an async function whose first parameter is `call: Call` and whose other
parameters (`Annotated[..., Field(...)]`) are its arguments; it returns a pydantic result
or an `ImageResult`. The adapters build the `Call`: glmap_tools.server from an MCP
request, glmap_tools.toolset for a call in this process.

A `Call` may carry a `Sampler`: the calling client's model (MCP sampling). `session_of`
offers it, with the session's `SamplingUsage`, to the model calls the tool makes on its
worker threads (glmap_tools.language.sampling).
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Awaitable, Callable
from dataclasses import dataclass, field, fields
from typing import TYPE_CHECKING, Any, TypeVar

import anyio.to_thread

from glmap_tools.app.config import ServerConfig
from glmap_tools.app.session import Session
from glmap_tools.app.state import SessionRegistry
from glmap_tools.language.sampling import Sampler, SamplingUsage, bind

if TYPE_CHECKING:
    from glmap_tools.app.background import Background
    from glmap_tools.geometry.frame import RGBDFrame
    from glmap_tools.language.embed import Embedder
    from glmap_tools.perception.pending import PendingFrames
    from glmap_tools.perception.semantics import FrameSemantics

T = TypeVar("T")

PerceptionBackend = Callable[["RGBDFrame"], "FrameSemantics"]
ProgressCallback = Callable[[float, "float | None", "str | None"], None]
AsyncProgress = Callable[[float, "float | None", "str | None"], Awaitable[None]]


@dataclass
class AppState:
    """Heavy, process-wide state built once (the server's lifespan, a Toolset's open).

    Attributes:
        config: the server settings.
        embedder: the text embedder shared by every map.
        registry: sessions and open maps.
        perception: turns a frame into semantics when no annotations are given; None
            means annotations are required.
        background: the start-up work (embedder, kernels) calls wait for, if any.
        pending: frames whose segments wait for label_segments (made on first use).
        sampling_usage: what sampling cost each session, by handle (the latest 4096).
    """

    config: ServerConfig
    embedder: Embedder
    registry: SessionRegistry
    perception: PerceptionBackend | None = None
    background: Background | None = None
    pending: PendingFrames | None = None
    sampling_usage: OrderedDict[str, SamplingUsage] = field(default_factory=OrderedDict)

    def usage_of(self, handle: str) -> SamplingUsage:
        """The sampling figures of session `handle` (new ones on first use)."""
        usage = self.sampling_usage.get(handle)
        if usage is None:
            usage = self.sampling_usage[handle] = SamplingUsage()
            while len(self.sampling_usage) > MAX_USAGE_RECORDS:
                self.sampling_usage.popitem(last=False)
        else:
            self.sampling_usage.move_to_end(handle)
        return usage


MAX_USAGE_RECORDS = 4096


@dataclass(frozen=True)
class Call:
    """One tool call: the app state it runs on and what its transport says about it.

    Attributes:
        state: the app state.
        transport_id: the Mcp-Session-Id of a stateful HTTP connection, else None.
        over_http: whether the call came over HTTP (several clients may share the server).
        progress: receives (progress, total, message) as a long call advances; None drops it.
        sampler: asks the calling client's model for a completion (MCP sampling); None
            when the client offers none (its model parts then use their fallbacks).
    """

    state: AppState
    transport_id: str | None = None
    over_http: bool = False
    progress: AsyncProgress | None = None
    sampler: Sampler | None = None

    async def report_progress(
        self, progress: float, total: float | None = None, message: str | None = None
    ) -> None:
        """Tell the caller how far the call has got (an MCP progress notification)."""
        if self.progress is not None:
            await self.progress(progress, total, message)


@dataclass(frozen=True)
class Hints:
    """What a tool does to the map, for clients (MCP tool annotations; None = unsaid)."""

    read_only_hint: bool | None = None
    destructive_hint: bool | None = None
    idempotent_hint: bool | None = None

    def said(self) -> dict[str, bool]:
        """The hints given, by their MCP names (`ToolAnnotations.model_validate(hints.said())`)."""
        return {f.name: v for f in fields(self) if (v := getattr(self, f.name)) is not None}


@dataclass(frozen=True)
class ToolSpec:
    """One tool: an async function over a map session, and its hints.

    The function takes `call: Call` first and returns a pydantic result or an
    `ImageResult`; both faces (the MCP server and glmap_tools.toolset) are built from these.
    """

    fn: Callable[..., Awaitable[Any]]
    annotations: Hints

    @property
    def name(self) -> str:
        return self.fn.__name__


READ_ONLY = Hints(read_only_hint=True)
ADDS = Hints(destructive_hint=False)  # adds to the map, replaces nothing
REPLACES = Hints(idempotent_hint=True)  # overwrites; the same call twice = once
DROPS = Hints()  # may drop the current map (destructive, not idempotent)
CALL_PARAMETER = "call"  # the name every tool function gives its Call


def offer_sampling(call: Call, session: Session) -> None:
    """Let the model calls of this tool call (its worker threads included) ask the call's
    sampler, counting in `session`'s usage (glmap_tools.language.sampling.bind)."""
    if not call.state.config.llm.uses_sampling:
        return
    bind(call.sampler, call.state.usage_of(session.handle))


def session_of(call: Call, handle: str | None) -> Session:
    """The session this call works in (see glmap_tools.app.state); the call's sampler is
    offered to the model calls it makes (`offer_sampling`)."""
    session = call.state.registry.resolve(handle or None, call.transport_id)
    offer_sampling(call, session)
    return session


def session_for_new_map(call: Call, handle: str | None) -> Session:
    """The session new_map/load_map act on.

    Over HTTP with no handle (several clients may share the server) a new session is
    started rather than replacing the shared default map: on a stateless call, and on any
    connection when --map pins the default session to a saved map.
    """
    registry = call.state.registry
    handle = handle or None
    shared = call.transport_id is None or registry.pin is not None
    if handle is None and call.over_http and shared:
        session = registry.start_session()
    else:
        session = registry.resolve(handle, call.transport_id, restart=True)
    offer_sampling(call, session)
    return session


async def in_thread(fn: Callable[[], T]) -> T:
    """Run blocking map work on a worker thread, off the event loop."""
    return await anyio.to_thread.run_sync(fn)
