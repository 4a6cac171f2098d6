"""render_view: images of an instance, a region, the whole map, a pose, or four situated views.

No `from __future__ import annotations` here: the SDK reads these signatures at runtime.
"""

import math
from typing import Annotated, Literal

from mcp.server.mcpserver import Context, Image, MCPServer
from mcp.types import TextContent
from pydantic import Field

from glmap_tools.errors import InvalidInputError
from glmap_tools.geometry import Pose
from glmap_tools.map import GLMap
from glmap_tools.map.units import InstanceUnit, RegionUnit
from glmap_tools.server import views
from glmap_tools.server.inputs import PoseInput, pose_of
from glmap_tools.server.runtime import app_state, in_thread, session_of, tool_errors
from glmap_tools.server.state import locked
from glmap_tools.server.tools_map import READ_ONLY, SessionArg

Target = Literal["instance", "region", "map", "pose", "situated"]
Side = Annotated[int, Field(ge=32, le=1024, description="image side in pixels")]


def _cameras(
    glmap: GLMap,
    target: str,
    unit_id: int | None,
    pose: PoseInput | None,
    x: float | None,
    y: float | None,
    heading_deg: float,
    intrinsics_size: tuple[int, int],
) -> list[tuple[str, Pose]]:
    """The (label, camera) list a render_view request asks for; raises naming what is missing."""
    intr = views.agent_intrinsics(*intrinsics_size)
    if target in ("instance", "region"):
        if unit_id is None:
            raise InvalidInputError(
                f"target='{target}' needs unit_id (find one with find_{target})."
            )
        unit = glmap.unit(unit_id)
        if target == "instance" and not isinstance(unit, InstanceUnit):
            raise InvalidInputError(f"unit {unit_id} is a region; use target='region'.")
        if target == "region" and not isinstance(unit, RegionUnit):
            raise InvalidInputError(f"unit {unit_id} is an instance; use target='instance'.")
        lo, hi = views.unit_bounds(glmap, unit)
        label = f"{target} {unit_id}"
        return [(label, views.framing_pose(glmap, lo, hi, intr, views.VIEW_ELEVATION))]
    if target == "map":
        lo, hi = views.map_bounds(glmap)
        return [("whole map", views.framing_pose(glmap, lo, hi, intr, views.MAP_ELEVATION))]
    if target == "pose":
        if pose is None:
            raise InvalidInputError(
                "target='pose' needs pose={'matrix': <4x4 world_from_camera>, 'camera': "
                "'opencv'|'opengl', 'world_up': 'z'|'y'}."
            )
        return [("pose", pose_of(pose))]
    if x is None or y is None:
        raise InvalidInputError(
            "target='situated' needs x and y (metres) and optionally heading_deg; it renders "
            "front, left, back and right views from the agent's camera height there."
        )
    return views.situated_cameras(glmap, x, y, math.radians(heading_deg))


def register(server: MCPServer) -> None:
    """Add render_view to `server`."""

    @server.tool(annotations=READ_ONLY)
    @tool_errors
    async def render_view(
        target: Annotated[
            Target,
            Field(
                description="instance or region (by unit_id), map (all of it), pose (a "
                "camera you give), situated (front/left/back/right at x, y, heading_deg)"
            ),
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
        width: Side | None = None,
        height: Side | None = None,
        session: SessionArg = None,
    ) -> list[TextContent | Image]:
        """Render the map's 3D Gaussians as images, with the camera pose used for each.

        Use it to look at an instance or region you found, at the whole map, from a given
        camera pose, or around a spot: 'situated' gives four views (front, left, back,
        right) from the agent's eye height at (x, y) facing heading_deg.
        """
        state = app_state(ctx)
        target_session = session_of(ctx, session)
        w0, h0 = state.config.render_size
        size = (width or w0, height or h0)

        def cameras() -> list[tuple[str, Pose]]:
            with locked(target_session) as glmap:
                return _cameras(glmap, target, unit_id, pose, x, y, heading_deg, size)

        wanted = await in_thread(cameras)
        intr = views.agent_intrinsics(*size)
        rendered: list[views.View] = []
        for i, (label, cam) in enumerate(wanted):
            await ctx.report_progress(i, len(wanted), f"rendering {label}")

            def one(label: str = label, cam: Pose = cam) -> list[views.View]:
                with locked(target_session) as glmap:
                    return views.render_views(glmap, [(label, cam)], intr)

            rendered.extend(await in_thread(one))
        await ctx.report_progress(len(wanted), len(wanted), "done")
        lines = [v.describe() for v in rendered]
        lines.append("World frame: metres, z up. White = nothing mapped in that direction.")
        content: list[TextContent | Image] = [TextContent(type="text", text="\n".join(lines))]
        content.extend(Image(data=v.png, format="png") for v in rendered)
        return content
