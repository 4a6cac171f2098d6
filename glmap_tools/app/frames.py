"""Encode an RGB-D frame (and its annotation) as observe_frame arguments, for clients.

Used by the demo, the benchmark and the tests; any Python MCP client can use it too.
"""

from __future__ import annotations

import base64
from collections.abc import Mapping, Sequence
from typing import Any

import cv2
import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.geometry.frame import RGBDFrame


def png_base64(image: np.ndarray) -> str:
    """Base64 of the PNG of a uint8/uint16 image ([H, W] grey or [H, W, 3] RGB)."""
    arr = np.asarray(image)
    if arr.ndim == 3:
        arr = cv2.cvtColor(arr, cv2.COLOR_RGB2BGR)
    ok, buf = cv2.imencode(".png", arr)
    if not ok:
        raise InvalidInputError(f"cannot encode a {arr.dtype} {arr.shape} image as PNG.")
    return base64.b64encode(buf.tobytes()).decode("ascii")


def jpeg_base64(rgb: np.ndarray, quality: int = 90) -> str:  # rgb: [H, W, 3] uint8
    """Base64 of the JPEG of an RGB image."""
    ok, buf = cv2.imencode(
        ".jpg", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, quality]
    )
    if not ok:
        raise InvalidInputError("cannot encode the colour image as JPEG.")
    return base64.b64encode(buf.tobytes()).decode("ascii")


def observe_arguments(
    frame: RGBDFrame,
    instance_mask: np.ndarray | None = None,
    objects: Sequence[Mapping[str, Any]] = (),
    groups: Sequence[Mapping[str, Any]] = (),
    depth_scale: float = 1000.0,
    jpeg: bool = False,
) -> dict[str, Any]:
    """observe_frame arguments for `frame`: PNG/JPEG colour, 16-bit PNG depth, pose, mask.

    Args:
        frame: the posed RGB-D frame (OpenCV camera, z-up world).
        instance_mask: [H, W] integer object ids (0 = none), or None for no annotations.
        objects: [{"id", "label", "description"}] of the mask's ids.
        groups: [{"id", "description", "members"}].
        depth_scale: raw depth units per metre in the PNG.
        jpeg: send the colour image as JPEG (smaller) instead of PNG.
    """
    raw = np.clip(np.nan_to_num(frame.depth, nan=0.0, posinf=0.0) * depth_scale, 0, 65535)
    intr = frame.intrinsics
    args: dict[str, Any] = {
        "rgb": {"base64": jpeg_base64(frame.rgb) if jpeg else png_base64(frame.rgb)},
        "depth": {"base64": png_base64(raw.round().astype(np.uint16))},
        "depth_scale": depth_scale,
        "intrinsics": {"fx": intr.fx, "fy": intr.fy, "cx": intr.cx, "cy": intr.cy},
        "pose": {"matrix": frame.pose.matrix.tolist(), "camera": "opencv", "world_up": "z"},
    }
    if instance_mask is not None:
        mask = np.asarray(instance_mask)
        top = int(mask.max()) if mask.size else 0
        if mask.size and (int(mask.min()) < 0 or top > 65535):
            raise InvalidInputError("instance mask ids must be within 0..65535.")
        encoded = mask.astype(np.uint8 if top <= 255 else np.uint16)
        args["annotations"] = {
            "mask": {"base64": png_base64(encoded)},
            "objects": [dict(o) for o in objects],
            "groups": [dict(g) for g in groups],
        }
    return args
