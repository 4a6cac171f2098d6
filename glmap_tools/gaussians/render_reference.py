"""Slow, obviously correct EWA splatting: every pixel composites every Gaussian by depth.

This is the contract the fast tile rasterizer (`_render_numba`) is held to in the tests. It
is plain numpy and Python loops, fine for small images and a few thousand Gaussians.
Inputs are assumed validated by `glmap_tools.gaussians.render.render`.
"""

from __future__ import annotations

import numpy as np

from glmap_tools.gaussians._render_common import (
    ALPHA_MAX,
    ALPHA_MIN,
    LOW_PASS,
    SIGMA_EXTENT,
    T_MIN,
    camera_setup,
)
from glmap_tools.gaussians.types import GaussianSet
from glmap_tools.geometry import Intrinsics, Pose


def project_reference(
    gaussians: GaussianSet, pose: Pose, intrinsics: Intrinsics, near: float, far: float
) -> dict[str, np.ndarray]:
    """Project Gaussians to the image (EWA), keeping those in front of the camera.

    Returns:
        Arrays over the kept Gaussians, sorted front to back (stable in the input order):
        `index` [M] original index, `depth` [M] camera z (m), `center` [M, 2] pixel
        coordinates of the projected mean, `conic` [M, 3] (a, b, c) of the inverse 2D
        covariance, `radius` [M] screen extent in pixels, `opacity` [M], `color` [M, 3].
    """
    cam = camera_setup(pose, intrinsics)
    k = intrinsics
    m = gaussians.means.astype(np.float64)  # [N, 3]
    r, t = cam.rotation, cam.translation
    # Camera coordinates term by term, in the fast kernel's order: the sort keys are then
    # bit-identical, so depth ties (coplanar Gaussians) break the same way, by input order.
    x = r[0, 0] * m[:, 0] + r[0, 1] * m[:, 1] + r[0, 2] * m[:, 2] + t[0]
    y = r[1, 0] * m[:, 0] + r[1, 1] * m[:, 1] + r[1, 2] * m[:, 2] + t[1]
    z = r[2, 0] * m[:, 0] + r[2, 1] * m[:, 1] + r[2, 2] * m[:, 2] + t[2]
    with np.errstate(all="ignore"):
        # Jacobian of (fx x/z + cx, fy y/z + cy) at the mean, with x/z and y/z clamped.
        tx = np.clip(x / z, cam.tan_lo[0], cam.tan_hi[0]) * z
        ty = np.clip(y / z, cam.tan_lo[1], cam.tan_hi[1]) * z
        jac = np.zeros((len(z), 2, 3))
        jac[:, 0, 0] = k.fx / z
        jac[:, 0, 2] = -k.fx * tx / (z * z)
        jac[:, 1, 1] = k.fy / z
        jac[:, 1, 2] = -k.fy * ty / (z * z)
        jw = jac @ cam.rotation  # [N, 2, 3]
        cov2d = jw @ gaussians.covs.astype(np.float64) @ jw.transpose(0, 2, 1)  # [N, 2, 2]
        cov2d += LOW_PASS * np.eye(2)
        a, b, c = cov2d[:, 0, 0], cov2d[:, 0, 1], cov2d[:, 1, 1]
        det = a * c - b * b
        conic = np.stack([c / det, -b / det, a / det], axis=1)
        mid = 0.5 * (a + c)
        lambda_max = mid + np.sqrt(np.maximum(mid * mid - det, 0.0))
        radius = np.ceil(SIGMA_EXTENT * np.sqrt(lambda_max))
        center = np.stack([k.fx * x / z + k.cx, k.fy * y / z + k.cy], axis=1)
    keep = (
        (z >= near)
        & (z <= far)
        & (det > 0)
        & np.isfinite(center).all(axis=1)
        & np.isfinite(conic).all(axis=1)
        & np.isfinite(radius)
    )
    index = np.flatnonzero(keep)
    index = index[np.argsort(z[index], kind="stable")]
    return {
        "index": index,
        "depth": z[index],
        "center": center[index],
        "conic": conic[index],
        "radius": radius[index],
        "opacity": gaussians.opacities[index].astype(np.float64),
        "color": gaussians.colors[index].astype(np.float64),
    }


def render_reference(
    gaussians: GaussianSet,
    pose: Pose,
    intrinsics: Intrinsics,
    background: tuple[float, float, float],
    near: float,
    far: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Render by compositing, for each pixel, all Gaussians front to back.

    Returns:
        rgb [H, W, 3] float32 in [0, 1], depth [H, W] float32 (expected camera z over the
        composited Gaussians, 0 where none contributes), alpha [H, W] float32 (1 - final
        transmittance).
    """
    p = project_reference(gaussians, pose, intrinsics, near, far)
    h, w = intrinsics.height, intrinsics.width
    rgb = np.empty((h, w, 3), dtype=np.float32)
    depth = np.zeros((h, w), dtype=np.float32)
    alpha_img = np.zeros((h, w), dtype=np.float32)
    bg = np.asarray(background, dtype=np.float64)
    cu, cv = p["center"][:, 0], p["center"][:, 1]
    ca, cb, cc = p["conic"][:, 0], p["conic"][:, 1], p["conic"][:, 2]
    for py in range(h):
        for px in range(w):
            dx = px - cu
            dy = py - cv
            inside = (np.abs(dx) <= p["radius"]) & (np.abs(dy) <= p["radius"])
            m = ca * dx * dx + 2.0 * cb * dx * dy + cc * dy * dy
            alphas = np.minimum(ALPHA_MAX, p["opacity"] * np.exp(-0.5 * m))
            transmittance, color, z_sum = 1.0, np.zeros(3), 0.0
            for i in np.flatnonzero(inside & (alphas >= ALPHA_MIN)):  # front to back
                a = float(alphas[i])
                next_t = transmittance * (1.0 - a)
                if next_t < T_MIN:
                    break
                color += a * transmittance * p["color"][i]
                z_sum += a * transmittance * p["depth"][i]
                transmittance = next_t
            opacity = 1.0 - transmittance
            rgb[py, px] = np.clip(color + transmittance * bg, 0.0, 1.0)
            alpha_img[py, px] = opacity
            depth[py, px] = z_sum / opacity if opacity > 0.0 else 0.0
    return rgb, depth, alpha_img
