"""Scoring a candidate camera: how much of a target's Gaussians it sees past the rest."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from glmap_tools.gaussians.render import DEFAULT_NEAR, render
from glmap_tools.gaussians.types import GaussianSet
from glmap_tools.geometry import Intrinsics, Pose

EMPTY_ALPHA = 0.25  # z-buffer pixels with less accumulated opacity hide nothing


@dataclass(frozen=True)
class Visibility:
    """How much of a target one camera sees (all fractions opacity-weighted, in [0, 1]).

    Attributes:
        score: the view's score: the sum over visible Gaussians of opacity x facing, over
            the sum of all opacities (facing = the Gaussian's projected area across the
            viewing ray over its largest possible projected area).
        visible: fraction in view and not occluded.
        in_view: fraction whose means project into the image, in front of the camera.
    """

    score: float
    visible: float
    in_view: float


def facing(gaussians: GaussianSet, eye: np.ndarray) -> np.ndarray:  # -> [N]
    """Projected area of each Gaussian across the ray from `eye`, over its largest.

    The 1-sigma ellipsoid of covariance S projects onto the plane normal to a unit ray r
    with area pi sqrt(det S r^T S^-1 r); the largest, across the smallest axis, is
    pi sqrt(l1 l2) (eigenvalues l0 <= l1 <= l2), so the ratio is sqrt(l0 r^T S^-1 r):
    1 for a surface seen face-on, about sqrt(l0 / l1) edge-on, 1 everywhere for a ball.
    """
    return Scorer(gaussians).facing(np.asarray(eye, np.float64))


class Scorer:
    """Per-target arrays reused across candidates: means, weights, S^-1 and l0."""

    def __init__(self, target: GaussianSet) -> None:
        covs = target.covs.astype(np.float64)
        self.means = target.means.astype(np.float64)  # [N, 3]
        self.inv = np.linalg.inv(covs)  # [N, 3, 3]
        self.lam0 = np.linalg.eigvalsh(covs)[:, 0]  # [N]
        self.weights = target.opacities.astype(np.float64)  # [N]
        self.total = float(self.weights.sum())

    def facing(self, eye: np.ndarray) -> np.ndarray:  # -> [N]
        rays = self.means - eye[None, :]
        rays /= np.maximum(np.linalg.norm(rays, axis=1, keepdims=True), 1e-12)
        quad = np.einsum("ni,nij,nj->n", rays, self.inv, rays)
        return np.clip(np.sqrt(np.maximum(self.lam0 * quad, 0.0)), 0.0, 1.0)

    def __call__(
        self, occluders: GaussianSet, pose: Pose, intrinsics: Intrinsics, margin: float
    ) -> Visibility:
        zbuf = render(occluders, pose, intrinsics, return_depth=True, return_alpha=True)
        assert zbuf.depth is not None and zbuf.alpha is not None
        cam = (self.means - pose.translation) @ pose.rotation
        z = cam[:, 2]
        front = z > DEFAULT_NEAR
        zs = np.where(front, z, 1.0)
        u = np.rint(intrinsics.fx * cam[:, 0] / zs + intrinsics.cx).astype(np.int64)
        v = np.rint(intrinsics.fy * cam[:, 1] / zs + intrinsics.cy).astype(np.int64)
        in_view = front & (u >= 0) & (u < intrinsics.width) & (v >= 0) & (v < intrinsics.height)
        uu, vv = np.where(in_view, u, 0), np.where(in_view, v, 0)
        empty = zbuf.alpha[vv, uu] < EMPTY_ALPHA
        visible = in_view & (empty | (z <= zbuf.depth[vv, uu] + margin))
        w = self.weights
        score = float((w * self.facing(pose.translation))[visible].sum() / self.total)
        return Visibility(
            score, float(w[visible].sum() / self.total), float(w[in_view].sum() / self.total)
        )


def visibility(
    target: GaussianSet,
    occluders: GaussianSet,
    pose: Pose,
    intrinsics: Intrinsics,
    margin: float,
) -> Visibility:
    """Score one camera: how much of `target` it sees past `occluders`.

    A target Gaussian is in view when its mean lies beyond the near plane and projects
    inside the image; it is visible when, in addition, the z-buffer of `occluders` (their
    splatted expected depth, `render(..., return_depth=True)`) at its pixel is empty
    (alpha < EMPTY_ALPHA) or no nearer than its own depth minus `margin`. EMPTY_ALPHA is
    0.25, not 0.5: the gaps between a wall's merged Gaussians reach alpha 0.3-0.5 and
    would let 10 % of an object behind it count as seen.
    """
    return Scorer(target)(occluders, pose, intrinsics, margin)
