"""What every view shares: the rendered-view type, image-size caps, pose and id checks."""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass
from typing import TYPE_CHECKING

import cv2
import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.geometry import Intrinsics, Pose

if TYPE_CHECKING:
    from glmap_tools.map.glmap import GLMap

DEFAULT_HFOV_DEG = 79.0  # the agent camera's horizontal field of view
DEFAULT_SIZE = (320, 240)  # width, height in pixels
MAX_VIEW_SIDE = 2048  # pixels per image side (so at most 4.2 Mpx per view)
WHITE = (1.0, 1.0, 1.0)


@dataclass(frozen=True)
class RenderedView:
    """One rendered image and the camera it was rendered from.

    Attributes:
        label: what was rendered, e.g. "instance 3" or "front".
        rgb: [H, W, 3] uint8 RGB, composited over the background.
        alpha: [H, W] float32 in [0, 1): how much of each pixel the Gaussians cover.
        pose: world_from_camera (OpenCV camera, z-up world).
        intrinsics: the pinhole camera; its width x height is the image size.
        depth: [H, W] float32 expected camera z (m), 0 where nothing is drawn; only when asked.
    """

    label: str
    rgb: np.ndarray  # [H, W, 3]
    alpha: np.ndarray  # [H, W]
    pose: Pose
    intrinsics: Intrinsics
    depth: np.ndarray | None = None  # [H, W]

    def to_png(self) -> bytes:
        """The colour image as PNG bytes."""
        return encode_png(self.rgb)

    def describe(self) -> str:
        """One line: the label, camera position, heading, pitch and field of view."""
        eye = self.pose.translation
        forward = self.pose.rotation[:, 2]
        pitch = math.degrees(math.asin(max(-1.0, min(1.0, -float(forward[2])))))
        hfov = math.degrees(2 * math.atan(self.intrinsics.width / (2 * self.intrinsics.fx)))
        return (
            f"{self.label}: camera at ({eye[0]:.2f}, {eye[1]:.2f}, {eye[2]:.2f}) m, heading "
            f"{round(math.degrees(self.pose.heading))} deg (from +x, counter-clockwise), pitch "
            f"{round(pitch)} deg down, hfov {hfov:.0f} deg"
        )


def encode_png(rgb: np.ndarray) -> bytes:  # rgb: [H, W, 3] uint8
    """PNG bytes of an RGB uint8 image."""
    ok, buf = cv2.imencode(".png", cv2.cvtColor(np.ascontiguousarray(rgb), cv2.COLOR_RGB2BGR))
    assert ok, "PNG encoding of a uint8 image cannot fail"
    return buf.tobytes()


# ---------------------------------------------------------------------- validation


def _check_side(name: str, value: object) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise InvalidInputError(f"{name}={value!r} must be an integer number of pixels.")
    if not 1 <= int(value) <= MAX_VIEW_SIDE:
        raise InvalidInputError(
            f"{name}={value!r} is outside 1..{MAX_VIEW_SIDE} pixels (the view size cap); "
            f"ask for e.g. {DEFAULT_SIZE[0]}x{DEFAULT_SIZE[1]} (Intrinsics.scaled shrinks a "
            "camera)."
        )
    return int(value)


def check_intrinsics(intrinsics: Intrinsics) -> Intrinsics:
    """Return `intrinsics` if its image is within the view cap; raise otherwise.

    Raises:
        InvalidInputError: not an Intrinsics, or a side over MAX_VIEW_SIDE pixels.
    """
    if not isinstance(intrinsics, Intrinsics):
        raise InvalidInputError(
            f"intrinsics is a {type(intrinsics).__name__}; pass a glmap_tools.geometry."
            "Intrinsics, e.g. view_intrinsics(320, 240)."
        )
    _check_side("width", intrinsics.width)
    _check_side("height", intrinsics.height)
    return intrinsics


def view_intrinsics(
    width: int = DEFAULT_SIZE[0], height: int = DEFAULT_SIZE[1], hfov_deg: float = DEFAULT_HFOV_DEG
) -> Intrinsics:
    """Square-pixel intrinsics for a width x height view with a horizontal field of view.

    Args:
        width: pixels, 1..MAX_VIEW_SIDE.
        height: pixels, 1..MAX_VIEW_SIDE.
        hfov_deg: horizontal field of view in degrees, in [1, 170].

    Raises:
        InvalidInputError: a size outside the caps or a field of view outside [1, 170].
    """
    w, h = _check_side("width", width), _check_side("height", height)
    if not (isinstance(hfov_deg, numbers.Real) and 1.0 <= float(hfov_deg) <= 170.0):
        raise InvalidInputError(
            f"hfov_deg={hfov_deg!r} must be a number of degrees in [1, 170] "
            f"(the agent camera has {DEFAULT_HFOV_DEG})."
        )
    return check_intrinsics(Intrinsics.from_fov(w, h, float(hfov_deg)))


def as_pose(pose: Pose | np.ndarray) -> Pose:
    """A `Pose` from a Pose or a 4x4 world_from_camera matrix; raises if it is not rigid."""
    if isinstance(pose, Pose):
        return pose
    if isinstance(pose, np.ndarray | list | tuple):
        try:
            matrix = np.asarray(pose, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise InvalidInputError(
                "pose must be a 4x4 numeric world_from_camera matrix or a Pose."
            ) from exc
        return Pose(matrix)  # raises InvalidInputError unless rigid
    raise InvalidInputError(
        f"pose is a {type(pose).__name__}; pass a glmap_tools.geometry.Pose or a 4x4 "
        "world_from_camera matrix (OpenCV camera, z-up world)."
    )


def check_unit_id(unit_id: object) -> int:
    """`unit_id` as an int; raises InvalidInputError for a non-integer (bools included)."""
    if isinstance(unit_id, bool) or not isinstance(unit_id, numbers.Integral):
        raise InvalidInputError(
            f"unit id {unit_id!r} must be an integer id (find one with find_instances)."
        )
    return int(unit_id)


def require_instances(glmap: GLMap) -> None:
    """Raise InvalidInputError if the map has no instance to draw."""
    if not glmap.instances:
        raise InvalidInputError(
            "the map is empty (no instances); integrate frames before rendering or exporting it."
        )
