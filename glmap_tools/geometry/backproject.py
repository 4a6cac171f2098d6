"""Back-projection of (masked) depth images to coloured world-frame point clouds."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.geometry.camera import Intrinsics, Pose

DEFAULT_MAX_RANGE = 5.0  # metres; farther depth is noisy on consumer RGB-D sensors


@dataclass(frozen=True)
class PointCloud:
    """World-frame points with colours.

    Attributes:
        points: [N, 3] float64, metres.
        colors: [N, 3] float32 RGB in [0, 1].
    """

    points: np.ndarray  # [N, 3]
    colors: np.ndarray  # [N, 3]

    def __len__(self) -> int:
        return int(self.points.shape[0])


def depth_from_uint16(depth: np.ndarray, depth_scale: float) -> np.ndarray:
    """Convert a uint16 depth image to float32 metres (0 stays 0 = no measurement).

    Args:
        depth: [H, W] uint16 raw depth.
        depth_scale: raw units per metre (1000 for Redwood/ScanNet, 5000 for TUM).
    """
    check_depth_scale(depth_scale)
    return (np.asarray(depth).astype(np.float32) / np.float32(depth_scale)).astype(np.float32)


def check_depth_scale(depth_scale: float) -> None:
    """Raise unless `depth_scale` is positive and float32 holds it (normal, finite).

    Raises:
        InvalidInputError: naming the value and the usual scales.
    """
    f32 = np.finfo(np.float32)
    number = isinstance(depth_scale, int | float) and not isinstance(depth_scale, bool)
    if not (number and float(f32.tiny) <= depth_scale <= float(f32.max)):
        raise InvalidInputError(
            f"depth_scale={depth_scale!r} must be a positive number of raw units per metre "
            "(1000 for millimetres, 5000 for TUM)."
        )


def valid_depth_mask(depth: np.ndarray, max_range: float = DEFAULT_MAX_RANGE) -> np.ndarray:
    """[H, W] bool: finite, positive depth within `max_range` metres."""
    with np.errstate(invalid="ignore"):
        return np.isfinite(depth) & (depth > 0) & (depth <= max_range)


def check_frame_shapes(
    depth: np.ndarray,
    intrinsics: Intrinsics,
    rgb: np.ndarray | None = None,
    mask: np.ndarray | None = None,
) -> None:
    """Raise InvalidInputError unless depth, rgb, mask and intrinsics agree in size."""
    if depth.ndim != 2:
        raise InvalidInputError(f"depth has shape {depth.shape}; pass a [H, W] depth image.")
    h, w = depth.shape
    if (w, h) != (intrinsics.width, intrinsics.height):
        raise InvalidInputError(
            f"depth is {w}x{h} but intrinsics are for {intrinsics.width}x{intrinsics.height}; "
            "pass intrinsics for this image size (Intrinsics.scaled can rescale them)."
        )
    if rgb is not None and (rgb.ndim != 3 or rgb.shape[:2] != (h, w) or rgb.shape[2] != 3):
        raise InvalidInputError(
            f"rgb has shape {rgb.shape} but depth is {depth.shape}; pass an [H, W, 3] colour "
            "image registered to the depth image."
        )
    if mask is not None and mask.shape != (h, w):
        raise InvalidInputError(
            f"mask has shape {mask.shape} but depth is {depth.shape}; masks must match the "
            "depth image pixel for pixel."
        )


def backproject(
    depth: np.ndarray,
    intrinsics: Intrinsics,
    pose: Pose,
    rgb: np.ndarray | None = None,
    mask: np.ndarray | None = None,
    max_range: float = DEFAULT_MAX_RANGE,
    stride: int = 1,
) -> PointCloud:
    """Back-project the valid (and masked) pixels of a depth image into the world.

    Args:
        depth: [H, W] float metres; 0, NaN and inf are skipped, as is depth > max_range.
        intrinsics: camera intrinsics for an H x W image.
        pose: world_from_camera.
        rgb: [H, W, 3] uint8 or float in [0, 1]; grey 0.5 when omitted.
        mask: [H, W] bool; only True pixels are used.
        max_range: metres.
        stride: use every `stride`-th row and column.

    Returns:
        The world-frame point cloud (possibly empty).
    """
    depth = np.asarray(depth)
    check_frame_shapes(depth, intrinsics, rgb, mask)
    valid = valid_depth_mask(depth, max_range)
    if mask is not None:
        valid &= mask.astype(bool)
    if stride > 1:
        sub = np.zeros_like(valid)
        sub[::stride, ::stride] = True
        valid &= sub
    # Flat pixel indices and np.take: the values of depth[v, u] and rgb[v, u], ~4x faster.
    flat = np.flatnonzero(valid)
    v, u = np.divmod(flat, valid.shape[1])
    z = np.take(depth.ravel(), flat).astype(np.float64)
    x = (u - intrinsics.cx) / intrinsics.fx * z
    y = (v - intrinsics.cy) / intrinsics.fy * z
    points = pose.transform_points(np.stack([x, y, z], axis=1))
    if rgb is None:
        colors = np.full((len(z), 3), 0.5, dtype=np.float32)
    else:
        c = np.take(np.asarray(rgb).reshape(-1, 3), flat, axis=0)
        colors = (c.astype(np.float32) / 255.0) if c.dtype == np.uint8 else c.astype(np.float32)
    return PointCloud(points, colors)
