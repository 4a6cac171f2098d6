"""Image and annotation files at the ingest edge: uint8 RGB, uint16 depth PNGs, label masks."""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.geometry import depth_from_uint16
from glmap_tools.perception.annotated import semantics_from_annotation
from glmap_tools.perception.semantics import FrameSemantics

ANNOTATION_DIR = "annotations"


def load_rgb(path: str | Path) -> np.ndarray:
    """Read a colour image as uint8 RGB (OpenCV reads BGR; this swaps the channels).

    Args:
        path: a JPEG or PNG file; grey images are expanded to three channels.

    Returns:
        [H, W, 3] uint8 RGB.

    Raises:
        InvalidInputError: the file is missing, unreadable or not 8-bit.
    """
    p = Path(path)
    image = cv2.imread(str(p), cv2.IMREAD_UNCHANGED) if p.is_file() else None
    if image is None:
        raise InvalidInputError(
            f"cannot read colour image {str(p)!r}; check that the file exists and is a valid "
            "JPEG or PNG."
        )
    if image.dtype != np.uint8:
        raise InvalidInputError(
            f"colour image {str(p)!r} has dtype {image.dtype}; save colour frames as 8-bit "
            "JPEG or PNG."
        )
    if image.ndim == 2:
        return np.ascontiguousarray(np.repeat(image[:, :, None], 3, axis=2))
    if image.ndim == 3 and image.shape[2] == 4:
        return np.ascontiguousarray(cv2.cvtColor(image, cv2.COLOR_BGRA2RGB))
    if image.ndim == 3 and image.shape[2] == 3:
        return np.ascontiguousarray(cv2.cvtColor(image, cv2.COLOR_BGR2RGB))
    raise InvalidInputError(
        f"colour image {str(p)!r} has shape {image.shape}; pass a grey, RGB or RGBA image."
    )


def load_depth_png(path: str | Path, scale: float) -> np.ndarray:
    """Read a 16-bit depth PNG as float32 metres (0 stays 0 = no measurement).

    Args:
        path: a single-channel uint16 PNG.
        scale: raw units per metre (1000 for Redwood/ScanNet millimetres, 5000 for TUM).

    Returns:
        [H, W] float32 metres.

    Raises:
        InvalidInputError: the file is missing or unreadable, not single-channel 16-bit,
            or `scale` is not positive.
    """
    p = Path(path)
    raw = cv2.imread(str(p), cv2.IMREAD_UNCHANGED) if p.is_file() else None
    if raw is None:
        raise InvalidInputError(
            f"cannot read depth image {str(p)!r}; check that the file exists and is a valid PNG."
        )
    if raw.dtype != np.uint16 or raw.ndim != 2:
        channels = 1 if raw.ndim == 2 else raw.shape[2]
        raise InvalidInputError(
            f"depth image {str(p)!r} is {raw.dtype} with {channels} channel(s); depth must be a "
            "single-channel 16-bit PNG of raw sensor units (save it with "
            "cv2.imwrite(path, depth_uint16))."
        )
    return depth_from_uint16(raw, scale)


def annotation_paths(folder: str | Path, stem: str) -> tuple[Path, Path]:
    """The (mask PNG, labels JSON) paths of frame `stem` under `folder/annotations/`."""
    base = Path(folder) / ANNOTATION_DIR
    return base / f"{stem}.png", base / f"{stem}.json"


def read_annotation(folder: str | Path, stem: str, shape: tuple[int, int]) -> FrameSemantics | None:
    """Parse `annotations/<stem>.png` + `.json` into FrameSemantics, or None when absent.

    Args:
        folder: the sequence folder.
        stem: the colour image's file name without extension.
        shape: (H, W) of the frame; the mask must match it.

    Raises:
        InvalidInputError: only one of the two files exists, the mask is unreadable, not an
            integer image or the wrong size, the JSON does not parse, or the annotation
            itself is malformed (see glmap_tools.perception.annotated).
    """
    mask_path, json_path = annotation_paths(folder, stem)
    if not mask_path.exists() and not json_path.exists():
        return None
    if not (mask_path.is_file() and json_path.is_file()):
        have, missing = (mask_path, json_path) if mask_path.exists() else (json_path, mask_path)
        raise InvalidInputError(
            f"annotation {str(have)!r} has no partner {str(missing)!r}; each annotated frame "
            "needs both the instance-id mask PNG and the labels JSON (or neither)."
        )
    mask = cv2.imread(str(mask_path), cv2.IMREAD_UNCHANGED)
    if mask is None or mask.ndim != 2 or mask.dtype not in (np.uint8, np.uint16):
        what = "unreadable" if mask is None else f"{mask.dtype} with shape {mask.shape}"
        raise InvalidInputError(
            f"annotation mask {str(mask_path)!r} is {what}; save a single-channel uint8 or "
            "uint16 PNG of object ids (0 = none)."
        )
    if mask.shape != tuple(shape):
        raise InvalidInputError(
            f"annotation mask {str(mask_path)!r} is {mask.shape[1]}x{mask.shape[0]} but the "
            f"frame is {shape[1]}x{shape[0]}; draw masks at the colour image's resolution."
        )
    try:
        labels = json.loads(json_path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
        raise InvalidInputError(
            f"annotation labels {str(json_path)!r} are not valid JSON ({err}); write "
            '{"objects": [...], "groups": [...]} as in glmap_tools.perception.annotated.'
        ) from err
    try:
        return semantics_from_annotation(mask, labels)
    except InvalidInputError as err:
        raise InvalidInputError(f"annotation {str(json_path)!r}: {err}") from err


def write_annotation(
    folder: str | Path, stem: str, mask: np.ndarray, annotation: Mapping[str, Any]
) -> tuple[Path, Path]:
    """Validate and write one frame's annotation as `annotations/<stem>.png` + `.json`.

    The mask is stored as a compressed uint8 PNG when its ids fit, else uint16. Nothing is
    written unless the annotation parses (`semantics_from_annotation`).

    Args:
        folder: the sequence folder (`annotations/` is created inside it).
        stem: the colour image's file name without extension.
        mask: [H, W] integer object ids, 0 = none.
        annotation: {"objects": [...], "groups": [...]}.

    Returns:
        The (mask PNG, labels JSON) paths written.

    Raises:
        InvalidInputError: the mask has negative or > 65535 ids, or the annotation is malformed.
    """
    arr = np.asarray(mask)
    semantics_from_annotation(arr, annotation)  # raises before anything is written
    top = int(arr.max()) if arr.size else 0
    if arr.size and (int(arr.min()) < 0 or top > 65535):
        raise InvalidInputError(
            f"mask ids span {int(arr.min())}..{top}; object ids must be 1..65535 (0 = none)."
        )
    out: np.ndarray = arr.astype(np.uint8) if top <= 255 else arr.astype(np.uint16)
    mask_path, json_path = annotation_paths(folder, stem)
    mask_path.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(mask_path), out, [cv2.IMWRITE_PNG_COMPRESSION, 9]):
        raise InvalidInputError(f"cannot write {str(mask_path)!r}; check the folder is writable.")
    json_path.write_text(json.dumps(annotation, indent=2) + "\n", encoding="utf-8")
    return mask_path, json_path
