"""What the view tools ask of `glmap_tools.views`: one call per render_view target, the
server's empty-map check, the top-down image, and the renderer warm-up.

Camera placement, view selection (paper §3.2), situated views and the top-down drawing all
live in `glmap_tools.views`; this module only maps a tool request onto those calls and
says, in words for the model, how each camera was chosen.
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

import glmap_tools.views as gviews  # renders load on first use (the handshake does not wait)
from glmap_tools.errors import InvalidInputError
from glmap_tools.gaussians.types import GaussianSet
from glmap_tools.geometry import Pose
from glmap_tools.map.units import InstanceUnit, RegionUnit
from glmap_tools.views.common import view_intrinsics
from glmap_tools.views.topdown import TopDownImage, draw_topdown

if TYPE_CHECKING:
    from glmap_tools.map import GLMap
    from glmap_tools.views import RenderedView
    from glmap_tools.views.topdown_frame import TopDownFrame

# Imports inside functions stay there: gaussians, numba load on first use: build_server stays light
# (test_server_startup): the server loads them in the background or on first use; the tools load
# before these do, in the server and the in-process toolset alike.

EMPTY_MAP = (
    "the map is empty; observe frames (observe_frame or sim_step) before rendering or exporting it."
)
MAP_ELEVATION_DEG = 50.0  # the whole map is seen from this far above the horizon
# The server's order of the four situated views (views.situated gives front, back, left, right).
SITUATED_ORDER = ("front", "left", "back", "right")


@dataclass(frozen=True)
class ViewRequest:
    """A render_view request, already bounds-checked by the tool's argument schema.

    Attributes:
        target: "instance", "region", "map", "pose" or "situated".
        size: (width, height) of each image in pixels.
        unit_id: the instance or region, for those targets.
        pose: the camera, for target="pose".
        x: world x (m), for target="situated".
        y: world y (m), for target="situated".
        heading_deg: facing (degrees from +x, counter-clockwise), for target="situated".
        context: instance/region: draw the whole map from the chosen camera (True) or the
            unit's own Gaussians only (False).
    """

    target: str
    size: tuple[int, int]
    unit_id: int | None = None
    pose: Pose | None = None
    x: float | None = None
    y: float | None = None
    heading_deg: float = 0.0
    context: bool = True


@dataclass(frozen=True)
class Rendered:
    """The images of one request and the sentences that say how their cameras were chosen."""

    views: tuple[RenderedView, ...]
    notes: tuple[str, ...]


def check_request(request: ViewRequest) -> None:
    """Raise naming what a target needs when the request lacks it (before any map work).

    Raises:
        InvalidInputError: a target without its unit_id, pose, or x and y.
    """
    if request.target in ("instance", "region") and request.unit_id is None:
        raise InvalidInputError(
            f"target='{request.target}' needs unit_id (find one with find_{request.target})."
        )
    if request.target == "pose" and request.pose is None:
        raise InvalidInputError(
            "target='pose' needs pose={'matrix': <4x4 world_from_camera>, 'camera': "
            "'opencv'|'opengl', 'world_up': 'z'|'y'}."
        )
    if request.target == "situated" and (request.x is None or request.y is None):
        raise InvalidInputError(
            "target='situated' needs x and y (metres) and optionally heading_deg; it renders "
            "front, left, back and right views from the agent's camera height there."
        )


def render_request(glmap: GLMap, request: ViewRequest) -> Rendered:
    """Render what `request` asks for (call with the map's lock held).

    Raises:
        InvalidInputError: a missing argument, an empty map, or a unit of the other kind.
        UnknownIdError: no such unit (the message names the closest id).
    """
    check_request(request)
    if not glmap.instances:
        raise InvalidInputError(EMPTY_MAP)
    intrinsics = view_intrinsics(*request.size)
    if request.target in ("instance", "region"):
        return _selected(glmap, request)
    if request.target == "map":
        pose = gviews.overview_pose(glmap, intrinsics, MAP_ELEVATION_DEG)
        view = gviews.render_map(glmap, pose, intrinsics)
        note = (
            f"The camera looks down from {MAP_ELEVATION_DEG:.0f} deg above the horizon, from "
            "the side the map was observed from, and frames all of it."
        )
        return Rendered((view,), (note,))
    if request.target == "pose":
        assert request.pose is not None
        view = replace(gviews.render_map(glmap, request.pose, intrinsics), label="pose")
        return Rendered((view,), ())
    assert request.x is not None and request.y is not None
    around = gviews.situated_views(
        glmap, request.x, request.y, math.radians(request.heading_deg), intrinsics
    )
    by_direction = around.by_direction()
    note = (
        f"situated at ({around.x:.2f}, {around.y:.2f}), the agent's eye height "
        f"{around.camera_z:.2f} m; that spot is {around.cell_state} space in the map."
    )
    return Rendered(tuple(by_direction[d] for d in SITUATED_ORDER), (note,))


def _selected(glmap: GLMap, request: ViewRequest) -> Rendered:
    """The selected view of an instance or region (paper §3.2), with how it was chosen."""
    assert request.unit_id is not None
    unit = glmap.unit(request.unit_id)
    if request.target == "instance" and not isinstance(unit, InstanceUnit):
        raise InvalidInputError(f"unit {request.unit_id} is a region; use target='region'.")
    if request.target == "region" and not isinstance(unit, RegionUnit):
        raise InvalidInputError(f"unit {request.unit_id} is an instance; use target='instance'.")
    view, choice = gviews.render_selected_view(
        glmap, unit.id, view_intrinsics(*request.size), context=request.context
    )
    drawn = (
        "the whole map from that camera (context=false draws the unit alone)"
        if request.context
        else "the unit's own Gaussians only (context=true adds the rest of the map)"
    )
    notes = [
        f"view selection: {choice.note} Candidates stand at the agent's eye height in "
        "navigable space, facing the unit; the one that sees most of it unoccluded wins. "
        f"Drawn: {drawn}."
    ]
    if choice.fallback:
        notes.append(
            "The FALLBACK camera is not in space seen to be free; observe the space around "
            "the unit (e.g. walk there with sim_step) for a view from where the agent could "
            "stand."
        )
    return Rendered((view,), tuple(notes))


# ---------------------------------------------------------------------- top-down


# The frame of each map's last top-down image: kept while the map fits in it, so the
# scale and origin do not change from one map_summary to the next.
_FRAMES: weakref.WeakKeyDictionary[GLMap, TopDownFrame] = weakref.WeakKeyDictionary()


def topdown(glmap: GLMap) -> TopDownImage | None:
    """The labelled top-down image, the latest camera drawn as the agent; None when empty.

    Call with the map's lock held (the frame it keeps per map is updated).
    """
    if not glmap.instances and not glmap.occupancy.chunks:
        return None
    agent = Pose(np.asarray(glmap.trajectory[-1], np.float64)) if glmap.trajectory else None
    image = draw_topdown(glmap, agent=agent, frame=_FRAMES.get(glmap))
    if image.frame is not None:
        _FRAMES[glmap] = image.frame
    return image


def describe_topdown(image: TopDownImage | None) -> str:
    """How to read the top-down image, or why there is none yet."""
    if image is None:
        return "No top-down image yet: " + EMPTY_MAP
    return image.describe() + " The agent is the camera of the latest frame."


# ---------------------------------------------------------------------- warm-up


def warm_up() -> None:
    """Compile (or load from numba's cache) the splatting kernels, incl. the depth pass."""
    from glmap_tools.gaussians.render import render
    from glmap_tools.gaussians.render import warm_up as warm_renderer

    warm_renderer()
    g = GaussianSet(
        np.zeros((1, 3)), np.eye(3)[None] * 1e-3, np.ones((1, 3)), np.ones(1) * 0.8, np.ones(1)
    )
    pose = Pose.looking_at(np.array([1.0, 0.0, 0.0]), np.zeros(3))
    render(g, pose, view_intrinsics(16, 16), return_depth=True, return_alpha=True)
