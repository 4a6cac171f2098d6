"""Constants and camera set-up shared by the fast and the reference splatting rasterizers.

Both backends implement the same contract (see `render_design.md`); keeping the numbers in
one place keeps them equal.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from glmap_tools.geometry import Intrinsics, Pose

LOW_PASS = 0.3  # px^2 added to the diagonal of every 2D covariance (3DGS anti-aliasing)
ALPHA_MAX = 0.99  # a single Gaussian never makes a pixel fully opaque
ALPHA_MIN = 1.0 / 255.0  # contributions below this alpha are skipped
T_MIN = 1e-4  # a pixel stops before the Gaussian that would drop its transmittance below this
SIGMA_EXTENT = 3.0  # screen extent: a square of half-side ceil(3 sqrt(lambda_max)) pixels
JACOBIAN_MARGIN = 0.15  # the Jacobian's x/z, y/z are clamped to 15 % of the image past each edge
TILE = 32  # fast path: pixels per tile side


@dataclass(frozen=True)
class CameraSetup:
    """Camera quantities both backends derive from a pose and intrinsics.

    Attributes:
        rotation: [3, 3] float64, camera_from_world rotation (W in the EWA formula).
        translation: [3] float64, camera_from_world translation.
        tan_lo: [2] float64, lowest x/z and y/z used in the projection Jacobian.
        tan_hi: [2] float64, highest x/z and y/z used in the projection Jacobian.
    """

    rotation: np.ndarray  # [3, 3]
    translation: np.ndarray  # [3]
    tan_lo: np.ndarray  # [2]
    tan_hi: np.ndarray  # [2]


def camera_setup(pose: Pose, intrinsics: Intrinsics) -> CameraSetup:
    """The camera_from_world transform and the Jacobian clamp limits of a view."""
    cam_from_world = pose.inverse_matrix()
    k = intrinsics
    w, h = float(k.width), float(k.height)
    # Pixel centres sit at integer coordinates, so the image spans [-0.5, size - 0.5].
    tan_lo = np.array(
        [(-0.5 - JACOBIAN_MARGIN * w - k.cx) / k.fx, (-0.5 - JACOBIAN_MARGIN * h - k.cy) / k.fy]
    )
    tan_hi = np.array(
        [
            (w - 0.5 + JACOBIAN_MARGIN * w - k.cx) / k.fx,
            (h - 0.5 + JACOBIAN_MARGIN * h - k.cy) / k.fy,
        ]
    )
    return CameraSetup(
        np.ascontiguousarray(cam_from_world[:3, :3]),
        np.ascontiguousarray(cam_from_world[:3, 3]),
        tan_lo,
        tan_hi,
    )
