"""Pinhole intrinsics and rigid poses in the project's conventions.

World: right-handed, z up. Camera: OpenCV (x right, y down, z forward).
A `Pose` is always `world_from_camera`; other conventions enter through
`glmap_tools.geometry.adapters`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from glmap_tools.checks import is_real
from glmap_tools.errors import InvalidInputError
from glmap_tools.limits import MAX_COORDINATE

RIGID_TOLERANCE = 1e-4
MAX_IMAGE_SIDE = 8192
# Sane cameras only: a field of view up to MAX_FOV_DEG on either axis (wider pinhole views
# stretch pixels towards infinity), focal lengths at most MAX_FOCAL_RATIO image sides, the
# principal point within PRINCIPAL_MARGIN image sizes of the image, and camera centres
# within MAX_COORDINATE metres of the origin (glmap_tools.limits).
MAX_FOV_DEG = 170.0
MAX_FOCAL_RATIO = 100.0
PRINCIPAL_MARGIN = 0.5


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole camera intrinsics in pixels, with the image size they belong to."""

    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int

    def __post_init__(self) -> None:
        for name in ("fx", "fy", "cx", "cy"):
            value = getattr(self, name)
            if not is_real(value):
                raise InvalidInputError(f"Intrinsics {name}={value!r} is not a number of pixels.")
        for name in ("fx", "fy"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise InvalidInputError(
                    f"Intrinsics {name}={value!r} must be a positive finite focal length in "
                    "pixels; pass e.g. fx=fy=525 for a 640x480 PrimeSense camera."
                )
        for name in ("width", "height"):
            value = getattr(self, name)
            if not (isinstance(value, int | np.integer) and 0 < value <= MAX_IMAGE_SIDE):
                raise InvalidInputError(
                    f"Intrinsics {name}={value!r} must be an integer in 1..{MAX_IMAGE_SIDE}."
                )
        side = max(self.width, self.height)
        for f, c, size, axis in (
            ("fx", "cx", self.width, "horizontal"),
            ("fy", "cy", self.height, "vertical"),
        ):
            focal, centre = getattr(self, f), getattr(self, c)
            least = size / (2.0 * math.tan(math.radians(MAX_FOV_DEG) / 2.0))
            if focal < least:
                fov = math.degrees(2.0 * math.atan(size / (2.0 * focal)))
                raise InvalidInputError(
                    f"Intrinsics {f}={focal!r} gives a {axis} field of view of {fov:.6g} deg "
                    f"for {size} pixels; at most {MAX_FOV_DEG:g} deg is supported, so {f} "
                    f"must be >= {least:.4g}. Check the units (pixels) or undistort a fisheye."
                )
            if focal > MAX_FOCAL_RATIO * side:
                raise InvalidInputError(
                    f"Intrinsics {f}={focal!r} is over {MAX_FOCAL_RATIO:g} times the image "
                    f"side ({side} pixels); give the focal length in pixels of this image."
                )
            low, high = -PRINCIPAL_MARGIN * size, (1.0 + PRINCIPAL_MARGIN) * size
            if not (math.isfinite(centre) and low <= centre <= high):
                raise InvalidInputError(
                    f"Intrinsics {c}={centre!r} is not near the {size}-pixel image; the "
                    f"principal point must lie in [{low:g}, {high:g}], usually about {size / 2:g}."
                )

    @classmethod
    def from_fov(cls, width: int, height: int, hfov_deg: float) -> Intrinsics:
        """Square-pixel intrinsics from the horizontal field of view (degrees)."""
        if isinstance(hfov_deg, bool) or not (
            isinstance(hfov_deg, int | float | np.number) and 0 < hfov_deg <= MAX_FOV_DEG
        ):
            raise InvalidInputError(
                f"hfov_deg={hfov_deg!r} must be in (0, {MAX_FOV_DEG:g}] degrees, e.g. 79 for "
                "the agent camera."
            )
        for name, side in (("width", width), ("height", height)):
            if not (isinstance(side, int | np.integer) and 0 < side <= MAX_IMAGE_SIDE):
                raise InvalidInputError(
                    f"Intrinsics {name}={side!r} must be an integer in 1..{MAX_IMAGE_SIDE}."
                )
        fx = width / (2.0 * math.tan(math.radians(hfov_deg) / 2.0))
        return cls(fx, fx, (width - 1) / 2.0, (height - 1) / 2.0, int(width), int(height))

    @property
    def matrix(self) -> np.ndarray:
        """The 3x3 calibration matrix K."""
        return np.array([[self.fx, 0, self.cx], [0, self.fy, self.cy], [0, 0, 1]], dtype=np.float64)

    def scaled(self, width: int, height: int) -> Intrinsics:
        """The same camera at another resolution."""
        for name, side in (("width", width), ("height", height)):
            if not (isinstance(side, int | np.integer) and 0 < side <= MAX_IMAGE_SIDE):
                raise InvalidInputError(
                    f"Intrinsics {name}={side!r} must be an integer in 1..{MAX_IMAGE_SIDE}."
                )
        sx, sy = width / self.width, height / self.height
        return Intrinsics(
            self.fx * sx,
            self.fy * sy,
            (self.cx + 0.5) * sx - 0.5,
            (self.cy + 0.5) * sy - 0.5,
            int(width),
            int(height),
        )


@dataclass(frozen=True)
class Pose:
    """A rigid `world_from_camera` transform (OpenCV camera, z-up world).

    Attributes:
        matrix: [4, 4] float64 homogeneous transform; rotation orthonormal, det +1.
    """

    matrix: np.ndarray  # [4, 4]

    def __post_init__(self) -> None:
        try:
            m = np.asarray(self.matrix, dtype=np.float64)
        except (TypeError, ValueError):
            raise InvalidInputError(
                f"pose {self.matrix!r:.60} is not numbers; pass a 4x4 world_from_camera matrix."
            ) from None
        if m.shape != (4, 4):
            raise InvalidInputError(
                f"pose has shape {m.shape}; pass a 4x4 world_from_camera matrix."
            )
        if not np.all(np.isfinite(m)):
            raise InvalidInputError(
                "pose contains NaN or inf; pass a finite 4x4 world_from_camera matrix."
            )
        if not np.allclose(m[3], [0, 0, 0, 1], atol=RIGID_TOLERANCE):
            raise InvalidInputError(
                f"pose bottom row is {m[3].tolist()}; a rigid transform ends with [0, 0, 0, 1]."
            )
        far = float(np.abs(m[:3, 3]).max())
        if far > MAX_COORDINATE:
            raise InvalidInputError(
                f"pose translation {m[:3, 3].tolist()} is {far:.3g} m from the origin; camera "
                f"centres must lie within {MAX_COORDINATE:g} m. Give the position in metres "
                "(not mm), relative to a nearby origin."
            )
        r = m[:3, :3]
        err = float(np.abs(r @ r.T - np.eye(3)).max())
        det = float(np.linalg.det(r))
        if err > RIGID_TOLERANCE or abs(det - 1) > RIGID_TOLERANCE:
            raise InvalidInputError(
                f"pose rotation is not rigid (|R R^T - I| = {err:.3g}, det = {det:.4g}); "
                "pass an orthonormal rotation with det +1 (no scale or shear). If the pose is "
                "in another convention, convert it with glmap_tools.geometry.adapters."
            )
        object.__setattr__(self, "matrix", m)

    @classmethod
    def identity(cls) -> Pose:
        return cls(np.eye(4))

    @classmethod
    def from_rt(cls, rotation: np.ndarray, translation: np.ndarray) -> Pose:
        """Build from a [3, 3] rotation and a [3] translation (camera centre in world)."""
        m = np.eye(4)
        m[:3, :3] = rotation
        m[:3, 3] = np.asarray(translation, dtype=np.float64).reshape(3)
        return cls(m)

    @classmethod
    def looking_at(cls, eye: np.ndarray, target: np.ndarray, up: np.ndarray | None = None) -> Pose:
        """An OpenCV camera at `eye` whose optical axis points at `target` (z-up world)."""
        try:
            eye = np.asarray(eye, dtype=np.float64).reshape(3)
            forward = np.asarray(target, dtype=np.float64).reshape(3) - eye
        except (TypeError, ValueError):
            raise InvalidInputError(
                f"looking_at needs eye and target as three numbers each, not {eye!r:.40} and "
                f"{target!r:.40}."
            ) from None
        if not (np.abs(eye).max() <= 1e15 and np.abs(forward).max() <= 1e15):  # NaN fails too
            raise InvalidInputError(
                f"looking_at: eye {eye} and target must be finite metres (at most 1e15)."
            )
        norm = np.linalg.norm(forward)
        if norm < 1e-9:
            raise InvalidInputError("looking_at needs target != eye.")
        forward /= norm
        up_vec = np.array([0.0, 0.0, 1.0]) if up is None else np.asarray(up, dtype=np.float64)
        right = np.cross(forward, up_vec)
        if np.linalg.norm(right) < 1e-9:  # looking straight up or down
            right = np.cross(forward, np.array([0.0, 1.0, 0.0]))
        right /= np.linalg.norm(right)
        down = np.cross(forward, right)
        return cls.from_rt(np.stack([right, down, forward], axis=1), eye)

    @classmethod
    def from_position_heading(
        cls, x: float, y: float, height: float, heading: float, pitch: float = 0.0
    ) -> Pose:
        """A camera at (x, y, height) looking along planar `heading` (radians from +x, CCW).

        `pitch` tilts the view, positive down (radians).
        """
        named = (("x", x), ("y", y), ("height", height), ("heading", heading), ("pitch", pitch))
        for name, value in named:
            if not (is_real(value) and math.isfinite(value)):
                raise InvalidInputError(f"{name}={value!r} must be a finite number.")
        forward = np.array(
            [
                math.cos(heading) * math.cos(pitch),
                math.sin(heading) * math.cos(pitch),
                -math.sin(pitch),
            ]
        )
        eye = np.array([x, y, height], dtype=np.float64)
        return cls.looking_at(eye, eye + forward)

    @property
    def rotation(self) -> np.ndarray:
        return self.matrix[:3, :3]

    @property
    def translation(self) -> np.ndarray:
        return self.matrix[:3, 3]

    @property
    def heading(self) -> float:
        """Planar angle of the optical axis in the world x-y plane (radians from +x, CCW)."""
        f = self.matrix[:3, 2]
        return math.atan2(f[1], f[0])

    def inverse_matrix(self) -> np.ndarray:
        """camera_from_world as a [4, 4] matrix."""
        inv = np.eye(4)
        inv[:3, :3] = self.rotation.T
        inv[:3, 3] = -self.rotation.T @ self.translation
        return inv

    def transform_points(self, points_camera: np.ndarray) -> np.ndarray:
        """Map [N, 3] camera-frame points to the world."""
        return points_camera @ self.rotation.T + self.translation
