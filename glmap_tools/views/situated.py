"""Situated views (the SQA interface, paper §3.2): front, back, left and right of a position."""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from glmap_tools.errors import InvalidInputError
from glmap_tools.geometry import Intrinsics, Pose
from glmap_tools.map.occupancy import FREE, OBSTACLE
from glmap_tools.views.common import WHITE, RenderedView, check_intrinsics, view_intrinsics
from glmap_tools.views.targets import render_gaussians, require_drawable, scene_gaussians

if TYPE_CHECKING:
    from glmap_tools.map.glmap import GLMap

# Direction annotations d_k and their turn from the heading (counter-clockwise, z up).
DIRECTIONS = (("front", 0.0), ("back", math.pi), ("left", math.pi / 2), ("right", -math.pi / 2))
MAX_COORDINATE = 1e4  # m
_STATES = {FREE: "free", OBSTACLE: "obstacle"}


@dataclass(frozen=True)
class SituatedViews:
    """Four views from one spot, in the order front, back, left, right.

    Attributes:
        views: the rendered views; each label is its direction.
        x: position (m).
        y: position (m).
        heading: the facing direction (radians from +x, counter-clockwise).
        camera_z: camera height in the world (m): floor + camera_height.
        cell_state: occupancy of the spot: "free", "obstacle" or "unknown" (views are
            rendered whatever it is; an agent cannot stand in an obstacle).
    """

    views: tuple[RenderedView, ...]
    x: float
    y: float
    heading: float
    camera_z: float
    cell_state: str

    def by_direction(self) -> dict[str, RenderedView]:
        """The views keyed by "front", "back", "left", "right"."""
        return {v.label: v for v in self.views}


def situated_poses(glmap: GLMap, x: float, y: float, heading: float) -> list[tuple[str, Pose]]:
    """(direction, camera) at (x, y), floor + camera height, facing heading + each turn.

    Raises:
        InvalidInputError: a non-finite or out-of-range position or heading.
    """
    for name, value in (("x", x), ("y", y), ("heading", heading)):
        if isinstance(value, bool) or not isinstance(value, numbers.Real):
            raise InvalidInputError(f"{name}={value!r} must be a number.")
        if not (math.isfinite(value) and abs(value) <= MAX_COORDINATE):
            raise InvalidInputError(
                f"{name}={value!r} must be finite and within +-{MAX_COORDINATE:g} "
                "(metres for x, y; radians for heading)."
            )
    floor = glmap.floor_z if glmap.floor_z is not None else 0.0
    z = floor + glmap.config.camera_height
    return [
        (label, Pose.from_position_heading(float(x), float(y), z, float(heading) + turn))
        for label, turn in DIRECTIONS
    ]


def situated_views(
    glmap: GLMap,
    x: float,
    y: float,
    heading: float,
    intrinsics: Intrinsics | None = None,
    *,
    background: Sequence[float] = WHITE,
    structure: bool = True,
) -> SituatedViews:
    """Render the map front, back, left and right of (x, y) at the agent's camera height.

    Args:
        glmap: the map.
        x: position (m, world).
        y: position (m, world).
        heading: facing direction theta (radians from +x, counter-clockwise); left is
            theta + pi/2.
        intrinsics: the camera of each view; default `view_intrinsics()` (320x240, 79 deg).
        background: RGB in [0, 1] where nothing is mapped.
        structure: also draw the structure background layer, so walls hide what is
            behind them as they would for the agent.

    Raises:
        InvalidInputError: an empty map, a bad position or heading, or bad intrinsics.
    """
    intrinsics = check_intrinsics(intrinsics) if intrinsics is not None else view_intrinsics()
    poses = situated_poses(glmap, x, y, heading)
    require_drawable(glmap, structure)
    g = scene_gaussians(glmap, structure)
    views = tuple(
        render_gaussians(g, pose, intrinsics, label=label, background=background)
        for label, pose in poses
    )
    state = _STATES.get(glmap.occupancy.state_at(float(x), float(y)), "unknown")
    return SituatedViews(
        views, float(x), float(y), float(heading), float(poses[0][1].translation[2]), state
    )
