"""Render a `GaussianSet` from a camera by EWA splatting (3DGS, Kerbl et al. 2023) on the CPU.

`render` validates its inputs once and dispatches to the fast tile rasterizer (numba) or to
the slow per-pixel reference; both follow the contract in `render_design.md`.
"""

from __future__ import annotations

import math
import numbers
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from glmap_tools.errors import InvalidInputError, did_you_mean
from glmap_tools.gaussians._render_common import (
    ALPHA_MAX,
    ALPHA_MIN,
    LOW_PASS,
    SIGMA_EXTENT,
    T_MIN,
    TILE,
)
from glmap_tools.gaussians._render_numba import render_fast
from glmap_tools.gaussians.render_reference import render_reference
from glmap_tools.gaussians.types import GaussianSet
from glmap_tools.geometry import Intrinsics, Pose

MAX_RENDER_SIDE = 4096  # pixels per image side
MAX_RENDER_PIXELS = 16_000_000  # 16 Mpx per image
DEFAULT_BACKGROUND = (1.0, 1.0, 1.0)  # white
DEFAULT_NEAR = 0.05  # m
DEFAULT_FAR = 50.0  # m
BACKENDS = ("fast", "reference")
# numba's workqueue threading layer cannot run parallel kernels from two threads at once.
_FAST_LOCK = threading.Lock()

__all__ = [
    "ALPHA_MAX",
    "ALPHA_MIN",
    "BACKENDS",
    "LOW_PASS",
    "MAX_RENDER_PIXELS",
    "MAX_RENDER_SIDE",
    "SIGMA_EXTENT",
    "TILE",
    "T_MIN",
    "RenderResult",
    "render",
    "render_image",
    "warm_up",
]


