"""Cameras, poses, convention adapters and back-projection (numpy only)."""

from glmap_tools.geometry.backproject import (
    PointCloud,
    backproject,
    depth_from_uint16,
    valid_depth_mask,
)
from glmap_tools.geometry.camera import Intrinsics, Pose

__all__ = [
    "Intrinsics",
    "PointCloud",
    "Pose",
    "backproject",
    "depth_from_uint16",
    "valid_depth_mask",
]
