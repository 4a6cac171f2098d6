"""Map tools: observe_frame, find_instance, find_region, what_is_at, describe_unit, map_summary.

No `from __future__ import annotations` here: the SDK reads these signatures at runtime.
"""

from typing import Annotated

from mcp.server.mcpserver import Context, Image, MCPServer
from mcp.types import TextContent, ToolAnnotations
from pydantic import BaseModel, Field

from glmap_tools.map import FREE, OBSTACLE
from glmap_tools.map.report import UnitInfo
from glmap_tools.server import tools_perception
from glmap_tools.server.inputs import (
    AnnotationInput,
    FileInput,
    IntrinsicsInput,
    PoseInput,
    decode_frame,
    embed_ahead,
)
from glmap_tools.server.navsession import from_agent
from glmap_tools.server.results import Hits, MapInfo, ObserveResult, UnitsAt
from glmap_tools.server.runtime import (
    app_state,
    compact_json,
    in_thread,
    session_of,
    tool_errors,
)
from glmap_tools.server.state import locked
from glmap_tools.server.views import describe_topdown, topdown
from glmap_tools.views import TopDownImage

READ_ONLY = ToolAnnotations(read_only_hint=True, open_world_hint=False)
SessionArg = Annotated[
    str | None,
    Field(
        max_length=64,
        description="see new_map (shared stateless HTTP servers only)",
    ),
]
Query = Annotated[
    str,
    Field(
        min_length=1,
        max_length=500,
        description="what to look for, in words",
    ),
]
TopK = Annotated[int, Field(ge=1, le=50, description="hits to return")]
UnitId = Annotated[int, Field(ge=1, le=2**62, description="an instance or region id")]
OCCUPANCY_NAMES = {FREE: "free", OBSTACLE: "obstacle"}


class FromAgent(BaseModel):
    """Where a unit lies from the simulator agent."""

    id: int
    distance_m: float = Field(description="straight-line metres from the agent to the centroid")
    bearing_deg: float = Field(description="degrees from the agent's heading, + = to its left")


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


def register(server: MCPServer) -> None:
    """Add the map tools to `server`."""

    @server.tool(annotations=ToolAnnotations(destructive_hint=False, idempotent_hint=False))
    @tool_errors
    async def observe_frame(
        rgb: Annotated[FileInput, Field(description="colour image, PNG or JPEG")],
        depth: Annotated[
            FileInput,
            Field(description="depth: 16-bit PNG of raw units, or .npy (float metres)"),
        ],
        intrinsics: IntrinsicsInput,
        pose: Annotated[PoseInput, Field(description="where the camera was")],
        ctx: Context,
        depth_scale: Annotated[
            float,
            Field(gt=0, le=1e6, description="raw depth units per metre (1000 = millimetres)"),
        ] = 1000.0,
        annotations: Annotated[
            AnnotationInput | None,
            Field(description="mask + labels; omit: segments come back pending"),
        ] = None,
        session: SessionArg = None,
    ) -> ObserveResult:
        """Add a posed RGB-D frame: its annotated objects become or merge into instances.

        Without annotations its segments come back pending: name them with label_segments.

        Files go as base64 or a local path. Returns the ids added or merged; nothing changes
        if any input is rejected.
        """
        state = app_state(ctx)
        target = session_of(ctx, session)
        await ctx.report_progress(0, 3, "decoding the frame")
        frame, semantics = await in_thread(
            lambda: decode_frame(
                rgb, depth, depth_scale, intrinsics, pose, annotations, state.config
            )
        )
        if semantics is None:
            if state.perception is None:  # geometry now, segments pending for label_segments
                pending = await tools_perception.observe_unannotated(state, target, frame)
                return pending  # type: ignore[return-value]  # the SDK checks it as ObserveResult
            perceive = state.perception
            semantics = await in_thread(lambda: perceive(frame))
        await ctx.report_progress(1, 3, f"fusing {len(semantics.objects)} objects")
        await in_thread(lambda: embed_ahead(state.embedder, semantics))  # outside the lock

        def integrate() -> ObserveResult:
            with locked(target) as glmap:
                report = glmap.integrate(frame, semantics)
                name = target.live.name
            return ObserveResult(
                session=target.handle, map_name=name, summary=report.summary(), report=report
            )

        result = await in_thread(integrate)
        await ctx.report_progress(3, 3, "done")
        return result

    @server.tool(annotations=READ_ONLY)
    @tool_errors
    async def find_instance(
        query: Query, ctx: Context, top_k: TopK = 5, session: SessionArg = None
    ) -> AgentHits:
        """Find objects by description, e.g. 'something to sit on'.

        Hits: id, description, score, match (false: no such object mapped yet), centroid and
        bounds (m, z up).
        """
        target = session_of(ctx, session)

        def run() -> AgentHits:
            with locked(target) as glmap:
                hits = glmap.find_instances(query, top_k)
            return AgentHits(
                query=query,
                hits=hits,
                from_agent=[FromAgent(**d) for d in from_agent(target, hits)],
            )

        return await in_thread(run)

    @server.tool(annotations=READ_ONLY)
    @tool_errors
    async def find_region(
        query: Query, ctx: Context, top_k: TopK = 5, session: SessionArg = None
    ) -> Hits:
        """Find regions (described groups of objects, e.g. 'the dining area') by description."""
        target = session_of(ctx, session)

        def run() -> Hits:
            with locked(target) as glmap:
                return Hits(query=query, hits=glmap.find_regions(query, top_k))

        return await in_thread(run)

    @server.tool(annotations=READ_ONLY)
    @tool_errors
    async def what_is_at(
        x: Annotated[float, Field(ge=-1e4, le=1e4, description="world x (metres)")],
        y: Annotated[float, Field(ge=-1e4, le=1e4, description="world y (metres)")],
        ctx: Context,
        radius: Annotated[
            float, Field(ge=0, le=5, description="search radius on the floor plan (metres)")
        ] = 0.25,
        session: SessionArg = None,
    ) -> AgentUnitsAt:
        """Instances and regions on the floor plan near (x, y), nearest first; is (x, y) free?"""
        target = session_of(ctx, session)

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
                from_agent=[FromAgent(**d) for d in from_agent(target, units)],
            )

        return await in_thread(run)

    @server.tool(annotations=READ_ONLY)
    @tool_errors
    async def describe_unit(id: UnitId, ctx: Context, session: SessionArg = None) -> UnitInfo:
        """Everything the map knows about one instance or region, by id."""
        target = session_of(ctx, session)

        def run() -> UnitInfo:
            with locked(target) as glmap:
                return glmap.unit_details(id)

        return await in_thread(run)

    @server.tool(annotations=READ_ONLY)
    @tool_errors
    async def map_summary(
        ctx: Context,
        include_image: Annotated[bool, Field(description="attach the top-down map image")] = True,
        session: SessionArg = None,
    ) -> list[TextContent | Image]:
        """Counts and extent of the map, and a labelled top-down image (ticks in metres)."""
        target = session_of(ctx, session)

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
        content: list[TextContent | Image] = [
            TextContent(type="text", text=compact_json(info.model_dump(mode="json")))
        ]
        if include_image:
            content.append(TextContent(type="text", text=describe_topdown(image)))
        if png is not None:
            content.append(Image(data=png, format="png"))
        return content
