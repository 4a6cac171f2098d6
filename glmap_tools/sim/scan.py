"""Layouts from a real scan's object list: one category and one oriented box per object.

Input (a JSON object, or just its "objects" list)::

    {"up": "z", "name": "scene0000_00",
     "room": {"type": "living room", "polygon": [[x, y], ...]},     # optional
     "objects": [{"id": 7, "category": "chair", "center": [x, y, z], "size": [sx, sy, sz],
                  "yaw": 0.3,                     # or "rotation": [[...], [...], [...]]
                  "attributes": {"color": "red"}, "description": "a red chair"}]}

`size` is the box extent along its own axes (the scan world's axes before rotation); `yaw`
turns the box about the scan's up axis (counter-clockwise, radians), or `rotation` gives the
box axes as matrix columns. Boxes must be upright (rotation about the up axis only); the
box axis nearest to up becomes the height, the first other axis the width. Categories are
drawn with the catalog's mesh for them, found through `catalog.resolve_category` (plural
and "-"/"_" spellings, and the alias table `CATEGORY_ALIASES`: book -> books, bin -> trash
can, ...); a category none of these knows is drawn as a box with a `LayoutWarning`. The
floor is put at z = 0 (the lowest box bottom, or `floor_z`). Without a room polygon, the room
is the bounding rectangle of all footprints grown by `margin`.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from glmap_tools.errors import InvalidInputError, did_you_mean
from glmap_tools.geometry.adapters import world_zup_from_up_axis
from glmap_tools.sim.catalog import (
    CATEGORY_ALIASES,
    CATEGORY_MESH,
    mesh_for_category,
    resolve_category,
)
from glmap_tools.sim.layout import Layout, LayoutWarning, yaw_matrix
from glmap_tools.sim.layout_io import layout_from_dict

UPRIGHT_TOLERANCE = 0.05  # |cos| of the box's z axis against world up must exceed 1 - this


def _box_pose(
    entry: Mapping[str, Any], size: np.ndarray, up_rotation: np.ndarray, where: str
) -> tuple[float, np.ndarray]:
    """(yaw of the box's width axis in the z-up world, size as width, depth, height)."""
    if "rotation" in entry:
        r = np.asarray(entry["rotation"], dtype=np.float64)
        if r.shape != (3, 3) or not np.all(np.isfinite(r)):
            raise InvalidInputError(f"{where}.rotation must be a finite 3x3 matrix.")
        r = up_rotation @ r  # columns: the box axes in the z-up world
        up_axis = int(np.argmax(np.abs(r[2])))
        if abs(r[2, up_axis]) < 1 - UPRIGHT_TOLERANCE:
            tilt = math.degrees(math.acos(min(1.0, abs(r[2, up_axis]))))
            raise InvalidInputError(
                f"{where} box is tilted ({tilt:.1f} deg from upright); give upright boxes "
                "(rotation about the up axis only)."
            )
        a, b = (k for k in range(3) if k != up_axis)
        return math.atan2(r[1, a], r[0, a]), np.array([size[a], size[b], size[up_axis]])
    yaw = entry.get("yaw", entry.get("heading", 0.0))
    if isinstance(yaw, bool) or not isinstance(yaw, int | float) or not math.isfinite(yaw):
        raise InvalidInputError(f"{where}.yaw must be a finite number of radians, got {yaw!r}.")
    # A yaw about the scan's up axis is the same yaw about z; the extents follow the axes.
    return float(yaw), np.abs(up_rotation) @ size


def category_shapes(
    categories: Sequence[str], aliases: Mapping[str, str] | None = None
) -> list[tuple[str, int, str | None, str]]:
    """[(scan category, objects, catalog category or None, mesh)] once per category, in
    first-seen order: what `layout_from_scan` draws each category with."""
    counts: dict[str, int] = {}
    for c in categories:
        counts[c] = counts.get(c, 0) + 1
    return [
        (c, n, resolve_category(c, aliases), mesh_for_category(c, aliases))
        for c, n in counts.items()
    ]


def _warn_unknown_categories(
    categories: list[str], aliases: Mapping[str, str] | None = None
) -> None:
    """One `LayoutWarning` per category that neither the catalog nor an alias knows."""
    known = [*CATEGORY_MESH, *CATEGORY_ALIASES, *(aliases or {})]
    for category in sorted({c for c in categories if resolve_category(c, aliases) is None}):
        count = categories.count(category)
        warnings.warn(
            f"category {category!r} ({count} object{'s' * (count > 1)}) has no mesh and no "
            f"alias; drawn as a box.{did_you_mean(category.lower(), known)} Map it to a "
            "catalog category in an alias file (glmap sim from-scan --aliases), or rename it "
            "in the scan.",
            LayoutWarning,
            stacklevel=3,
        )


def layout_from_scan(
    data: Mapping[str, Any] | Sequence[Mapping[str, Any]],
    name: str | None = None,
    up: str | None = None,
    floor_z: float | None = None,
    margin: float = 0.5,
    use_meshes: bool = True,
    aliases: Mapping[str, str] | None = None,
) -> Layout:
    """Convert a scan's object list into a validated `Layout` (one room).

    Args:
        data: the JSON object described in this module, or its "objects" list.
        name: layout name (default: data["name"] or "scan").
        up: the scan world's up axis ("z", "y", ...; default data["up"] or "z").
        floor_z: height of the floor in the scan (default: lowest box bottom).
        margin: metres added around the objects when the room polygon is not given.
        use_meshes: draw known categories with furniture meshes (else every object is a box).
        aliases: scan label -> catalog category, tried before the built-in table
            (`catalog.check_aliases` checks a user's file).

    Raises:
        InvalidInputError: malformed boxes or an empty list.
    """
    meta: Mapping[str, Any] = data if isinstance(data, Mapping) else {"objects": list(data)}
    entries = meta.get("objects")
    if not isinstance(entries, list) or not entries:
        raise InvalidInputError("a scan needs a non-empty 'objects' list of oriented boxes.")
    up_rotation = world_zup_from_up_axis(str(up or meta.get("up", "z")))
    boxes = []
    for i, entry in enumerate(entries):
        where = f"objects[{i}]"
        if not isinstance(entry, Mapping):
            raise InvalidInputError(f"{where} must be an object, got {entry!r}.")
        category = str(entry.get("category", entry.get("label", ""))).strip()
        if not category:
            raise InvalidInputError(f"{where} has no 'category'; name the object's class.")
        try:
            center = up_rotation @ np.asarray(entry["center"], dtype=np.float64).reshape(3)
            size = np.abs(np.asarray(entry.get("size", entry.get("extent")), dtype=np.float64))
            size = size.reshape(3)
        except (KeyError, TypeError, ValueError) as exc:
            raise InvalidInputError(
                f"{where} needs 'center' [x, y, z] and 'size' [sx, sy, sz] in metres."
            ) from exc
        if not (np.all(np.isfinite(center)) and np.all(np.isfinite(size)) and np.all(size > 0)):
            raise InvalidInputError(f"{where} has a non-finite centre or a non-positive size.")
        yaw, size = _box_pose(entry, size, up_rotation, where)
        boxes.append((entry, category, center, size, yaw))
    if use_meshes:
        _warn_unknown_categories([category for _, category, _, _, _ in boxes], aliases)
    bottom = min(c[2] - s[2] / 2 for _, _, c, s, _ in boxes) if floor_z is None else floor_z
    objects, corners = [], []
    for i, (entry, category, center, size, yaw) in enumerate(boxes):
        heading = yaw - math.pi / 2  # our local -y is the front; the box's x is our width
        half = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * size[:2] / 2
        corners.append(half @ yaw_matrix(yaw)[:2, :2].T + center[:2])
        objects.append(
            {
                "id": int(entry.get("id", i + 1)),
                "category": category,
                "mesh": mesh_for_category(category, aliases) if use_meshes else "primitive/box",
                "position": [center[0], center[1], center[2] - size[2] / 2 - bottom],
                "heading": heading,
                "size": size.tolist(),
                "attributes": dict(entry.get("attributes", {})),
                "color": entry.get("color"),
                "description": str(entry.get("description", "")),
            }
        )
    room = dict(meta.get("room") or {})
    if "polygon" not in room:
        pts = np.concatenate(corners)
        lo, hi = pts.min(axis=0) - margin, pts.max(axis=0) + margin
        room["polygon"] = [[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]]
    top = max(c[2] + s[2] / 2 for _, _, c, s, _ in boxes) - bottom
    room.setdefault("id", 1)
    room.setdefault("type", "room")
    room.setdefault("wall_height", max(2.6, top + 0.2))
    return layout_from_dict(
        {
            "name": name or str(meta.get("name", "scan")),
            "rooms": [room],
            "objects": objects,
            "regions": list(meta.get("regions", [])),
        }
    )
