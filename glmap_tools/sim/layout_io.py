"""Read, validate and write layout JSON files (format "glmap-sim-layout", version 1)."""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.sim.catalog import mesh_spec
from glmap_tools.sim.jsonfile import read_json
from glmap_tools.sim.layout import (
    Layout,
    Opening,
    Region,
    Room,
    SceneObject,
    point_segment_distance,
    polygon_signed_area,
)
from glmap_tools.sim.wallfit import fit_inside_room

FORMAT = "glmap-sim-layout"
VERSION = 1
MAX_OBJECT_ID = 65535  # ids are written into uint16 annotation PNGs
MAX_SPAN = 200.0  # metres along x and y (the nav grid at 5 cm: 4000 cells a side)
OPENING_TOLERANCE = 0.15  # metres between an opening's centre and each room's wall


def _get(entry: Mapping[str, Any], key: str, where: str, default: Any = ...) -> Any:
    if not isinstance(entry, Mapping):
        raise InvalidInputError(f"{where} must be a JSON object, got {str(entry)[:80]}.")
    if key in entry:
        return entry[key]
    if default is ...:
        raise InvalidInputError(f"{where} has no {key!r}; add it (see glmap_tools/sim/design.md).")
    return default


def _int(value: Any, where: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer):
        raise InvalidInputError(f"{where} must be an integer, got {value!r}.")
    return int(value)


def _float(value: Any, where: str, positive: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.number):
        raise InvalidInputError(f"{where} must be a number, got {value!r}.")
    try:
        out = float(value)
    except OverflowError:  # an integer past float64
        out = math.inf
    if not math.isfinite(out) or (positive and out <= 0):
        kind = "a positive finite" if positive else "a finite"
        raise InvalidInputError(f"{where} must be {kind} number, got {value!r}.")
    return out


def _vector(value: Any, n: int, where: str, positive: bool = False) -> np.ndarray:
    if not isinstance(value, Sequence) or isinstance(value, str) or len(value) != n:
        raise InvalidInputError(f"{where} must be a list of {n} numbers, got {value!r}.")
    return np.array([_float(v, f"{where}[{i}]", positive) for i, v in enumerate(value)])


def _color(value: Any, where: str) -> tuple[float, float, float]:
    rgb = _vector(value, 3, where)
    if np.any(rgb < 0) or np.any(rgb > 1):
        raise InvalidInputError(f"{where} = {value!r}: give RGB in [0, 1].")
    return (float(rgb[0]), float(rgb[1]), float(rgb[2]))


def _unique(ids: list[int], kind: str) -> None:
    seen: set[int] = set()
    for i in ids:
        if i in seen:
            raise InvalidInputError(
                f"{kind} id {i} is used twice; give every {kind} its own id "
                f"(next free: {max(ids) + 1})."
            )
        seen.add(i)


def _parse_room(entry: Mapping[str, Any], where: str) -> Room:
    room_id = _int(_get(entry, "id", where), f"{where}.id")
    if room_id <= 0:
        raise InvalidInputError(f"{where}.id = {room_id}: room ids are > 0 (0 means outside).")
    raw = _get(entry, "polygon", where)
    if not isinstance(raw, Sequence) or len(raw) < 3:
        raise InvalidInputError(f"{where}.polygon needs at least 3 [x, y] corners, got {raw!r}.")
    polygon = np.stack([_vector(p, 2, f"{where}.polygon[{i}]") for i, p in enumerate(raw)])
    area = polygon_signed_area(polygon)
    if abs(area) < 0.5:
        raise InvalidInputError(
            f"{where} (room {room_id}) has floor area {abs(area):.2f} m^2; a room needs at "
            "least 0.5 m^2 (check the polygon's corners)."
        )
    if area < 0:
        polygon = polygon[::-1].copy()
    height = _float(entry.get("wall_height", 2.6), f"{where}.wall_height", positive=True)
    room_type = str(_get(entry, "type", where))
    return Room(
        id=room_id,
        type=room_type,
        name=str(entry.get("name", room_type)),
        polygon=polygon,
        wall_height=height,
        floor_color=_color(entry.get("floor_color", (0.6, 0.5, 0.4)), f"{where}.floor_color"),
        wall_color=_color(entry.get("wall_color", (0.9, 0.9, 0.88)), f"{where}.wall_color"),
    )


def _on_wall(room: Room, point: np.ndarray) -> float:
    poly = room.polygon
    return min(
        point_segment_distance(point, poly[i], poly[(i + 1) % len(poly)]) for i in range(len(poly))
    )


