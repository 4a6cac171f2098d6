"""Render quality against a real image: PSNR over the pixels the map covers."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import cv2
import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.geometry import Intrinsics, Pose
from glmap_tools.views.common import RenderedView
from glmap_tools.views.targets import render_map

if TYPE_CHECKING:
    from glmap_tools.map.glmap import GLMap

BLACK = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class CoverageScore:
    """How well a render matches a real image where the map covers it.

    Attributes:
        psnr: dB over covered pixels, the map's own colour (the render over black divided
            by its alpha) against the real image: colour fidelity, whatever the coverage.
        psnr_composited: dB over the same pixels, the render over a black background
            against the real image: what a viewer sees, half-covered pixels darkened.
        coverage: fraction of the image's pixels with alpha above the threshold.
        alpha_threshold: the accumulated opacity a pixel needs to count as covered.
    """

    psnr: float
    psnr_composited: float
    coverage: float
    alpha_threshold: float


def _psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = float(np.mean((a - b) ** 2))
    return math.inf if mse == 0 else 10.0 * math.log10(1.0 / mse)


def coverage_psnr(
    view: RenderedView, real_rgb: np.ndarray, alpha_threshold: float = 0.5
) -> CoverageScore:
    """Score `view` (rendered over black) against a real [H, W, 3] uint8 image.

    Raises:
        InvalidInputError: the images differ in size, the real one is not uint8 RGB, or
            no pixel is covered.
    """
    real = np.asarray(real_rgb)
    if real.dtype != np.uint8 or real.shape != view.rgb.shape:
        raise InvalidInputError(
            f"real image is {real.dtype} {real.shape}; pass uint8 RGB of the rendered size "
            f"{view.rgb.shape}."
        )
    covered = view.alpha > alpha_threshold
    if not covered.any():
        raise InvalidInputError(
            f"the render covers no pixel with alpha > {alpha_threshold}; the map is not in view."
        )
    truth = real[covered].astype(np.float64) / 255.0
    shown = view.rgb[covered].astype(np.float64) / 255.0
    own = np.clip(shown / view.alpha[covered, None].astype(np.float64), 0.0, 1.0)
    return CoverageScore(
        _psnr(own, truth), _psnr(shown, truth), float(covered.mean()), alpha_threshold
    )


def render_against(
    glmap: GLMap, pose: Pose, intrinsics: Intrinsics, real_rgb: np.ndarray
) -> tuple[CoverageScore, RenderedView]:
    """Render the map's instances over black at a real frame's camera and score them.

    The structure layer is left out: this scores the semantic units' Gaussians, as the
    held-out PSNR figures in design.md were measured.
    """
    view = render_map(glmap, pose, intrinsics, background=BLACK, structure=False)
    return coverage_psnr(view, real_rgb), view


def side_by_side(view: RenderedView, real_rgb: np.ndarray, gap: int = 8) -> np.ndarray:
    """[H, 3W + 2 gap, 3] uint8: the render, the real image, and the real image dimmed
    where the map does not cover it (alpha <= 0.5)."""
    real = np.asarray(real_rgb, np.uint8)
    dimmed = real.copy()
    outside = view.alpha <= 0.5
    dimmed[outside] = (dimmed[outside] * 0.25).astype(np.uint8)
    h = view.rgb.shape[0]
    white = np.full((h, gap, 3), 255, np.uint8)
    image = np.concatenate([view.rgb, white, real, white, dimmed], axis=1)
    for text, x in (("render", 6), ("real", view.rgb.shape[1] + gap + 6)):
        cv2.putText(image, text, (x, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (255, 255, 0), 2)
    return image
