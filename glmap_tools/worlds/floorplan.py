"""Seeded floor plans: a rectangle sliced into 3-7 rectangular rooms joined by doors.

Rooms get target areas by type; the apartment rectangle is cut recursively (longer side
first) so each room's area matches its target. Rooms sharing at least `MIN_SHARED` metres of
wall are neighbours; the living room connects to all its neighbours, the rest join by a
spanning tree, kitchens and dining rooms next to the living room get a wide opening.

Larger apartments (the benchmark split): `area_scale` multiplies every room's target area,
and `hallway=True` lays the rooms out in two rows along a long corridor (an extra room of
type "hallway", `HALLWAY_WIDTH` wide, across the whole apartment) that opens to every room
touching it; the others join by the spanning tree. The defaults draw exactly what they
always drew, so existing seeds keep their apartments.

Houses (`house=True`, the house splits): 7-11 furnished rooms along the hallway (8-12 rooms
in all), always two bedrooms and two bathrooms, a dining room, and extras drawn from an
office, a third bedroom, a third bathroom and a laundry room (`house_room_types`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.sim.layout import Opening, Room
from glmap_tools.sim.palette import FLOOR_COLORS, WALL_COLORS

MIN_SHARED = 1.4  # metres of shared wall needed for a door
DOOR_WIDTH = 0.9
OPENING_WIDTH = (1.4, 2.2)
MIN_SIDE = 2.0  # metres
MAX_ASPECT = 2.6
HALLWAY_WIDTH = (1.3, 1.7)  # metres
HALLWAY_ASPECT = (2.2, 3.2)  # apartment length / depth when the rooms line a hallway
HOUSE_ASPECT = (1.5, 2.4)  # the same for houses: deeper rows, where small rooms stack

AREA = {  # m^2 ranges per room type
    "living room": (20.0, 30.0),
    "kitchen": (9.0, 14.0),
    "bedroom": (11.0, 16.0),
    "bathroom": (4.5, 7.0),
    "office": (8.0, 11.0),
    "dining room": (10.0, 14.0),
    "laundry room": (4.5, 7.0),
}
FLOORS = {
    "living room": ("light oak parquet", "dark wood floor", "blue-grey vinyl"),
    "kitchen": ("grey tiles", "white tiles", "terracotta tiles"),
    "bedroom": ("beige carpet", "light oak parquet", "dark wood floor"),
    "bathroom": ("white tiles", "grey tiles"),
    "office": ("light oak parquet", "blue-grey vinyl", "beige carpet"),
    "dining room": ("dark wood floor", "light oak parquet", "terracotta tiles"),
    "hallway": ("light oak parquet", "grey tiles", "dark wood floor"),
    "laundry room": ("white tiles", "grey tiles", "blue-grey vinyl"),
}
HOUSE_TRIES = 2000  # floor plans drawn for a house: many small rooms fail MIN_SIDE more often
HOUSE_ROOMS = (7, 11)  # furnished rooms of a house (a hallway comes on top)
HOUSE_BASE = ("living room", "kitchen", "bedroom", "bedroom", "bathroom", "bathroom", "dining room")
HOUSE_EXTRA = ("office", "bedroom", "bathroom", "laundry room")


@dataclass(frozen=True)
class Rect:
    """An axis-aligned rectangle (metres)."""

    x0: float
    y0: float
    x1: float
    y1: float

    @property
    def w(self) -> float:
        return self.x1 - self.x0

    @property
    def h(self) -> float:
        return self.y1 - self.y0


def room_types(n_rooms: int, rng: np.random.Generator) -> list[str]:
    """The room types of an apartment with `n_rooms` rooms (living room, kitchen, ...)."""
    if not 3 <= n_rooms <= 7:
        raise InvalidInputError(f"n_rooms={n_rooms} must be in 3..7.")
    base = ["living room", "kitchen", "bedroom", "bathroom"][:n_rooms]
    extra = ["office", "dining room", "bedroom"]
    rng.shuffle(extra)
    return base + extra[: n_rooms - len(base)]


def house_room_types(n_rooms: int, rng: np.random.Generator) -> list[str]:
    """The room types of a house of `n_rooms` furnished rooms: two bedrooms, two bathrooms,
    a living room, a kitchen, a dining room and `n_rooms` - 7 extras (`HOUSE_EXTRA`)."""
    if not HOUSE_ROOMS[0] <= n_rooms <= HOUSE_ROOMS[1]:
        raise InvalidInputError(
            f"n_rooms={n_rooms} must be in {HOUSE_ROOMS[0]}..{HOUSE_ROOMS[1]} for a house."
        )
    extra = list(HOUSE_EXTRA)
    rng.shuffle(extra)
    return list(HOUSE_BASE) + extra[: n_rooms - len(HOUSE_BASE)]


def _slice(rect: Rect, areas: list[float], ids: list[int], out: dict[int, Rect]) -> None:
    if len(ids) == 1:
        out[ids[0]] = rect
        return
    total = sum(areas)
    best, best_diff = 1, math.inf
    for k in range(1, len(ids)):
        diff = abs(sum(areas[:k]) - total / 2)
        if diff < best_diff:
            best, best_diff = k, diff
    frac = sum(areas[:best]) / total
    if rect.w >= rect.h:
        cut = rect.x0 + rect.w * frac
        _slice(Rect(rect.x0, rect.y0, cut, rect.y1), areas[:best], ids[:best], out)
        _slice(Rect(cut, rect.y0, rect.x1, rect.y1), areas[best:], ids[best:], out)
    else:
        cut = rect.y0 + rect.h * frac
        _slice(Rect(rect.x0, rect.y0, rect.x1, cut), areas[:best], ids[:best], out)
        _slice(Rect(rect.x0, cut, rect.x1, rect.y1), areas[best:], ids[best:], out)


def _shared(a: Rect, b: Rect) -> tuple[np.ndarray, np.ndarray] | None:
    """The wall segment two rectangles share (endpoints), or None."""
    tol = 1e-6
    if abs(a.x1 - b.x0) < tol or abs(b.x1 - a.x0) < tol:
        x = a.x1 if abs(a.x1 - b.x0) < tol else a.x0
        lo, hi = max(a.y0, b.y0), min(a.y1, b.y1)
        if hi - lo > tol:
            return np.array([x, lo]), np.array([x, hi])
    if abs(a.y1 - b.y0) < tol or abs(b.y1 - a.y0) < tol:
        y = a.y1 if abs(a.y1 - b.y0) < tol else a.y0
        lo, hi = max(a.x0, b.x0), min(a.x1, b.x1)
        if hi - lo > tol:
            return np.array([lo, y]), np.array([hi, y])
    return None


def _round(v: float) -> float:
    return round(v * 20) / 20  # 5 cm


def _bad_shapes(rects: dict[int, Rect], rooms: list[int]) -> bool:
    return any(
        min(rects[i].w, rects[i].h) < MIN_SIDE
        or max(rects[i].w, rects[i].h) / min(rects[i].w, rects[i].h) > MAX_ASPECT
        for i in rooms
    )


def _split(order: list[int], areas: list[float]) -> int:
    """How many of `order` go into the first of two rows of about equal area."""
    total, best, best_diff = sum(areas), 1, math.inf
    for k in range(1, len(order)):
        diff = abs(sum(areas[:k]) - total / 2)
        if diff < best_diff:
            best, best_diff = k, diff
    return best


def _hallway_rects(
    order: list[int],
    areas: list[float],
    rng: np.random.Generator,
    aspects: tuple[float, float] = HALLWAY_ASPECT,
) -> dict[int, Rect]:
    """Two rows of rooms along a corridor (key len(order)) that runs the apartment's length."""
    total = sum(areas)
    aspect = float(rng.uniform(*aspects))
    corridor = _round(float(rng.uniform(*HALLWAY_WIDTH)))
    length = _round(math.sqrt(total * aspect))
    k = _split(order, areas)
    depth_a = _round(sum(areas[:k]) / length)
    depth_b = _round(sum(areas[k:]) / length)
    rects: dict[int, Rect] = {}
    _slice(Rect(0.0, 0.0, length, depth_a), areas[:k], order[:k], rects)
    y1 = depth_a + corridor
    _slice(Rect(0.0, y1, length, y1 + depth_b), areas[k:], order[k:], rects)
    rects[len(order)] = Rect(0.0, depth_a, length, y1)
    return rects


