"""Map tools: observe_frame, find_instance, find_region, what_is_at, describe_unit, map_summary.

No `from __future__ import annotations` here: the MCP face reads these signatures at runtime.
"""

from typing import Annotated, TypeVar

from pydantic import Field

from glmap_tools.app import tools_perception
from glmap_tools.app.arguments import SessionArg
from glmap_tools.app.inputs import (
    AnnotationInput,
    FileInput,
    FrameFiles,
    IntrinsicsInput,
    PoseInput,
    decode_frame_files,
    embed_ahead,
    read_frame_files,
)
from glmap_tools.app.memory import frame_work, frame_work_bytes
from glmap_tools.app.nav_steps import from_agent
from glmap_tools.app.results import (
    FromAgent,
    Hits,
    ImageResult,
    MapInfo,
    ObserveResult,
    Picture,
    UnitsAt,
)
from glmap_tools.app.runtime import (
    ADDS,
    READ_ONLY,
    Call,
    ToolSpec,
    in_thread,
    session_of,
)
from glmap_tools.app.session import Session, locked
from glmap_tools.app.views import describe_topdown, topdown
from glmap_tools.errors import LLMError
from glmap_tools.language.sampling import fallback_message, note_fallback
from glmap_tools.map import FREE, OBSTACLE
from glmap_tools.map.report import UnitInfo
from glmap_tools.views import TopDownImage

# Bounds a model cannot plausibly hit are checked but not advertised (see compact_schema).
Query = Annotated[
    str, Field(min_length=1, max_length=500, description="what to look for, in words")
]
TopK = Annotated[int, Field(ge=1, le=50, description="hits to return")]
UnitId = Annotated[int, Field(ge=1, le=2**62, description="instance or region id")]
Metres = Annotated[float, Field(ge=-1e4, le=1e4)]
OCCUPANCY_NAMES = {FREE: "free", OBSTACLE: "obstacle"}


class AgentHits(Hits):
    """Hits, and where they lie from the agent while a simulator episode runs."""

    from_agent: list[FromAgent] = Field(default_factory=list, description="per hit, same order")


class AgentUnitsAt(UnitsAt):
    """Units around a point, and where they lie from the agent while an episode runs."""

    from_agent: list[FromAgent] = Field(default_factory=list, description="per unit, same order")


def resource_uris(handle: str) -> list[str]:
    """The glmap:// resources of one session."""
    return [
        f"glmap://{handle}/summary",
        f"glmap://{handle}/instances",
        f"glmap://{handle}/regions",
        f"glmap://{handle}/topdown.png",
        f"glmap://{handle}/instances/{{id}}",
        f"glmap://{handle}/regions/{{id}}",
    ]


async def observe_frame(
    rgb: Annotated[FileInput, Field(description="colour image, PNG or JPEG")],
    depth: Annotated[FileInput, Field(description="16-bit PNG (raw units) or .npy (metres)")],
    intrinsics: Annotated[
        IntrinsicsInput, Field(description="pixels: fx, fy, cx, cy; or hfov_deg (degrees)")
    ],
    pose: PoseInput,
    call: Call,
    depth_scale: Annotated[
        float, Field(gt=0, le=1e6, description="raw depth units per metre")
    ] = 1000.0,
    annotations: Annotated[
        AnnotationInput | None, Field(description="omit: segments come back pending")
    ] = None,
    session: SessionArg = "",
) -> ObserveResult:
    """Add a posed RGB-D frame (files: base64 or absolute path): annotated objects become
    or merge into instances; unannotated segments wait for label_segments."""
    state = call.state
    target = session_of(call, session)
    files = await in_thread(lambda: read_frame_files(rgb, depth, pose, annotations, state.config))
    # Frames in flight are bounded in bytes (app.memory.FrameWork): a call waits its turn.
    async with frame_work(state).hold(frame_work_bytes(files.width, files.height)):
        return await _observe(files, depth_scale, intrinsics, pose, annotations, call, target)


async def _observe(
    files: FrameFiles,
    depth_scale: float,
    intrinsics: IntrinsicsInput,
    pose: PoseInput,
    annotations: AnnotationInput | None,
    call: Call,
    target: Session,
) -> ObserveResult:
    """observe_frame's work on its read files: decode, perceive or park, integrate."""
    state = call.state
    await call.report_progress(0, 3, "decoding the frame")
    frame, semantics = await in_thread(
        lambda: decode_frame_files(files, depth_scale, intrinsics, pose, annotations, state.config)
    )
    if semantics is None:
        if state.perception is None:  # geometry now, segments pending for label_segments
            # A PendingObserveResult: an ObserveResult with the segments that wait for names.
            return await tools_perception.observe_unannotated(state, target, frame)
        perceive = state.perception
        try:
            semantics = await in_thread(lambda: perceive(frame))
        except LLMError as exc:  # the client's model (sampling) did not name the segments
            if not state.config.llm.uses_sampling or state.config.llm.fallback == "none":
                raise
            note_fallback(
                fallback_message("naming the segments", exc, "pending segments for label_segments")
            )
            return await tools_perception.observe_unannotated(state, target, frame)
    await call.report_progress(1, 3, f"fusing {len(semantics.objects)} objects")
    await in_thread(lambda: embed_ahead(state.embedder, semantics))  # outside the lock

    def integrate() -> ObserveResult:
        with locked(target) as glmap:
            report = glmap.integrate(frame, semantics)
            name = target.live.name
        return ObserveResult(
            session=target.handle, map_name=name, summary=report.summary(), report=report
        )

    result = await in_thread(integrate)
    await call.report_progress(3, 3, "done")
    return result


