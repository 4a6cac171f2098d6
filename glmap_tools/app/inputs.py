"""Tool inputs of observe_frame: files as base64 or local paths, intrinsics, pose, annotations.

Every check runs before any map state is touched, and each failure names the bad value and
the fix. The image files themselves are decoded by `glmap_tools.app.images`.
"""

from __future__ import annotations

import base64
import binascii
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from glmap_tools.app.arguments import Description, Label
from glmap_tools.app.config import MIB, ServerConfig
from glmap_tools.app.images import decode_depth, decode_mask, decode_rgb, image_header
from glmap_tools.errors import InvalidInputError
from glmap_tools.geometry import Intrinsics, Pose
from glmap_tools.geometry.adapters import from_dataset
from glmap_tools.geometry.camera import MAX_FOV_DEG
from glmap_tools.geometry.frame import RGBDFrame
from glmap_tools.language.embed import Embedder
from glmap_tools.language.text_merger import MAX_DESCRIPTION_CHARS, ExtractiveTextMerger
from glmap_tools.perception.annotated import semantics_from_annotation
from glmap_tools.perception.semantics import FrameSemantics

# Per frame, at most this many objects and groups (see docs/mcp.md, "Limits").
MAX_OBJECTS = 64
MAX_GROUPS = 16


class FileInput(BaseModel):
    """A file given by value (base64) or by reference (a local path); exactly one of the two."""

    model_config = ConfigDict(extra="forbid")
    base64: str | None = None
    path: str | None = None