def _parse_opening(entry: Mapping[str, Any], where: str, rooms: dict[int, Room]) -> Opening:
    opening_id = _int(_get(entry, "id", where), f"{where}.id")
    pair = _get(entry, "rooms", where)
    if not isinstance(pair, Sequence) or len(pair) != 2:
        raise InvalidInputError(f"{where}.rooms must name two room ids, got {pair!r}.")
    a, b = (_int(r, f"{where}.rooms") for r in pair)
    center = _vector(_get(entry, "center", where), 2, f"{where}.center")
    for rid in (a, b):
        if rid not in rooms:
            raise InvalidInputError(
                f"{where} (opening {opening_id}) joins unknown room {rid}; rooms are "
                f"{sorted(rooms)}."
            )
        gap = _on_wall(rooms[rid], center)
        if gap > OPENING_TOLERANCE:
            raise InvalidInputError(
                f"{where} (opening {opening_id}) centre {center.tolist()} is {gap:.2f} m from "
                f"every wall of room {rid}; put it on the wall the two rooms share."
            )
    kind = str(entry.get("kind", "door"))
    if kind not in ("door", "opening"):
        raise InvalidInputError(f"{where}.kind = {kind!r}; use 'door' or 'opening'.")
    return Opening(
        id=opening_id,
        rooms=(a, b),
        center=center,
        width=_float(entry.get("width", 0.9), f"{where}.width", positive=True),
        height=_float(entry.get("height", 2.1), f"{where}.height", positive=True),
        kind=kind,
    )


def _room_of(point: np.ndarray, rooms: list[Room]) -> int:
    for room in rooms:
        if room.contains(point.reshape(1, 2))[0]:
            return room.id
    return 0


def _parse_object(entry: Mapping[str, Any], where: str, rooms: list[Room]) -> SceneObject:
    object_id = _int(_get(entry, "id", where), f"{where}.id")
    if not 0 < object_id <= MAX_OBJECT_ID:
        raise InvalidInputError(
            f"{where}.id = {object_id}: object ids are mask values in 1..{MAX_OBJECT_ID}."
        )
    category = str(_get(entry, "category", where)).strip()
    if not category:
        raise InvalidInputError(f"{where} (object {object_id}) has an empty category; name it.")
    mesh = str(_get(entry, "mesh", where))
    spec = mesh_spec(mesh, where=f"{where} (object {object_id}) mesh")
    size = (
        _vector(entry["size"], 3, f"{where}.size", positive=True)
        if "size" in entry
        else np.array(spec.default_size)
    )
    position = _vector(_get(entry, "position", where), 3, f"{where}.position")
    room = _room_of(position[:2], rooms)
    if room == 0:
        lo = np.min([r.polygon.min(axis=0) for r in rooms], axis=0)
        hi = np.max([r.polygon.max(axis=0) for r in rooms], axis=0)
        raise InvalidInputError(
            f"object {object_id} ({category!r}) at ({position[0]:.2f}, {position[1]:.2f}) is "
            f"outside every room (rooms span x {lo[0]:.2f}..{hi[0]:.2f}, y {lo[1]:.2f}.."
            f"{hi[1]:.2f}); move it inside a room's polygon or add the room it stands in."
        )
    if "room" in entry and _int(entry["room"], f"{where}.room") != room:
        raise InvalidInputError(
            f"object {object_id} ({category!r}) says room {entry['room']} but stands in room "
            f"{room}; fix its position or its 'room' (or leave 'room' out)."
        )
    attributes = entry.get("attributes", {})
    if not isinstance(attributes, Mapping):
        raise InvalidInputError(f"{where}.attributes must be an object of strings.")
    supported_by = entry.get("supported_by")
    return SceneObject(
        id=object_id,
        category=category,
        mesh=mesh,
        position=position,
        heading=_float(entry.get("heading", 0.0), f"{where}.heading"),
        size=size,
        attributes={str(k): str(v) for k, v in attributes.items()},
        color=_color(entry["color"], f"{where}.color") if entry.get("color") is not None else None,
        description=str(entry.get("description", "")),
        room=room,
        supported_by=None if supported_by is None else _int(supported_by, f"{where}.supported_by"),
    )


def _parse_region(entry: Mapping[str, Any], where: str, object_ids: set[int]) -> Region:
    region_id = _int(_get(entry, "id", where), f"{where}.id")
    members = _get(entry, "members", where)
    if not isinstance(members, Sequence) or not members:
        raise InvalidInputError(f"{where} (region {region_id}) needs a non-empty 'members' list.")
    ids = tuple(_int(m, f"{where}.members") for m in members)
    unknown = sorted(set(ids) - object_ids)
    if unknown:
        raise InvalidInputError(
            f"region {region_id} lists unknown object ids {unknown}; members must be ids of "
            "objects in this layout."
        )
    description = str(_get(entry, "description", where)).strip()
    if not description:
        raise InvalidInputError(f"region {region_id} has an empty description; describe it.")
    return Region(
        id=region_id,
        name=str(entry.get("name", description.split(":")[0])),
        description=description,
        members=ids,
        room=_int(entry.get("room", 0) or 0, f"{where}.room"),
    )


def _list(data: Mapping[str, Any], key: str, required: bool) -> list[Any]:
    value = data.get(key, None if required else [])
    if not isinstance(value, list) or (required and not value):
        raise InvalidInputError(f"layout needs a non-empty list {key!r}, got {value!r}.")
    return value