# A search of a map that has seen nothing: most often a client that starts a server process
# per tool call (LangChain's get_tools()), so each call meets a new, empty map.
EMPTY_MAP = (
    "the map is empty: nothing observed yet (observe_frame, or sim_reset and nav_step). A "
    "client that starts a server per tool call gets a new, empty map on each call: launch "
    "glmap-mcp with --map NAME, or keep one session open (e.g. LangChain's client.session(...))."
)


H = TypeVar("H", bound=Hits)


def with_empty_note(found: H, empty: bool, session: Session) -> H:
    """`found`, its text saying why there are no hits when the map has seen nothing and no
    episode runs."""
    if empty and not found.hits and session.sim is None:
        found.note = EMPTY_MAP
    return found


async def find_instance(
    query: Query, call: Call, top_k: TopK = 5, session: SessionArg = ""
) -> AgentHits:
    """Find objects by description ('something to sit on'), best first; match false:
    nothing mapped fits."""
    target = session_of(call, session)

    def run() -> AgentHits:
        with locked(target) as glmap:
            hits = glmap.find_instances(query, top_k)
            empty = not glmap.trajectory
        found = AgentHits(
            query=query,
            hits=hits,
            from_agent=from_agent(target, hits),
        )
        return with_empty_note(found, empty, target)

    return await in_thread(run)


async def find_region(query: Query, call: Call, top_k: TopK = 5, session: SessionArg = "") -> Hits:
    """Find regions (described groups of objects, e.g. 'the dining area'), best first."""
    target = session_of(call, session)

    def run() -> Hits:
        with locked(target) as glmap:
            found = Hits(query=query, hits=glmap.find_regions(query, top_k))
            empty = not glmap.trajectory
        return with_empty_note(found, empty, target)

    return await in_thread(run)


async def what_is_at(
    x: Metres,
    y: Metres,
    call: Call,
    radius: Annotated[float, Field(ge=0, le=5)] = 0.25,
    session: SessionArg = "",
) -> AgentUnitsAt:
    """Units within radius of (x, y) m on the floor plan, nearest first; is (x, y) free."""
    target = session_of(call, session)

    def run() -> AgentUnitsAt:
        with locked(target) as glmap:
            units = glmap.units_at(x, y, radius)
            occ = OCCUPANCY_NAMES.get(glmap.occupancy.state_at(x, y), "unknown")
        return AgentUnitsAt(
            x=x,
            y=y,
            radius=radius,
            occupancy=occ,
            units=units,
            from_agent=from_agent(target, units),
        )

    return await in_thread(run)


async def describe_unit(id: UnitId, call: Call, session: SessionArg = "") -> UnitInfo:
    """Everything the map knows about one instance or region, by id."""
    target = session_of(call, session)

    def run() -> UnitInfo:
        with locked(target) as glmap:
            return glmap.unit_details(id)

    return await in_thread(run)


async def map_summary(
    call: Call,
    include_image: bool = True,
    session: SessionArg = "",
) -> ImageResult[MapInfo]:
    """Counts, extent and a labelled top-down image of the map."""
    target = session_of(call, session)

    def run() -> tuple[MapInfo, TopDownImage | None, bytes | None]:
        with locked(target) as glmap:
            info = MapInfo(
                session=target.handle,
                map_name=target.live.name,
                summary=glmap.summary(),
                resources=resource_uris(target.handle),
            )
            image = topdown(glmap) if include_image else None
        return info, image, image.to_png() if image is not None else None

    info, image, png = await in_thread(run)
    return ImageResult(
        data=info,
        notes=[describe_topdown(image)] if include_image else [],
        images=[Picture(format="png", data=png)] if png is not None else [],
    )


TOOLS = [
    ToolSpec(observe_frame, ADDS),
    ToolSpec(find_instance, READ_ONLY),
    ToolSpec(find_region, READ_ONLY),
    ToolSpec(what_is_at, READ_ONLY),
    ToolSpec(describe_unit, READ_ONLY),
    ToolSpec(map_summary, READ_ONLY),
]