class IntrinsicsInput(BaseModel):
    """Pinhole intrinsics in pixels (fx, fy, cx, cy), or a horizontal field of view."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)
    fx: float | None = None
    fy: float | None = None
    cx: float | None = None
    cy: float | None = None
    hfov_deg: float | None = Field(default=None, description=f"<= {MAX_FOV_DEG:g}")


class PoseInput(BaseModel):
    """A 4x4 world_from_camera matrix and the conventions it is written in."""

    model_config = ConfigDict(extra="forbid")
    matrix: list[list[float | None]] = Field(
        max_length=8,
        description="4x4 world_from_camera, row-major, metres",
    )
    camera: Literal["opencv", "opengl"] = Field(
        default="opencv",
        description="opencv: x right, y down, z ahead; opengl: y up, -z ahead",
    )
    world_up: Literal["z", "y", "-y", "x", "-x", "-z"] = Field(
        default="z", description="world up axis (y in Habitat, glTF)"
    )


class ObjectAnnotation(BaseModel):
    """One object of the frame: its value in the mask and its words."""

    model_config = ConfigDict(extra="forbid")
    id: int = Field(ge=1, le=65535, description="its value in the mask")
    label: Label = Field(default="", max_length=200, description="e.g. 'chair'")
    description: Description = Field(default="", max_length=MAX_DESCRIPTION_CHARS)


class GroupAnnotation(BaseModel):
    """One region of the frame: a described group of objects."""

    model_config = ConfigDict(extra="forbid")
    id: int = Field(ge=0, le=65535)
    description: Description = Field(
        max_length=MAX_DESCRIPTION_CHARS, description="e.g. 'dining area'"
    )
    members: list[int] = Field(max_length=MAX_OBJECTS, description="object ids")


class AnnotationInput(BaseModel):
    """Instance masks and labels for the frame (the simulator's or your detector's output)."""

    model_config = ConfigDict(extra="forbid")
    mask: FileInput = Field(description="object id per pixel (0 = none), PNG or .npy")
    objects: list[ObjectAnnotation] = Field(max_length=MAX_OBJECTS)
    groups: list[GroupAnnotation] = Field(default_factory=list, max_length=MAX_GROUPS)


@dataclass
class Budget:
    """Bytes left for the files of one observe_frame call."""

    left: int
    limit: int

    def take(self, n: int, what: str) -> None:
        if n > self.left:
            raise InvalidInputError(
                f"{what} is {n / MIB:.1f} MiB, which exceeds the {self.limit / MIB:.0f} MiB "
                "limit for one frame's files (--max-frame-mb); send a smaller or more "
                "compressed image (JPEG colour, PNG depth), or raise the limit."
            )
        self.left -= n


# ---------------------------------------------------------------------- bytes


def read_file_input(
    src: FileInput, what: str, config: ServerConfig, budget: Budget
) -> tuple[bytes, str]:
    """The bytes of a FileInput and a short name of where they came from.

    Raises:
        InvalidInputError: neither or both given, malformed base64, a path that is not
            absolute, outside the allowed roots, missing, or over the byte budget.
    """
    if (src.base64 is None) == (src.path is None):
        raise InvalidInputError(
            f"{what} needs exactly one of 'base64' (the file's bytes) or 'path' (a local "
            'file), e.g. {"base64": "iVBORw0..."}.'
        )
    if src.base64 is not None:
        text = src.base64.strip()
        if text.startswith("data:"):
            head, sep, text = text.partition(",")
            if not sep or ";base64" not in head:
                raise InvalidInputError(
                    f"{what}.base64 is a data URI without ';base64,'; send "
                    "'data:image/png;base64,<bytes>' or the bare base64 text."
                )
        budget.take(len(text) * 3 // 4, what)
        try:
            data = base64.b64decode("".join(text.split()), validate=True)
        except (binascii.Error, ValueError) as exc:
            raise InvalidInputError(
                f"{what}.base64 is not valid base64 ({exc}); encode the raw file bytes, e.g. "
                "base64.b64encode(open(path, 'rb').read()).decode()."
            ) from None
        if not data:
            raise InvalidInputError(f"{what}.base64 is empty; send the file's bytes.")
        return data, f"{what} (base64)"
    assert src.path is not None
    return _read_path(src.path, what, config, budget), src.path


def _read_path(raw: str, what: str, config: ServerConfig, budget: Budget) -> bytes:
    if config.file_roots is not None and not config.file_roots:
        raise InvalidInputError(
            f"{what}.path: this server does not read local files (started without "
            "--file-root); send the file as base64 instead."
        )
    if "\x00" in raw:
        raise InvalidInputError(f"{what}.path contains a NUL byte; give a plain file path.")
    path = Path(raw).expanduser()
    if not path.is_absolute():
        raise InvalidInputError(
            f"{what}.path {raw!r} is relative; give an absolute path (the server's working "
            "folder is not yours)."
        )
    try:
        resolved = path.resolve()
    except (OSError, RuntimeError) as exc:
        raise InvalidInputError(f"{what}.path {raw!r} cannot be resolved ({exc}).") from None
    if config.file_roots is not None and not any(
        resolved.is_relative_to(root) for root in config.file_roots
    ):
        roots = [str(r) for r in config.file_roots]
        raise InvalidInputError(
            f"{what}.path {raw!r} is outside the folders this server may read {roots}; "
            "move the file there or send it as base64."
        )
    if not resolved.is_file():
        raise InvalidInputError(
            f"{what}.path {raw!r} is not a readable file; check the path, or send base64."
        )
    try:
        budget.take(resolved.stat().st_size, what)
        return resolved.read_bytes()
    except OSError as exc:
        raise InvalidInputError(f"cannot read {what}.path {raw!r}: {exc}.") from None


# ---------------------------------------------------------------------- camera


def intrinsics_of(src: IntrinsicsInput, width: int, height: int) -> Intrinsics:
    """Intrinsics for a width x height image from fx/fy/cx/cy or hfov_deg."""
    values = (src.fx, src.fy, src.cx, src.cy)
    if src.hfov_deg is not None:
        if any(v is not None for v in values):
            raise InvalidInputError("intrinsics: give either fx, fy, cx, cy or hfov_deg, not both.")
        return Intrinsics.from_fov(width, height, src.hfov_deg)
    if any(v is None for v in values):
        raise InvalidInputError(
            'intrinsics need fx, fy, cx and cy (pixels), e.g. {"fx": 525, "fy": 525, '
            '"cx": 319.5, "cy": 239.5}, or hfov_deg.'
        )
    fx, fy, cx, cy = (float(v) for v in values)  # type: ignore[arg-type]
    return Intrinsics(fx, fy, cx, cy, width, height)


def pose_of(src: PoseInput) -> Pose:
    """The pose in this project's conventions (OpenCV camera, z-up world)."""
    rows = src.matrix
    if len(rows) != 4 or any(len(r) != 4 for r in rows):
        shape = f"{len(rows)}x{'/'.join(str(len(r)) for r in rows)}"
        raise InvalidInputError(
            f"pose.matrix is {shape}; send 4 rows of 4 numbers (row-major world_from_camera)."
        )
    matrix = np.array([[np.nan if v is None else v for v in r] for r in rows], np.float64)
    if not np.all(np.isfinite(matrix)):
        raise InvalidInputError(
            "pose.matrix contains NaN, infinity or null; send a finite 4x4 world_from_camera "
            "matrix (a lost tracking pose cannot be observed: skip that frame)."
        )
    return from_dataset(matrix, up=src.world_up, camera=src.camera)


