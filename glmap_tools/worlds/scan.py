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
and "-"/"_" spellings, a caller's alias file, and the alias table `CATEGORY_ALIASES`: book
-> books, bin -> trash can, ...); a category none of these knows is drawn as a box with a
`LayoutWarning`. The floor is put at z = 0 (the lowest box bottom, or `floor_z`). Without a
room polygon, the room is the bounding rectangle of all footprints grown by `margin`.

Several rooms: `"rooms": [{"type", "polygon"}, ...]` (ids 1, 2, ... in order) and
`"openings": [{"id", "rooms": [a, b], "center": [x, y], "width"}]` on the walls they share;
each object belongs to the room its centre stands in. Rooms may be turned: a box square to
the scan's axes (yaw 0, or a yaw or rotation within `SQUARE_DEG` of a multiple of 90 deg: what
a scanner that fits axis-aligned boxes gives) in a room whose walls are turned more than
`AXIS_ALIGNED_DEG` is read as the bounding box of a box square to those walls
(`box_in_room_frame`; a thin wall box such as a picture as a 5 cm thin box), and each such
box is reported. A box with a rotation of its own is taken as given; when a box in a turned
room was left as given and then crosses a wall, the refusal says why the fix was skipped.
"""

from __future__ import annotations

import math
import re
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
from glmap_tools.worlds.passages import MIN_PART_AREA as MIN_PART_AREA
from glmap_tools.worlds.passages import narrow_passages

UPRIGHT_TOLERANCE = 0.05  # |cos| of the box's z axis against world up must exceed 1 - this


def _box_pose(
    entry: Mapping[str, Any], size: np.ndarray, up_rotation: np.ndarray, where: str
) -> tuple[float, np.ndarray]:
    """(yaw of the box's width axis in the z-up world, size as width, depth, height)."""
    if "rotation" in entry:
        try:
            r = np.asarray(entry["rotation"], dtype=np.float64)
        except (TypeError, ValueError, OverflowError):
            r = np.full(1, np.nan)
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
    if not _finite_number(yaw):
        raise InvalidInputError(
            f"{where}.yaw must be a finite number of radians, got {str(yaw)[:40]}."
        )
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


AXIS_ALIGNED_DEG = 5.0  # a room whose walls are within this of the scan's axes is not turned


def room_yaw(polygon: np.ndarray) -> float:
    """The direction of a room's walls (its longest edge), radians in (-pi/4, pi/4]."""
    edges = np.roll(polygon, -1, axis=0) - polygon
    dx, dy = edges[int(np.argmax(np.hypot(edges[:, 0], edges[:, 1])))]
    yaw = math.atan2(dy, dx)
    return float((yaw + math.pi / 4) % (math.pi / 2) - math.pi / 4)


MIN_SIDE = 0.05  # metres: the thinnest side of a box read inside a bounding box
THIN_FIT = 0.05  # metres (or 5 % of the box) a thin box's bounding box may be off the given one


def box_in_room_frame(size_xy: np.ndarray, yaw: float) -> np.ndarray | None:
    """The (width, depth) of a box turned by `yaw` whose axis-aligned bounding box is
    `size_xy`, or None when no box with both sides >= `MIN_SIDE` has that bounding box.

    A scan that fits axis-aligned boxes to the objects of a room turned by `yaw` gives
    each object's bounding box, not the object: w cos + d sin = X, w sin + d cos = Y. A thin
    box (a picture on a turned wall, 3 cm deep) solves to a side under 5 cm, or below 0 with
    the scan's noise: it is read as a `MIN_SIDE`-thin box whose other side fits the bounding
    box best (least squares), when that box's bounding box lies within `THIN_FIT` of the
    given one.
    """
    c, s = abs(math.cos(yaw)), abs(math.sin(yaw))
    det = c * c - s * s
    if abs(det) < 0.2:  # near 45 deg the two sides cannot be told apart
        return None
    x, y = float(size_xy[0]), float(size_xy[1])
    w = (c * x - s * y) / det
    d = (c * y - s * x) / det
    if min(w, d) >= MIN_SIDE:
        return np.array([w, d])
    best: tuple[float, np.ndarray] | None = None
    for thin_is_depth in (True, False):
        # The long side L with the thin side t: bbox (L c + t s, L s + t c) when the thin
        # side is the depth, (t c + L s, t s + L c) when it is the width.
        t = MIN_SIDE
        if thin_is_depth:
            long_ = (x - t * s) * c + (y - t * c) * s
            fit = np.array([long_ * c + t * s, long_ * s + t * c])
            box = np.array([long_, t])
        else:
            long_ = (x - t * c) * s + (y - t * s) * c
            fit = np.array([t * c + long_ * s, t * s + long_ * c])
            box = np.array([t, long_])
        off = float(np.max(np.abs(fit - [x, y])))
        if long_ >= MIN_SIDE and (best is None or off < best[0]):
            best = (off, box)
    if best is None or best[0] > max(THIN_FIT, 0.05 * max(x, y)):
        return None
    return best[1]


def _scan_rooms(meta: Mapping[str, Any]) -> list[dict[str, Any]]:
    """The scan's rooms: its "rooms" list, or its one "room" (ids from 1)."""
    raw = meta.get("rooms")
    if raw is None:
        room = meta.get("room") or {}
        if not isinstance(room, Mapping):
            raise InvalidInputError(f"a scan's 'room' must be a room object, got {str(room)[:80]}.")
        return [_checked_polygon(dict(room), "room")] if "polygon" in room else [dict(room)]
    if not isinstance(raw, list) or not raw or not all(isinstance(r, Mapping) for r in raw):
        raise InvalidInputError("a scan's 'rooms' must be a non-empty list of room objects.")
    rooms = []
    for i, room in enumerate(raw):
        if "polygon" not in room:
            raise InvalidInputError(
                f"rooms[{i}] has no 'polygon'; with several rooms each needs its [x, y] corners."
            )
        rooms.append(_checked_polygon({"id": i + 1, "type": "room", **dict(room)}, f"rooms[{i}]"))
    return rooms


def _checked_polygon(room: dict[str, Any], where: str) -> dict[str, Any]:
    """`room`, its "polygon" checked: at least 3 [x, y] corners of finite numbers."""
    polygon = room["polygon"]
    ok = isinstance(polygon, list | tuple) and len(polygon) >= 3
    for corner in polygon if ok else ():
        ok = ok and isinstance(corner, list | tuple) and len(corner) == 2
        ok = ok and all(_finite_number(v) for v in corner)
    if not ok:
        raise InvalidInputError(
            f"{where}.polygon must list at least 3 [x, y] corners in metres, got "
            f"{str(polygon)[:80]}."
        )
    return room


def _finite_number(value: Any) -> bool:
    """A JSON number (not a bool) that float64 holds finite."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return False
    try:
        return math.isfinite(float(value))
    except OverflowError:  # an integer past float64
        return False


def _containing(rooms: list[dict[str, Any]], xy: np.ndarray) -> dict[str, Any] | None:
    """The first room whose polygon holds `xy` (even-odd rule), or None."""
    for room in rooms:
        poly = np.asarray(room.get("polygon", []), dtype=np.float64)
        if len(poly) < 3:
            continue
        inside = False
        for (x0, y0), (x1, y1) in zip(poly, np.roll(poly, -1, axis=0), strict=True):
            if (y0 > xy[1]) != (y1 > xy[1]):
                x = x0 + (xy[1] - y0) * (x1 - x0) / (y1 - y0)
                inside ^= bool(xy[0] < x)
        if inside:
            return room
    return None


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
    passages: bool = True,
) -> Layout:
    """Convert a scan's object list into a validated `Layout` (its rooms, or one room).

    Args:
        data: the JSON object described in this module, or its "objects" list.
        name: layout name (default: data["name"] or "scan").
        up: the scan world's up axis ("z", "y", ...; default data["up"] or "z").
        floor_z: height of the floor in the scan (default: lowest box bottom).
        margin: metres added around the objects when the room polygon is not given.
        use_meshes: draw known categories with furniture meshes (else every object is a box).
        aliases: scan label -> catalog category, tried before the built-in table
            (`catalog.check_aliases` checks a user's file).
        passages: warn (`LayoutWarning`) of floor joined to the rest only through a passage
            the agent cannot be expected to pass (`narrow_passages`).

    Raises:
        InvalidInputError: malformed boxes or an empty list.
    """
    meta: Mapping[str, Any] = data if isinstance(data, Mapping) else {"objects": list(data)}
    entries = meta.get("objects")
    if not isinstance(entries, list) or not entries:
        raise InvalidInputError("a scan needs a non-empty 'objects' list of oriented boxes.")
    up_rotation = world_zup_from_up_axis(str(up or meta.get("up", "z")))
    boxes = _scan_boxes(entries, up_rotation)
    rooms = _scan_rooms(meta)
    skipped: dict[int, str] = {}
    boxes = _into_room_frames(boxes, rooms, skipped)
    if use_meshes:
        _warn_unknown_categories([category for _, category, _, _, _ in boxes], aliases)
    bottom = min(c[2] - s[2] / 2 for _, _, c, s, _ in boxes) if floor_z is None else floor_z
    objects, corners = _scan_objects(boxes, bottom, use_meshes, aliases)
    if "polygon" not in rooms[0]:
        pts = np.concatenate(corners)
        lo, hi = pts.min(axis=0) - margin, pts.max(axis=0) + margin
        rooms[0]["polygon"] = [[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]]
    top = max(c[2] + s[2] / 2 for _, _, c, s, _ in boxes) - bottom
    for room in rooms:
        room.setdefault("id", 1)
        room.setdefault("type", "room")
        room.setdefault("wall_height", max(2.6, top + 0.2))
    try:
        layout = layout_from_dict(
            {
                "name": name or str(meta.get("name", "scan")),
                "rooms": rooms,
                "openings": meta.get("openings", []),
                "objects": objects,
                "regions": meta.get("regions", []),
            }
        )
    except InvalidInputError as exc:
        said = _say_skipped(exc, skipped)
        if said is exc:
            raise
        raise said from exc
    if passages:
        for text in narrow_passages(layout):
            warnings.warn(text, LayoutWarning, stacklevel=2)
    return layout


def _scan_boxes(
    entries: list[Any], up_rotation: np.ndarray
) -> list[tuple[Mapping[str, Any], str, np.ndarray, np.ndarray, float]]:
    """(entry, category, centre [3] m z-up, size [3] m, yaw rad) of each checked scan entry.

    Raises:
        InvalidInputError: an entry that is no object, or lacks a category, a centre or a
            size, or has a non-finite centre or a non-positive size.
    """
    boxes = []
    for i, entry in enumerate(entries):
        where = f"objects[{i}]"
        if not isinstance(entry, Mapping):
            raise InvalidInputError(f"{where} must be an object, got {entry!r}.")
        category = str(entry.get("category", entry.get("label", ""))).strip()
        if not category:
            raise InvalidInputError(f"{where} has no 'category'; name the object's class.")
        oid = entry.get("id", i + 1)
        if isinstance(oid, bool) or not isinstance(oid, int):
            raise InvalidInputError(f"{where}.id must be an integer, got {str(oid)[:40]}.")
        if not isinstance(entry.get("attributes", {}), Mapping):
            raise InvalidInputError(
                f'{where}.attributes must be an object like {{"color": "red"}}, got '
                f"{str(entry['attributes'])[:40]}."
            )
        try:
            center = up_rotation @ np.asarray(entry["center"], dtype=np.float64).reshape(3)
            size = np.abs(np.asarray(entry.get("size", entry.get("extent")), dtype=np.float64))
            size = size.reshape(3)
        except (KeyError, TypeError, ValueError, OverflowError) as exc:
            raise InvalidInputError(
                f"{where} needs 'center' [x, y, z] and 'size' [sx, sy, sz] in metres."
            ) from exc
        if not (np.all(np.isfinite(center)) and np.all(np.isfinite(size)) and np.all(size > 0)):
            raise InvalidInputError(f"{where} has a non-finite centre or a non-positive size.")
        yaw, size = _box_pose(entry, size, up_rotation, where)
        boxes.append((entry, category, center, size, yaw))
    return boxes


def _scan_objects(
    boxes: list[tuple[Mapping[str, Any], str, np.ndarray, np.ndarray, float]],
    bottom: float,
    use_meshes: bool,
    aliases: Mapping[str, str] | None,
) -> tuple[list[dict[str, Any]], list[np.ndarray]]:
    """(layout object dicts, footprint corners [4, 2] m of each) of the boxes, standing on
    the floor at height `bottom`."""
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
    return objects, corners


SQUARE_DEG = 1.0  # a box's yaw within this of a multiple of 90 deg is square to the scan axes


def _square_to_axes(yaw: float) -> bool:
    """Whether a box turned by `yaw` stands square to the scan's axes (its box is then its
    axis-aligned bounding box, whether given as yaw 0 or an identity rotation)."""
    off = (math.degrees(yaw) + 45.0) % 90.0 - 45.0
    return abs(off) <= SQUARE_DEG


def _into_room_frames(
    boxes: list[Any], rooms: list[dict[str, Any]], skipped: dict[int, str] | None = None
) -> list[Any]:
    """Boxes square to the scan's axes (yaw 0, or a rotation that is a multiple of 90 deg:
    a scan's axis-aligned bounding boxes) in a room whose walls are turned become boxes
    turned with the room (`box_in_room_frame`); each one turned is reported with a
    `LayoutWarning`. `skipped` collects, by object id, why a box in a turned room was left
    as given (so a later refusal can say the fix did not apply)."""
    out = []
    for i, (entry, category, center, size, yaw) in enumerate(boxes):
        room = _containing(rooms, center[:2]) if "polygon" in rooms[0] else None
        turned, walls, why = None, 0.0, ""
        if room is not None:
            walls = room_yaw(np.asarray(room["polygon"], dtype=np.float64))
        if room is not None and abs(math.degrees(walls)) > AXIS_ALIGNED_DEG:
            if _square_to_axes(yaw):
                c, s_ = abs(math.cos(yaw)), abs(math.sin(yaw))
                bbox = np.array([size[0] * c + size[1] * s_, size[0] * s_ + size[1] * c])
                turned = box_in_room_frame(bbox, walls)
                if turned is None:
                    why = (
                        f"no box turned {math.degrees(walls):.1f} deg with the walls of room "
                        f"{room.get('id', 1)} has its {bbox[0]:.2f} x {bbox[1]:.2f} m "
                        "bounding box"
                        + (
                            " (walls near 45 deg)"
                            if abs(abs(math.degrees(walls)) - 45) < 12
                            else ""
                        )
                    )
            else:
                why = (
                    f"its box carries its own rotation ({math.degrees(yaw):.1f} deg; the walls "
                    f"of room {room.get('id', 1)} are turned {math.degrees(walls):.1f} deg), "
                    "so it was taken as given"
                )
        if turned is not None:
            warnings.warn(
                f"object {entry.get('id', '?')} ({category!r}): its axis-aligned box is read "
                f"as a {turned[0]:.2f} x {turned[1]:.2f} m box turned "
                f"{math.degrees(walls):.1f} deg with the walls of room "
                f"{room.get('id', 1)}.",  # type: ignore[union-attr]
                LayoutWarning,
                stacklevel=3,
            )
            size = np.array([turned[0], turned[1], size[2]])
            yaw = walls
        elif why and skipped is not None:
            skipped[int(entry.get("id", i + 1))] = why
        out.append((entry, category, center, size, yaw))
    return out


_NAMED_OBJECT = re.compile(r"\(object (\d+),")


def _say_skipped(exc: InvalidInputError, skipped: dict[int, str]) -> InvalidInputError:
    """`exc` with, for the object it names, why the turned-room fix did not apply."""
    named = _NAMED_OBJECT.search(str(exc))
    if named is None or int(named.group(1)) not in skipped:
        return exc
    oid = int(named.group(1))
    return InvalidInputError(
        f"{exc} The turned-room fix (a scan's axis-aligned box read square to turned walls) "
        f"was skipped for object {oid}: {skipped[oid]}."
    )