def layout_from_dict(data: Mapping[str, Any]) -> Layout:
    """Parse and validate a layout JSON object.

    Raises:
        InvalidInputError: unknown mesh (with a suggestion), object outside every room,
            duplicate ids, openings off the shared wall, malformed fields, an object that
            crosses a wall by more than `wallfit.MAX_WALL_SHIFT`.

    An object crossing a wall by less is moved inside its room with a `LayoutWarning`.
    """
    if not isinstance(data, Mapping):
        raise InvalidInputError(f"a layout is a JSON object, got {type(data).__name__}.")
    fmt = data.get("format", FORMAT)
    if fmt != FORMAT or data.get("version", VERSION) != VERSION:
        raise InvalidInputError(
            f"layout format {fmt!r} version {data.get('version')!r} is not {FORMAT!r} "
            f"version {VERSION}; convert it or regenerate it with `glmap sim new`."
        )
    room_entries = _list(data, "rooms", required=True)
    rooms = [_parse_room(e, f"rooms[{i}]") for i, e in enumerate(room_entries)]
    span = np.ptp(np.concatenate([r.polygon for r in rooms]), axis=0)
    if span.max() > MAX_SPAN:
        raise InvalidInputError(
            f"the rooms span {span[0]:.4g} x {span[1]:.4g} m; a layout spans at most "
            f"{MAX_SPAN:.0f} m along x and y: give coordinates in metres, or split it into scenes."
        )
    _unique([r.id for r in rooms], "room")
    by_id = {r.id: r for r in rooms}
    openings = [
        _parse_opening(e, f"openings[{i}]", by_id)
        for i, e in enumerate(_list(data, "openings", required=False))
    ]
    _unique([o.id for o in openings], "opening")
    objects = [
        _parse_object(e, f"objects[{i}]", rooms)
        for i, e in enumerate(_list(data, "objects", required=False))
    ]
    _unique([o.id for o in objects], "object")
    objects = [fit_inside_room(o, by_id[o.room], f"objects[{i}]") for i, o in enumerate(objects)]
    object_ids = {o.id for o in objects}
    for obj in objects:
        if obj.supported_by is not None and obj.supported_by not in object_ids:
            raise InvalidInputError(
                f"object {obj.id} is supported_by unknown object {obj.supported_by}; use an "
                "object id of this layout or leave it out."
            )
    regions = [
        _parse_region(e, f"regions[{i}]", object_ids)
        for i, e in enumerate(_list(data, "regions", required=False))
    ]
    _unique([g.id for g in regions], "region")
    seed = data.get("seed")
    return Layout(
        name=str(data.get("name", "layout")),
        rooms=rooms,
        openings=openings,
        objects=objects,
        regions=regions,
        seed=None if seed is None else _int(seed, "layout seed"),
    )


def _r(values: np.ndarray | Sequence[float], nd: int = 4) -> list[float]:
    return [round(float(v), nd) for v in values]


def layout_to_dict(layout: Layout) -> dict[str, Any]:
    """The JSON object of a layout (round-trips through `layout_from_dict`)."""
    return {
        "format": FORMAT,
        "version": VERSION,
        "name": layout.name,
        "seed": layout.seed,
        "rooms": [
            {
                "id": r.id,
                "type": r.type,
                "name": r.name,
                "polygon": [_r(p) for p in r.polygon],
                "wall_height": r.wall_height,
                "floor_color": _r(r.floor_color, 3),
                "wall_color": _r(r.wall_color, 3),
            }
            for r in layout.rooms
        ],
        "openings": [
            {
                "id": o.id,
                "rooms": list(o.rooms),
                "center": _r(o.center),
                "width": o.width,
                "height": o.height,
                "kind": o.kind,
            }
            for o in layout.openings
        ],
        "objects": [
            {
                "id": o.id,
                "category": o.category,
                "mesh": o.mesh,
                "room": o.room,
                "position": _r(o.position),
                "heading": round(float(o.heading), 5),
                "size": _r(o.size),
                "attributes": dict(o.attributes),
                "color": None if o.color is None else _r(o.color, 3),
                "description": o.description,
                **({} if o.supported_by is None else {"supported_by": o.supported_by}),
            }
            for o in layout.objects
        ],
        "regions": [
            {
                "id": g.id,
                "name": g.name,
                "description": g.description,
                "members": list(g.members),
                "room": g.room,
            }
            for g in layout.regions
        ],
    }


def load_layout(path: str | os.PathLike[str]) -> Layout:
    """Read and validate a layout JSON file."""
    data = read_json(path, "layout file", "`glmap sim new`")
    return layout_from_dict(data)


def save_layout(layout: Layout, path: str | os.PathLike[str]) -> None:
    """Write a layout as indented JSON."""
    with open(path, "w", encoding="utf-8") as f:
        json.dump(layout_to_dict(layout), f, indent=1)
        f.write("\n")