# ---------------------------------------------------------------------- frame


@dataclass(frozen=True)
class FrameFiles:
    """The still-encoded files of one observe_frame call and the frame's size.

    Attributes:
        rgb, depth, mask: the files' bytes (mask None without annotations).
        width, height: the colour image's size from its header (nothing decoded yet).
    """

    rgb: bytes
    depth: bytes
    mask: bytes | None
    width: int
    height: int


def read_frame_files(
    rgb: FileInput,
    depth: FileInput,
    pose: PoseInput,
    annotations: AnnotationInput | None,
    config: ServerConfig,
) -> FrameFiles:
    """Check the pose, read (not decode) observe_frame's files, and the frame's size from
    the colour file's header.

    Raises:
        InvalidInputError: a bad pose, a malformed or oversized file input, or a colour file
            that is not a PNG or JPEG.
    """
    pose_of(pose)  # first, as before any file is read
    budget = Budget(config.max_frame_bytes, config.max_frame_bytes)
    rgb_bytes, _ = read_file_input(rgb, "rgb", config, budget)
    depth_bytes, _ = read_file_input(depth, "depth", config, budget)
    mask_bytes = (
        read_file_input(annotations.mask, "annotations.mask", config, budget)[0]
        if annotations is not None
        else None
    )
    _, width, height, _, _ = image_header(rgb_bytes)
    return FrameFiles(rgb_bytes, depth_bytes, mask_bytes, width, height)


def decode_frame(
    rgb: FileInput,
    depth: FileInput,
    depth_scale: float,
    intrinsics: IntrinsicsInput,
    pose: PoseInput,
    annotations: AnnotationInput | None,
    config: ServerConfig,
) -> tuple[RGBDFrame, FrameSemantics | None]:
    """Decode and check every input of observe_frame; nothing is integrated here.

    Raises:
        InvalidInputError: any malformed, oversized or inconsistent input.
    """
    files = read_frame_files(rgb, depth, pose, annotations, config)
    return decode_frame_files(files, depth_scale, intrinsics, pose, annotations, config)


def decode_frame_files(
    files: FrameFiles,
    depth_scale: float,
    intrinsics: IntrinsicsInput,
    pose: PoseInput,
    annotations: AnnotationInput | None,
    config: ServerConfig,
) -> tuple[RGBDFrame, FrameSemantics | None]:
    """Decode and check the files `read_frame_files` read (see `decode_frame`)."""
    cam_pose = pose_of(pose)
    rgb_image = decode_rgb(files.rgb, config)
    depth_m = decode_depth(files.depth, depth_scale, config)
    h, w = depth_m.shape
    if rgb_image.shape[:2] != (h, w):
        raise InvalidInputError(
            f"rgb is {rgb_image.shape[1]}x{rgb_image.shape[0]} but depth is {w}x{h}; send a "
            "colour image registered to the depth image, at the same size."
        )
    frame = RGBDFrame(rgb_image, depth_m, intrinsics_of(intrinsics, w, h), cam_pose)
    if annotations is None or files.mask is None:
        return frame, None
    mask = decode_mask(files.mask, config)
    if mask.shape != (h, w):
        raise InvalidInputError(
            f"annotations.mask is {mask.shape[1]}x{mask.shape[0]} but depth is {w}x{h}; draw "
            "the mask at the depth image's size."
        )
    labels = {
        "objects": [o.model_dump() for o in annotations.objects],
        "groups": [g.model_dump() for g in annotations.groups],
    }
    return frame, semantics_from_annotation(mask, labels)


def embed_ahead(embedder: Embedder, semantics: FrameSemantics) -> None:
    """Embed a frame's texts, and what merging them into text buffers embeds, ahead of time.

    Run outside the map's lock: the embedder caches the vectors, so integrating the frame
    (which embeds the same texts under the lock) reuses them instead of running the model
    there, and other calls on the map wait less (docs/mcp.md, "Limits").
    """
    texts = [o.text for o in semantics.objects] + [g.description.strip() for g in semantics.groups]
    texts = [t for t in texts if t]
    merger = ExtractiveTextMerger(embedder)
    pieces = [p for t in texts for p in merger.texts_to_embed([t])]
    if texts:
        embedder.embed(list(dict.fromkeys(texts + pieces)))