def generate_floorplan(
    n_rooms: int,
    rng: np.random.Generator,
    tries: int = 200,
    area_scale: float = 1.0,
    hallway: bool = False,
    house: bool = False,
) -> tuple[list[Room], list[Opening]]:
    """Rooms (rectangles, counter-clockwise) and the openings that connect them all.

    Args:
        n_rooms: 3..7 furnished rooms (a hallway comes on top).
        rng: the generator's random stream.
        tries: floor plans drawn before giving up.
        area_scale: multiplies every room's target area (1.0: the usual apartment).
        hallway: line the rooms along a corridor (the last room, type "hallway").
        house: `n_rooms` in 7..11 of `house_room_types` (implies `hallway`).
    """
    if not 0.5 <= area_scale <= 3.0:
        raise InvalidInputError(f"area_scale={area_scale!r} must be in [0.5, 3].")
    types = house_room_types(n_rooms, rng) if house else room_types(n_rooms, rng)
    hallway = hallway or house
    tries = max(tries, HOUSE_TRIES) if house else tries
    for _ in range(tries):
        order = list(range(n_rooms))
        rng.shuffle(order)
        areas = [float(rng.uniform(*AREA[types[i]])) * area_scale for i in order]
        if hallway:
            rects = _hallway_rects(order, areas, rng, HOUSE_ASPECT if house else HALLWAY_ASPECT)
        else:
            total = sum(areas)
            aspect = float(rng.uniform(1.1, 1.7))
            width = _round(math.sqrt(total * aspect))
            height = _round(total / width)
            rects = {}
            _slice(Rect(0.0, 0.0, width, height), areas, order, rects)
        rects = {
            i: Rect(_round(r.x0), _round(r.y0), _round(r.x1), _round(r.y1))
            for i, r in rects.items()
        }
        if _bad_shapes(rects, list(range(n_rooms))):
            continue
        all_types = types + ["hallway"] if hallway else types
        openings = _connect(all_types, rects, rng)
        if openings is None:
            continue
        return _rooms(all_types, rects, rng), openings
    raise InvalidInputError(
        f"no floor plan with {n_rooms} rooms found in {tries} tries; try another seed."
    )


