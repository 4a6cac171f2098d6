"""render_view: images of an instance, a region, the whole map, a pose, or four situated views.

No `from __future__ import annotations` here: the SDK reads these signatures at runtime.
"""

from typing import Annotated, Literal

from mcp.server.mcpserver import Context, Image, MCPServer
from mcp.types import TextContent
from pydantic import Field

from glmap_tools.server.inputs import PoseInput, pose_of
from glmap_tools.server.runtime import app_state, in_thread, session_of, tool_errors
from glmap_tools.server.state import locked
from glmap_tools.server.tools_map import READ_ONLY, SessionArg
from glmap_tools.server.views import Rendered, ViewRequest, check_request, render_request

Target = Literal["instance", "region", "map", "pose", "situated"]
Side = Annotated[int, Field(ge=32, le=1024, description="image side in pixels")]
WHAT = {
    "instance": "selecting a view of instance {} and rendering it",
    "region": "selecting a view of region {} and rendering it",
    "map": "rendering the whole map",
    "pose": "rendering from the given pose",
    "situated": "rendering front, left, back and right",
}


def register(server: MCPServer) -> None:
    """Add render_view to `server`."""

    @server.tool(annotations=READ_ONLY)
    @tool_errors
    async def render_view(
        target: Annotated[
            Target,
            Field(description="instance/region: unit_id; pose: pose; situated: x, y, heading_deg"),
        ],
        ctx: Context,
        unit_id: Annotated[
            int | None, Field(ge=1, le=2**62, description="for instance/region")
        ] = None,
        pose: Annotated[PoseInput | None, Field(description="for target='pose'")] = None,
        x: Annotated[float | None, Field(ge=-1e4, le=1e4, description="situated: world x")] = None,
        y: Annotated[float | None, Field(ge=-1e4, le=1e4, description="situated: world y")] = None,
        heading_deg: Annotated[
            float,
            Field(ge=-360, le=360, description="situated: facing, degrees from +x, CCW"),
        ] = 0.0,
        context: Annotated[
            bool,
            Field(description="instance/region: draw the map around it too"),
        ] = True,
        width: Side | None = None,
        height: Side | None = None,
        session: SessionArg = None,
    ) -> list[TextContent | Image]:
        """Render the map's 3D Gaussians: a unit, the map, a pose, or 4 views around a spot.

        Units are seen from the agent's eye height, from the side that shows most of them.
        """
        state = app_state(ctx)
        target_session = session_of(ctx, session)
        w0, h0 = state.config.render_size
        request = ViewRequest(
            target=target,
            size=(width or w0, height or h0),
            unit_id=unit_id,
            pose=pose_of(pose) if pose is not None and target == "pose" else None,
            x=x,
            y=y,
            heading_deg=heading_deg,
            context=context,
        )
        check_request(request)
        await ctx.report_progress(0, 1, WHAT[target].format(unit_id))

        def run() -> tuple[Rendered, list[bytes]]:
            with locked(target_session) as glmap:
                rendered = render_request(glmap, request)
            return rendered, [v.to_png() for v in rendered.views]

        rendered, pngs = await in_thread(run)
        await ctx.report_progress(1, 1, "done")
        lines = [v.describe() for v in rendered.views]
        lines.extend(rendered.notes)
        lines.append("World frame: metres, z up. White = nothing mapped in that direction.")
        content: list[TextContent | Image] = [TextContent(type="text", text="\n".join(lines))]
        content.extend(Image(data=png, format="png") for png in pngs)
        return content
