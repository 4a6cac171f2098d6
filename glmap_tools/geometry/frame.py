"""`RGBDFrame`: one posed RGB-D observation in the project's conventions."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.geometry.backproject import check_frame_shapes, valid_depth_mask
from glmap_tools.geometry.camera import Intrinsics, Pose


@dataclass(frozen=True)
class RGBDFrame:
    """A posed RGB-D frame.

    Attributes:
        rgb: [H, W, 3] uint8.
        depth: [H, W] float32 metres; 0/NaN/inf = no measurement.
        intrinsics: pinhole intrinsics of the H x W image.
        pose: world_from_camera (OpenCV camera, z-up world).
    """

    rgb: np.ndarray  # [H, W, 3]
    depth: np.ndarray  # [H, W]
    intrinsics: Intrinsics
    pose: Pose

    def __post_init__(self) -> None:
        if not isinstance(self.intrinsics, Intrinsics):
            raise InvalidInputError(
                f"intrinsics is {type(self.intrinsics).__name__}, not Intrinsics; pass e.g. "
                "Intrinsics(525.0, 525.0, 319.5, 239.5, 640, 480)."
            )
        if not isinstance(self.pose, Pose):
            raise InvalidInputError(
                f"pose is {type(self.pose).__name__}, not Pose; pass Pose(world_from_camera) "
                "with the 4x4 camera-to-world matrix, or Pose.identity()."
            )
        rgb = np.asarray(self.rgb)
        depth = np.asarray(self.depth)
        if rgb.dtype != np.uint8:
            raise InvalidInputError(
                f"rgb has dtype {rgb.dtype}; pass uint8 RGB (convert floats with "
                "(rgb * 255).round().astype(np.uint8))."
            )
        if not np.issubdtype(depth.dtype, np.floating):
            raise InvalidInputError(
                f"depth has dtype {depth.dtype}; pass float metres (convert raw uint16 with "
                "glmap_tools.geometry.depth_from_uint16(depth, depth_scale))."
            )
        check_frame_shapes(depth, self.intrinsics, rgb)
        object.__setattr__(self, "depth", depth.astype(np.float32, copy=False))

    def valid_depth(self, max_range: float) -> np.ndarray:
        """[H, W] bool mask of usable depth."""
        return valid_depth_mask(self.depth, max_range)