@dataclass(frozen=True)
class RenderResult:
    """A rendered view.

    Attributes:
        rgb: [H, W, 3] float32 in [0, 1], composited over the background.
        depth: [H, W] float32 metres or None: the expected camera z of the composited
            Gaussians, sum_i(w_i z_i) / alpha with w_i = alpha_i T_i; 0 where no Gaussian
            contributes (alpha == 0).
        alpha: [H, W] float32 in [0, 1) or None: accumulated opacity, 1 - final transmittance.
    """

    rgb: np.ndarray  # [H, W, 3]
    depth: np.ndarray | None = None  # [H, W]
    alpha: np.ndarray | None = None  # [H, W]

    def to_uint8(self) -> np.ndarray:
        """The colour image as [H, W, 3] uint8 RGB (rounded)."""
        return (np.clip(self.rgb, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)


def _check_inputs(
    gaussians: GaussianSet,
    pose: Pose,
    intrinsics: Intrinsics,
    background: Sequence[float],
    near: float,
    far: float,
    backend: str,
) -> tuple[float, float, float]:
    """Validate `render`'s arguments; return the background as three floats."""
    if not isinstance(gaussians, GaussianSet):
        raise InvalidInputError(
            f"gaussians is a {type(gaussians).__name__}; pass a glmap_tools.gaussians.GaussianSet."
        )
    if not isinstance(pose, Pose):
        raise InvalidInputError(
            f"pose is a {type(pose).__name__}; pass a glmap_tools.geometry.Pose "
            "(world_from_camera, e.g. Pose(matrix) or Pose.looking_at(eye, target))."
        )
    if not isinstance(intrinsics, Intrinsics):
        raise InvalidInputError(
            f"intrinsics is a {type(intrinsics).__name__}; pass a glmap_tools.geometry.Intrinsics "
            "(e.g. Intrinsics.from_fov(width, height, hfov_deg))."
        )
    w, h = intrinsics.width, intrinsics.height
    for name, side in (("width", w), ("height", h)):
        if not 0 < side <= MAX_RENDER_SIDE:
            raise InvalidInputError(
                f"image {name}={side} is outside 1..{MAX_RENDER_SIDE} pixels; render at most "
                f"{MAX_RENDER_SIDE} px per side (Intrinsics.scaled can shrink the camera)."
            )
    if w * h > MAX_RENDER_PIXELS:
        raise InvalidInputError(
            f"image {w}x{h} has {w * h} pixels, over the cap of {MAX_RENDER_PIXELS}; render a "
            "smaller image (Intrinsics.scaled can shrink the camera)."
        )
    if not (isinstance(near, numbers.Real) and isinstance(far, numbers.Real)):
        raise InvalidInputError(f"near={near!r} and far={far!r} must be numbers of metres.")
    if not (math.isfinite(near) and math.isfinite(far) and 0 < near < far):
        raise InvalidInputError(
            f"near={near!r}, far={far!r} must be finite with 0 < near < far metres "
            f"(defaults {DEFAULT_NEAR}, {DEFAULT_FAR})."
        )
    try:
        bg = np.asarray(background, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        bg = np.zeros(0)  # not numbers: refused below
    if bg.shape != (3,) or not np.all(np.isfinite(bg)) or bg.min() < 0 or bg.max() > 1:
        raise InvalidInputError(
            f"background={background!r} must be three RGB floats in [0, 1], e.g. (1, 1, 1)."
        )
    if not isinstance(backend, str) or backend not in BACKENDS:
        raise InvalidInputError(
            f"backend={backend!r} is not one of {BACKENDS}."
            + (did_you_mean(backend, BACKENDS) if isinstance(backend, str) else "")
        )
    return float(bg[0]), float(bg[1]), float(bg[2])


def render(
    gaussians: GaussianSet,
    pose: Pose,
    intrinsics: Intrinsics,
    *,
    background: Sequence[float] = DEFAULT_BACKGROUND,
    near: float = DEFAULT_NEAR,
    far: float = DEFAULT_FAR,
    return_depth: bool = False,
    return_alpha: bool = False,
    backend: Literal["fast", "reference"] = "fast",
) -> RenderResult:
    """Splat `gaussians` into the image of a camera at `pose`.

    Each Gaussian is projected with the EWA Jacobian (2D covariance J W Sigma W^T J^T plus
    LOW_PASS px^2 on the diagonal), culled unless its mean lies at near <= z <= far, and
    composited front to back by camera z: alpha = min(ALPHA_MAX, opacity exp(-d^T conic d / 2))
    over the pixels of its 3-sigma square, skipping alpha < ALPHA_MIN and stopping a pixel
    before its transmittance would fall below T_MIN. The background shows through the final
    transmittance.

    Args:
        gaussians: the Gaussians to draw (world frame); any GaussianSet, possibly empty.
        pose: world_from_camera (OpenCV camera: x right, y down, z forward; z-up world).
        intrinsics: pinhole camera; its width x height is the image size (at most
            MAX_RENDER_SIDE per side and MAX_RENDER_PIXELS in all).
        background: RGB in [0, 1] behind the Gaussians.
        near: metres; Gaussians whose mean is nearer are dropped.
        far: metres; Gaussians whose mean is farther are dropped.
        return_depth: also return the expected-depth image.
        return_alpha: also return the accumulated-opacity image.
        backend: "fast" (numba tiles) or "reference" (slow per-pixel loop, for tests).

    Returns:
        A RenderResult; `depth` and `alpha` are None unless requested.

    Raises:
        InvalidInputError: a malformed argument or an image over the size caps.
    """
    bg = _check_inputs(gaussians, pose, intrinsics, background, near, far, backend)
    for name, flag in (("return_depth", return_depth), ("return_alpha", return_alpha)):
        if not isinstance(flag, bool | np.bool_):
            raise InvalidInputError(f"{name}={flag!r:.40} must be True or False.")
    if len(gaussians) == 0:
        h, w = intrinsics.height, intrinsics.width
        rgb = np.empty((h, w, 3), dtype=np.float32)
        rgb[:] = np.asarray(bg, dtype=np.float32)
        depth = np.zeros((h, w), dtype=np.float32)
        alpha = np.zeros((h, w), dtype=np.float32)
    elif backend == "fast":
        with _FAST_LOCK:  # the kernels already use every core; one frame at a time
            rgb, depth, alpha = render_fast(
                gaussians, pose, intrinsics, bg, float(near), float(far)
            )
    else:
        rgb, depth, alpha = render_reference(
            gaussians, pose, intrinsics, bg, float(near), float(far)
        )
    return RenderResult(rgb, depth if return_depth else None, alpha if return_alpha else None)


def render_image(
    gaussians: GaussianSet,
    pose: Pose,
    intrinsics: Intrinsics,
    *,
    background: Sequence[float] = DEFAULT_BACKGROUND,
    near: float = DEFAULT_NEAR,
    far: float = DEFAULT_FAR,
    backend: Literal["fast", "reference"] = "fast",
) -> np.ndarray:
    """Render and return the colour image as [H, W, 3] uint8 RGB (see `render`)."""
    result = render(
        gaussians, pose, intrinsics, background=background, near=near, far=far, backend=backend
    )
    return result.to_uint8()


def warm_up() -> float:
    """Compile the fast kernels (or load them from numba's on-disk cache); return seconds.

    Call once at start-up, e.g. in the MCP server's lifespan, so that the first real render
    does not pay for it.
    """
    t0 = time.perf_counter()
    k = Intrinsics(8.0, 8.0, 3.5, 3.5, 8, 8)
    g = GaussianSet(
        np.array([[0.0, 0.0, 1.0]]),
        np.eye(3)[None] * 0.01,
        np.full((1, 3), 0.5),
        np.ones(1),
        np.ones(1),
    )
    render(g, Pose.identity(), k)
    return time.perf_counter() - t0
