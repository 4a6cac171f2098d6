"""render_view: images of an instance, a region, the whole map, a pose, or four situated views.

No `from __future__ import annotations` here: the MCP face reads these signatures at runtime.
"""

from typing import Annotated, Literal

from pydantic import Field

from glmap_tools.app.arguments import SessionArg
from glmap_tools.app.inputs import PoseInput, pose_of
from glmap_tools.app.results import ImageResult, Picture
from glmap_tools.app.runtime import READ_ONLY, Call, ToolSpec, in_thread, session_of
from glmap_tools.app.session import locked
from glmap_tools.app.views import Rendered, ViewRequest, check_request, render_request
from glmap_tools.errors import InvalidInputError

Target = Literal["instance", "region", "map", "pose", "situated"]
Side = int  # checked by _side (0 or 32..1024)
MIN_SIDE, MAX_SIDE = 32, 1024


def _side(value: int, name: str) -> int:
    """An image side: 0 (the server's default) or 32..1024 pixels."""
    if value != 0 and not MIN_SIDE <= value <= MAX_SIDE:
        raise InvalidInputError(
            f"{name}={value}: give 0 (the default) or a side greater than or equal to "
            f"{MIN_SIDE} and less than or equal to {MAX_SIDE} pixels."
        )
    return value


WHAT = {
    "instance": "selecting a view of instance {} and rendering it",
    "region": "selecting a view of region {} and rendering it",
    "map": "rendering the whole map",
    "pose": "rendering from the given pose",
    "situated": "rendering front, left, back and right",
}


async def render_view(
    target: Target,
    call: Call,
    unit_id: Annotated[int | None, Field(ge=1, le=2**62)] = None,
    pose: PoseInput | None = None,
    x: Annotated[float | None, Field(ge=-1e4, le=1e4)] = None,
    y: Annotated[float | None, Field(ge=-1e4, le=1e4)] = None,
    heading_deg: Annotated[float, Field(ge=-360, le=360, description="CCW from +x")] = 0.0,
    context: Annotated[bool, Field(description="draw the map around the unit")] = True,
    width: Side = 0,
    height: Side = 0,
    session: SessionArg = "",
) -> ImageResult:
    """Render the map's 3D Gaussians: a unit (unit_id, from its most visible side), the
    map, a camera pose, or 'situated': 4 views from (x, y) facing heading_deg."""
    state = call.state
    target_session = session_of(call, session)
    w0, h0 = state.config.render_size
    request = ViewRequest(
        target=target,
        size=(_side(width, "width") or w0, _side(height, "height") or h0),
        unit_id=unit_id,
        pose=pose_of(pose) if pose is not None and target == "pose" else None,
        x=x,
        y=y,
        heading_deg=heading_deg,
        context=context,
    )
    check_request(request)
    await call.report_progress(0, 1, WHAT[target].format(unit_id))

    def run() -> tuple[Rendered, list[bytes]]:
        with locked(target_session) as glmap:
            rendered = render_request(glmap, request)
        return rendered, [v.to_png() for v in rendered.views]

    rendered, pngs = await in_thread(run)
    await call.report_progress(1, 1, "done")
    lines = [v.describe() for v in rendered.views]
    lines.extend(rendered.notes)
    lines.append("World frame: metres, z up. White = nothing mapped in that direction.")
    return ImageResult(
        notes=["\n".join(lines)], images=[Picture(format="png", data=png) for png in pngs]
    )


TOOLS = [
    ToolSpec(render_view, READ_ONLY),
]
