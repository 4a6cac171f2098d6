"""Decoding of observed image files: PNG/JPEG colour, 16-bit PNG or .npy depth, id masks.

Sizes come from the file headers and are checked before anything is decoded, so a small
file that would decode to a huge image is refused without being decoded.
"""

from __future__ import annotations

import io

import cv2
import numpy as np

from glmap_tools.app.config import ServerConfig
from glmap_tools.errors import InvalidInputError
from glmap_tools.geometry.backproject import depth_from_uint16

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
JPEG_MAGIC = b"\xff\xd8\xff"
NPY_MAGIC = b"\x93NUMPY"


def image_header(data: bytes) -> tuple[str, int, int, int | None, int | None]:
    """(format, width, height, png bit depth, png colour type) from a PNG or JPEG header.

    Raises:
        InvalidInputError: not a PNG or JPEG, or a truncated header.
    """
    if data.startswith(PNG_MAGIC):
        if len(data) < 26 or data[12:16] != b"IHDR":
            raise InvalidInputError("the PNG is truncated (no IHDR header); send the whole file.")
        w = int.from_bytes(data[16:20], "big")
        h = int.from_bytes(data[20:24], "big")
        return "png", w, h, data[24], data[25]
    if data.startswith(JPEG_MAGIC):
        size = _jpeg_size(data)
        if size is None:
            raise InvalidInputError("the JPEG is truncated (no frame header); send the whole file.")
        return "jpeg", size[0], size[1], None, None
    head = data[:8]
    raise InvalidInputError(
        f"the file is not a PNG or JPEG (it starts with {head!r}); send PNG or JPEG bytes."
    )


def _jpeg_size(data: bytes) -> tuple[int, int] | None:
    """(width, height) from the first SOF marker of a JPEG, or None."""
    i = 2
    n = len(data)
    while i + 4 <= n:
        if data[i] != 0xFF:
            return None
        marker = data[i + 1]
        if marker == 0xFF:
            i += 1
            continue
        if marker in (0x01, 0xD8) or 0xD0 <= marker <= 0xD7:
            i += 2
            continue
        length = int.from_bytes(data[i + 2 : i + 4], "big")
        if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC):
            if i + 9 > n:
                return None
            h = int.from_bytes(data[i + 5 : i + 7], "big")
            w = int.from_bytes(data[i + 7 : i + 9], "big")
            return w, h
        if length < 2:
            return None
        i += 2 + length
    return None


def _check_pixels(w: int, h: int, what: str, config: ServerConfig) -> None:
    if w <= 0 or h <= 0:
        raise InvalidInputError(f"{what} has an empty size {w}x{h}; send a real image.")
    if w * h > config.max_frame_pixels:
        raise InvalidInputError(
            f"{what} is {w}x{h} = {w * h} pixels, over the limit of {config.max_frame_pixels} "
            "pixels per image; downscale it (and scale the intrinsics with it)."
        )


def _imdecode(data: bytes, flags: int, what: str) -> np.ndarray:
    image = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), flags)
    if image is None:
        raise InvalidInputError(f"{what} could not be decoded; the file is corrupt or truncated.")
    return image


def decode_rgb(data: bytes, config: ServerConfig) -> np.ndarray:  # -> [H, W, 3] uint8
    """Decode colour PNG/JPEG bytes to uint8 RGB."""
    fmt, w, h, bits, _ = image_header(data)
    _check_pixels(w, h, "rgb", config)
    if fmt == "png" and bits == 16:
        raise InvalidInputError("rgb is a 16-bit PNG; send 8-bit colour (PNG or JPEG).")
    image = _imdecode(data, cv2.IMREAD_COLOR, "rgb")
    return np.ascontiguousarray(cv2.cvtColor(image, cv2.COLOR_BGR2RGB))


def load_npy(data: bytes, what: str, config: ServerConfig) -> np.ndarray:
    """A 2D numeric array from .npy bytes (shape read and checked before loading)."""
    f = io.BytesIO(data)
    try:
        version = np.lib.format.read_magic(f)
        header = (
            np.lib.format.read_array_header_1_0(f)
            if version == (1, 0)
            else np.lib.format.read_array_header_2_0(f)
        )
    except (ValueError, OSError) as exc:
        raise InvalidInputError(f"{what} is not a valid .npy file ({exc}).") from None
    shape, _, dtype = header
    if len(shape) != 2 or dtype.hasobject or dtype.kind not in "iuf":
        raise InvalidInputError(
            f"{what}.npy holds {dtype} with shape {shape}; send a 2D numeric [H, W] array."
        )
    _check_pixels(int(shape[1]), int(shape[0]), what, config)
    try:
        return np.load(io.BytesIO(data), allow_pickle=False)
    except (ValueError, OSError, EOFError) as exc:
        raise InvalidInputError(f"{what} is a damaged .npy file ({exc}).") from None


def decode_depth(data: bytes, depth_scale: float, config: ServerConfig) -> np.ndarray:  # [H, W]
    """Depth in metres from a 16-bit PNG (raw units / depth_scale) or a .npy array.

    A float .npy is taken as metres; an integer .npy as raw units divided by depth_scale.
    """
    if data.startswith(NPY_MAGIC):
        arr = load_npy(data, "depth", config)
        if arr.dtype.kind == "f":
            return arr.astype(np.float32)
        return depth_from_uint16(arr, depth_scale)
    fmt, w, h, bits, colour = image_header(data)
    if fmt != "png" or bits != 16 or colour != 0:
        kind = "a JPEG" if fmt == "jpeg" else f"a {bits}-bit PNG of colour type {colour}"
        raise InvalidInputError(
            f"depth is {kind}; send a single-channel 16-bit PNG of raw depth units (with "
            "depth_scale units per metre) or a float32 .npy in metres."
        )
    _check_pixels(w, h, "depth", config)
    raw = _imdecode(data, cv2.IMREAD_UNCHANGED, "depth")
    return depth_from_uint16(raw, depth_scale)


def decode_mask(data: bytes, config: ServerConfig) -> np.ndarray:  # [H, W] int
    """Instance ids from a single-channel 8/16-bit PNG or an integer .npy."""
    if data.startswith(NPY_MAGIC):
        arr = load_npy(data, "annotations.mask", config)
        if arr.dtype.kind not in "iu":
            raise InvalidInputError(
                f"annotations.mask.npy has dtype {arr.dtype}; send integer object ids."
            )
        return arr
    fmt, w, h, bits, colour = image_header(data)
    if fmt != "png" or colour != 0 or bits not in (8, 16):
        kind = "a JPEG (lossy: ids would blur)" if fmt == "jpeg" else f"colour type {colour}"
        raise InvalidInputError(
            f"annotations.mask is {kind}; send a single-channel 8- or 16-bit PNG whose "
            "pixel values are object ids (0 = none)."
        )
    _check_pixels(w, h, "annotations.mask", config)
    return _imdecode(data, cv2.IMREAD_UNCHANGED, "annotations.mask")
