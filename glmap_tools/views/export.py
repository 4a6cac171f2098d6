"""Files out of a map: 3DGS PLY of a map, an instance or a region; PNG images. All atomic."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from glmap_tools.atomic import write_atomic
from glmap_tools.errors import InvalidInputError, StoreError
from glmap_tools.gaussians.ply import SH_REST_COUNT, write_ply
from glmap_tools.views.common import encode_png, require_instances
from glmap_tools.views.targets import (
    instance_ids_of,
    map_gaussians,
    unit_label,
    with_structure,
)

if TYPE_CHECKING:
    from glmap_tools.map.glmap import GLMap


@dataclass(frozen=True)
class ExportResult:
    """What `export_ply` wrote.

    Attributes:
        path: the file.
        what: "whole map", "instance 3 (chair)" or "region 9".
        gaussians: number of Gaussians written.
        instance_ids: the instances whose Gaussians are in the file.
    """

    path: Path
    what: str
    gaussians: int
    instance_ids: tuple[int, ...]


def _check_path(path: str | os.PathLike[str]) -> Path:
    if not isinstance(path, str | os.PathLike) or not str(path):
        raise InvalidInputError(f"path={path!r} must be a file path, e.g. 'map.ply'.")
    p = Path(path)
    if p.is_dir():
        raise StoreError(f"cannot write {p}: it is a folder; give a file name inside it.")
    if not p.parent.is_dir():
        raise StoreError(f"cannot write {p}: folder {p.parent} does not exist; create it.")
    return p


def export_ply(
    glmap: GLMap,
    path: str | os.PathLike[str],
    unit_id: int | None = None,
    *,
    sh_degree: int = 0,
    structure: bool = False,
) -> ExportResult:
    """Write a map, an instance or a region as a standard 3D Gaussian Splatting PLY.

    The layout (positions, SH DC colour, logit opacity, log scales, rotation quaternion) is
    the one 3DGS viewers read; see `glmap_tools.gaussians.ply`. `read_ply` reads it back.
    Everything is validated before the file is touched, and the file is written to a
    temporary name and renamed, so a failure never leaves a partial file.

    Args:
        glmap: the map.
        path: the file to write (its folder must exist; an existing file is replaced).
        unit_id: None for the whole map, an instance id, or a region id (the union of
            its instances' Gaussians).
        sh_degree: 0 (colour only) or 3 (adds the 45 zero f_rest_* properties).
        structure: also write the structure background layer (walls, floor), after the
            units' Gaussians; `gaussians` in the result counts both.

    Raises:
        InvalidInputError: an empty map, a bad id or sh_degree.
        UnknownIdError: no such unit.
        StoreError: the path is a folder, its folder is missing, or the write fails.
    """
    if sh_degree not in SH_REST_COUNT:
        raise InvalidInputError(
            f"sh_degree={sh_degree!r} is not one of {sorted(SH_REST_COUNT)}; use 0 or 3."
        )
    require_instances(glmap)
    if unit_id is None:
        ids, what = tuple(sorted(glmap.instances)), "whole map"
    else:
        ids, what = instance_ids_of(glmap, unit_id), unit_label(glmap, unit_id)
    p = _check_path(path)
    cached = map_gaussians(glmap)
    g = cached.gaussians if unit_id is None else cached.gaussians.subset(cached.mask_of(ids))
    g = with_structure(glmap, g, structure)
    write_ply(p, g, sh_degree=sh_degree)
    return ExportResult(p, what, len(g), ids)


def write_bytes_atomic(path: str | os.PathLike[str], data: bytes) -> Path:
    """Write `data` to `path` through a temporary file and a rename (no partial file).

    Raises:
        StoreError: the path is a folder, its folder is missing, or the write fails.
    """
    return write_atomic(_check_path(path), [data])


def write_png(path: str | os.PathLike[str], rgb: np.ndarray) -> Path:  # rgb: [H, W, 3] uint8
    """Write an RGB uint8 image as a PNG file, atomically.

    Raises:
        InvalidInputError: `rgb` is not an [H, W, 3] uint8 array.
        StoreError: the file cannot be written.
    """
    rgb = np.asarray(rgb)
    if rgb.dtype != np.uint8 or rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.size == 0:
        raise InvalidInputError(
            f"image has dtype {rgb.dtype} and shape {rgb.shape}; pass [H, W, 3] uint8 RGB."
        )
    return write_bytes_atomic(path, encode_png(rgb))