def _connect(
    types: list[str], rects: dict[int, Rect], rng: np.random.Generator
) -> list[Opening] | None:
    n = len(types)
    shared = {}
    for i in range(n):
        for j in range(i + 1, n):
            seg = _shared(rects[i], rects[j])
            if seg is not None and np.linalg.norm(seg[1] - seg[0]) >= MIN_SHARED:
                shared[(i, j)] = seg
    edges: list[tuple[int, int]] = []
    # The hub opens to all its neighbours: the hallway if there is one, else the living room.
    hub = types.index("hallway") if "hallway" in types else 0
    connected = {hub}
    for i, j in shared:
        if hub in (i, j) and (hub != 0 or "bathroom" not in (types[i], types[j])):
            edges.append((i, j))
            connected.add(j if i == hub else i)
    while len(connected) < n:
        frontier = [
            (i, j)
            for (i, j) in shared
            if (i in connected) != (j in connected)
            and types[i if i in connected else j] != "bathroom"
        ]
        if not frontier:
            frontier = [(i, j) for (i, j) in shared if (i in connected) != (j in connected)]
        if not frontier:
            return None
        i, j = frontier[int(rng.integers(len(frontier)))]
        edges.append((i, j))
        connected.update((i, j))
    openings = []
    for k, (i, j) in enumerate(edges):
        a, b = shared[(i, j)]
        length = float(np.linalg.norm(b - a))
        wide = {types[i], types[j]} & {"kitchen", "dining room"} and "living room" in (
            types[i],
            types[j],
        )
        width = DOOR_WIDTH
        kind = "door"
        if wide and rng.random() < 0.7:
            width = min(float(rng.uniform(*OPENING_WIDTH)), length - 0.5)
            kind = "opening" if width > 1.2 else "door"
        margin = width / 2 + 0.25
        t = float(rng.uniform(margin, length - margin)) if length > 2 * margin else length / 2
        center = a + (b - a) / length * t
        openings.append(
            Opening(
                id=k + 1,
                rooms=(i + 1, j + 1),
                center=np.round(center * 100) / 100,
                width=round(width, 2),
                height=2.1 if kind == "door" else 2.3,
                kind=kind,
            )
        )
    return openings


def _rooms(types: list[str], rects: dict[int, Rect], rng: np.random.Generator) -> list[Room]:
    wall_colors = list(WALL_COLORS)
    rng.shuffle(wall_colors)
    height = float(rng.choice([2.5, 2.6, 2.7, 2.8]))
    counts: dict[str, int] = {}
    rooms = []
    for i, room_type in enumerate(types):
        r = rects[i]
        counts[room_type] = counts.get(room_type, 0) + 1
        ordinal = ("", "", "second ", "third ")[min(counts[room_type], 3)]
        name = ordinal + room_type
        floor = str(rng.choice(FLOORS[room_type]))
        rooms.append(
            Room(
                id=i + 1,
                type=room_type,
                name=name,
                polygon=np.array([[r.x0, r.y0], [r.x1, r.y0], [r.x1, r.y1], [r.x0, r.y1]]),
                wall_height=height,
                floor_color=FLOOR_COLORS[floor],
                wall_color=wall_colors[i % len(wall_colors)],
            )
        )
    return rooms
