"""What a dataset reader finds in a folder, before conversion to the project's conventions."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.geometry import Intrinsics

# PrimeSense / Kinect v1 at 640x480 (Open3D's default camera, the TUM "ROS default").
PRIMESENSE = Intrinsics(525.0, 525.0, 319.5, 239.5, 640, 480)


def text_lines(path: Path) -> list[str]:
    """The lines of a dataset's text file (trajectory, file list, association).

    Raises:
        InvalidInputError: the file cannot be read or is not UTF-8 text.
    """
    try:
        return path.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError) as err:
        raise InvalidInputError(
            f"cannot read {str(path)!r} as text ({err}); it must be a plain UTF-8 text file "
            "as the dataset wrote it (re-download or re-export it)."
        ) from err


@dataclass(frozen=True)
class FrameSource:
    """One frame's files and its pose in the dataset's own world.

    Attributes:
        index: position of the frame in the full sequence (before stride / max_frames).
        rgb_path: the colour image.
        depth_path: the 16-bit depth image.
        world_from_camera: [4, 4] float64, OpenCV camera, dataset world (not yet z-up).
        where: where the pose came from, for error messages ("trajectory.log frame 3").
        timestamp: seconds (TUM), or None.
    """

    index: int
    rgb_path: Path
    depth_path: Path
    world_from_camera: np.ndarray  # [4, 4]
    where: str
    timestamp: float | None = None


@dataclass(frozen=True)
class ParsedFolder:
    """A recognised sequence folder.

    Attributes:
        format: "redwood" or "tum".
        frames: the frames in sequence order.
        intrinsics: from the folder's calibration file, or the format's default.
        intrinsics_source: where `intrinsics` came from (a file name or "default ...").
        depth_scale: the format's raw depth units per metre.
        up_axis: the format's world up axis ("y" for Redwood/ICL-NUIM, "z" for TUM).
        dropped: frames without a matching depth image or pose (TUM association).
    """

    format: str
    frames: list[FrameSource]
    intrinsics: Intrinsics
    intrinsics_source: str
    depth_scale: float
    up_axis: str
    dropped: int = 0
