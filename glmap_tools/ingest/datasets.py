"""Open posed RGB-D sequences on disk (Redwood/Open3D or TUM RGB-D) in the project's conventions.

`open_sequence(folder)` recognises the layout, reads the frame list, poses and intrinsics
up front (so bad poses fail before any frame is used), and `RGBDSequence.frames()` then
loads images lazily. Poses are converted once, here, from the dataset's world (y-up for
Redwood/ICL-NUIM, z-up for TUM; `up_axis` overrides) to the z-up world with an OpenCV camera.
Optional per-frame annotations (`annotations/<stem>.png` + `.json`) become `FrameSemantics`.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.geometry import Intrinsics, Pose
from glmap_tools.geometry.adapters import from_dataset, world_zup_from_up_axis
from glmap_tools.geometry.backproject import check_depth_scale
from glmap_tools.geometry.frame import RGBDFrame
from glmap_tools.ingest import redwood, tum
from glmap_tools.ingest.images import load_depth_png, load_rgb, read_annotation
from glmap_tools.ingest.source import FrameSource, ParsedFolder
from glmap_tools.perception.semantics import FrameSemantics

FORMATS = ("redwood", "tum")


@dataclass(frozen=True)
class IngestFrame:
    """One loaded frame of a sequence.

    Attributes:
        index: position in the full sequence (before stride / max_frames).
        frame: the posed RGB-D frame (z-up world, OpenCV camera, depth in metres).
        semantics: parsed annotations, or None when the frame has none.
        rgb_path: the colour image file.
        depth_path: the depth image file.
    """

    index: int
    frame: RGBDFrame
    semantics: FrameSemantics | None
    rgb_path: Path
    depth_path: Path


@dataclass(frozen=True)
class RGBDSequence:
    """A posed RGB-D sequence on disk, read lazily frame by frame.

    Attributes:
        name: the folder's name.
        format: "redwood" or "tum".
        folder: the sequence folder.
        intrinsics: pinhole intrinsics of every frame.
        intrinsics_source: the calibration file used, or which default.
        depth_scale: raw depth units per metre used to read the depth PNGs.
        up_axis: the dataset world's up axis the poses were converted from.
        sources: the selected frames' files and raw poses.
        poses: world_from_camera of each selected frame (z-up world, OpenCV camera).
        dropped: frames left out because they had no depth image or pose (TUM association).
    """

    name: str
    format: str
    folder: Path
    intrinsics: Intrinsics
    intrinsics_source: str
    depth_scale: float
    up_axis: str
    sources: tuple[FrameSource, ...]
    poses: tuple[Pose, ...]
    dropped: int = 0

    @property
    def frame_count(self) -> int:
        """Number of selected frames."""
        return len(self.sources)

    def __len__(self) -> int:
        return len(self.sources)

    def load(self, k: int) -> IngestFrame:
        """Load the k-th selected frame (0 <= k < len(self)).

        Raises:
            InvalidInputError: an unreadable image, depth that is not 16-bit, colour and
                depth of different sizes, or a bad annotation.
        """
        if not 0 <= k < len(self.sources):
            raise InvalidInputError(
                f"frame {k} is out of range; this sequence has {len(self.sources)} frames "
                f"(0..{len(self.sources) - 1})."
            )
        source = self.sources[k]
        rgb, depth = _load_pair(source, self.depth_scale)
        _check_intrinsics(self.intrinsics, self.intrinsics_source, source, depth.shape)
        frame = RGBDFrame(rgb, depth, self.intrinsics, self.poses[k])
        semantics = read_annotation(self.folder, source.rgb_path.stem, depth.shape)
        return IngestFrame(source.index, frame, semantics, source.rgb_path, source.depth_path)

    def frames(self) -> Iterator[IngestFrame]:
        """Yield each selected frame in order, loading its images and annotations."""
        for k in range(len(self.sources)):
            yield self.load(k)


def _load_pair(source: FrameSource, depth_scale: float) -> tuple[np.ndarray, np.ndarray]:
    rgb = load_rgb(source.rgb_path)
    depth = load_depth_png(source.depth_path, depth_scale)
    if rgb.shape[:2] != depth.shape:
        raise InvalidInputError(
            f"colour image {str(source.rgb_path)!r} is {rgb.shape[1]}x{rgb.shape[0]} but depth "
            f"{str(source.depth_path)!r} is {depth.shape[1]}x{depth.shape[0]}; colour and depth "
            "must be registered at the same resolution (resize one of them)."
        )
    return rgb, depth


def _check_intrinsics(
    intrinsics: Intrinsics, where: str, source: FrameSource, shape: tuple[int, ...]
) -> None:
    if (intrinsics.height, intrinsics.width) != tuple(shape):
        raise InvalidInputError(
            f"image {str(source.depth_path)!r} is {shape[1]}x{shape[0]} but the intrinsics "
            f"({where}) are for {intrinsics.width}x{intrinsics.height}; pass intrinsics for "
            "this resolution (intrinsics=..., or Intrinsics.scaled)."
        )


def _detect(folder: Path) -> ParsedFolder:
    if not folder.is_dir():
        raise InvalidInputError(
            f"sequence folder {str(folder)!r} does not exist or is not a folder; pass the "
            "folder that holds the RGB-D sequence."
        )
    if redwood.is_redwood(folder):
        return redwood.parse_redwood(folder)
    if tum.is_tum(folder):
        return tum.parse_tum(folder)
    present = sorted(p.name + ("/" if p.is_dir() else "") for p in folder.iterdir())[:12]
    raise InvalidInputError(
        f"folder {str(folder)!r} is not a recognised RGB-D sequence (it holds {present}). "
        f"A Redwood/Open3D sequence needs {redwood.REQUIRED}; a TUM RGB-D sequence needs "
        f"{tum.REQUIRED}."
    )


def _convert_pose(source: FrameSource, up_axis: str) -> Pose:
    try:
        return from_dataset(source.world_from_camera, up=up_axis)
    except InvalidInputError as err:
        raise InvalidInputError(f"{source.where} ({str(source.rgb_path)!r}): {err}") from err


def open_sequence(
    folder: str | Path,
    *,
    depth_scale: float | None = None,
    up_axis: str | None = None,
    max_frames: int | None = None,
    stride: int = 1,
    intrinsics: Intrinsics | None = None,
) -> RGBDSequence:
    """Open a Redwood/Open3D or TUM RGB-D folder as a posed sequence in the z-up world.

    Args:
        folder: the sequence folder.
        depth_scale: raw depth units per metre; default 1000 (Redwood) or 5000 (TUM).
        up_axis: the dataset world's up axis ("x", "y", "z" or negated); default "y" for
            Redwood/ICL-NUIM, "z" for TUM.
        max_frames: keep at most this many frames (after `stride`).
        stride: keep every `stride`-th frame.
        intrinsics: override the folder's calibration file or the format's default.

    Returns:
        The sequence; frames load lazily through `frames()`.

    Raises:
        InvalidInputError: a missing or unrecognised folder, a frame count mismatch, a
            malformed pose file, a non-rigid or non-finite pose, bad arguments, or a first
            frame whose images do not match each other or the intrinsics.
    """
    if depth_scale is not None:
        check_depth_scale(depth_scale)
    if isinstance(stride, bool) or not isinstance(stride, int) or stride < 1:
        raise InvalidInputError(f"stride={stride!r} must be an integer >= 1.")
    if max_frames is not None and (
        isinstance(max_frames, bool) or not isinstance(max_frames, int) or max_frames < 1
    ):
        raise InvalidInputError(f"max_frames={max_frames!r} must be an integer >= 1 or None.")
    if up_axis is not None:
        world_zup_from_up_axis(up_axis)  # raises on an unknown axis name
    path = Path(folder)
    parsed = _detect(path)
    up = up_axis or parsed.up_axis
    scale = float(depth_scale) if depth_scale is not None else parsed.depth_scale
    selected = parsed.frames[::stride][:max_frames]
    poses = tuple(_convert_pose(s, up) for s in selected)
    if not selected:
        raise InvalidInputError(f"sequence folder {str(path)!r} has no frames.")
    k, k_source = parsed.intrinsics, parsed.intrinsics_source
    if intrinsics is not None:
        k, k_source = intrinsics, "given intrinsics"
    _, depth = _load_pair(selected[0], scale)
    if k_source.startswith("default") and (k.height, k.width) != depth.shape:
        k = k.scaled(depth.shape[1], depth.shape[0])
    _check_intrinsics(k, k_source, selected[0], depth.shape)
    return RGBDSequence(
        name=path.resolve().name,
        format=parsed.format,
        folder=path,
        intrinsics=k,
        intrinsics_source=k_source,
        depth_scale=scale,
        up_axis=up,
        sources=tuple(selected),
        poses=poses,
        dropped=parsed.dropped,
    )
