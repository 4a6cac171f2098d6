"""Seeded procedural apartments: floor plan, furniture by placement rules, regions.

`generate_apartment(seed)` is deterministic: the same seed gives the same layout, byte for
byte once saved. Every generated layout passes `layout_from_dict` validation and has every
room and opening on one connected navigable area. `generate_house(seed)` is the same with
`house=True`: 8-12 rooms along a hallway, repeated room types, clutter and now and then a
goal-category object in an unlikely room (`clutter.py`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.sim.describe import object_description, region_description
from glmap_tools.sim.layout import Layout, Opening, Room
from glmap_tools.sim.layout_io import layout_from_dict, layout_to_dict
from glmap_tools.sim.navgrid import build_nav_grid
from glmap_tools.worlds.clutter import UNLIKELY_RATE, furnish_house_extras
from glmap_tools.worlds.floorplan import generate_floorplan
from glmap_tools.worlds.placement import Placed, RoomPlanner
from glmap_tools.worlds.recipes import RECIPES, RegionPlan, add_decor
from glmap_tools.worlds.specs import SpecMaker

MIN_OBJECTS = 25
MAX_OBJECTS = 80
HOUSE_MIN_OBJECTS = 60
HOUSE_MAX_OBJECTS = 200
FURNISH_TRIES = 6
PLAN_TRIES = 3


def _furnish(
    rooms: list[Room],
    openings: list[Opening],
    rng: np.random.Generator,
    min_objects: int,
    house: tuple[np.random.Generator, np.random.Generator, float] | None = None,
) -> tuple[list[RoomPlanner], list[RegionPlan], list[Placed]]:
    """Recipes, then (houses: `house` = unlikely stream, clutter stream, unlikely rate) the
    unlikely goal objects and clutter, then decorations up to `min_objects`.

    Returns:
        (planners, regions, the unlikely objects placed).
    """
    maker = SpecMaker(rng)
    planners, regions = [], []
    for room in rooms:
        planner = RoomPlanner(room, [o for o in openings if room.id in o.rooms], rng)
        regions += RECIPES[room.type](planner, maker)
        planners.append(planner)
    unlikely = furnish_house_extras(planners, maker, *house) if house is not None else []
    for _ in range(200):
        if sum(len(p.placed) for p in planners) >= min_objects:
            break
        add_decor(planners[int(rng.integers(len(planners)))], maker)
    return planners, regions, unlikely


def _trim(
    planners: list[RoomPlanner],
    regions: list[RegionPlan],
    max_objects: int,
    keep: list[Placed] | None = None,
) -> None:
    """Drop decorations (objects in no region, supporting nothing, not in `keep`) until at
    most max_objects."""
    in_region = {id(p) for _, _, members in regions for p in members}
    in_region |= {id(p) for p in keep or []}
    supports = {id(p.support) for pl in planners for p in pl.placed if p.support is not None}
    while sum(len(p.placed) for p in planners) > max_objects:
        planner = max(planners, key=lambda p: len(p.placed))
        spare = [p for p in planner.placed if id(p) not in in_region and id(p) not in supports]
        if not spare:
            planner = next(pl for pl in planners if pl.placed)
            spare = [planner.placed[-1]]
        planner.placed.remove(spare[-1])
        for _, _, members in regions:
            if spare[-1] in members:
                members.remove(spare[-1])


def _layout_dict(
    seed: int, rooms: list[Room], openings: list[Opening], planners: list[RoomPlanner],
    regions: list[RegionPlan], kind: str = "apartment",
) -> dict[str, Any]:  # fmt: skip
    ids: dict[int, int] = {}
    objects = []
    for planner in planners:
        for p in planner.placed:
            ids[id(p)] = len(ids) + 1
    for planner in planners:
        for p in planner.placed:
            entry = {
                "id": ids[id(p)],
                "category": p.spec.category,
                "mesh": p.spec.mesh,
                "position": [round(float(v), 4) for v in p.position],
                "heading": round(math.remainder(p.heading, 2 * math.pi), 5),
                "size": [round(float(v), 4) for v in p.spec.size],
                "attributes": dict(p.spec.attributes),
                "description": object_description(p.spec.category, p.spec.attributes),
            }
            if p.support is not None and id(p.support) in ids:
                entry["supported_by"] = ids[id(p.support)]
            objects.append(entry)
    region_entries: list[dict[str, Any]] = []
    for name, purpose, members in regions:
        kept = [m for m in members if id(m) in ids]
        if not kept:
            continue
        region_entries.append(
            {
                "id": len(region_entries) + 1,
                "name": name,
                "description": region_description(name, purpose, [m.spec.category for m in kept]),
                "members": [ids[id(m)] for m in kept],
                "room": kept[0].room,
            }
        )
    skeleton = Layout(f"{kind}-{seed}", rooms, openings, [], [], seed)
    data = layout_to_dict(skeleton)
    data["objects"] = objects
    data["regions"] = region_entries
    return data


def _connected(layout: Layout) -> bool:
    """Every room has navigable floor and every opening is passable, all in one component."""
    grid = build_nav_grid(layout)
    xs, ys = grid.cell_centers()
    pts = np.column_stack([xs.ravel(), ys.ravel()])
    nav = grid.navigable.ravel()
    for room in layout.rooms:
        if (nav & room.contains(pts)).sum() * grid.cell**2 < 0.6:
            return False
    for opening in layout.openings:
        near = np.linalg.norm(pts - opening.center, axis=1) < 0.2
        if not (nav & near).any():
            return False
    return True


def generate_apartment(
    seed: int,
    n_rooms: int | None = None,
    min_objects: int | None = None,
    max_objects: int | None = None,
    area_scale: float = 1.0,
    hallway: bool = False,
    house: bool = False,
    unlikely_rate: float = UNLIKELY_RATE,
) -> Layout:
    """A furnished apartment of 3-7 rooms (a house of 7-11 and a hallway) from `seed`
    (deterministic).

    Args:
        seed: any non-negative integer.
        n_rooms: furnished rooms, 3..7 (houses 7..11); drawn from the seed when None.
        min_objects: decorations are added until there are at least this many objects
            (default `MIN_OBJECTS`, houses `HOUSE_MIN_OBJECTS`).
        max_objects: decorations are removed above this many objects (default
            `MAX_OBJECTS`, houses `HOUSE_MAX_OBJECTS`).
        area_scale: multiplies every room's target area (larger apartments; 1.0 as always).
        hallway: line the rooms along a corridor that runs the apartment's length (an extra
            room of type "hallway"). The defaults keep every seed's apartment unchanged.
        house: a house (`floorplan.house_room_types`, always along a hallway, named
            "house-<seed>"), with clutter and unlikely goal objects (`clutter.py`).
        unlikely_rate: houses: the chance per room of a goal-category object where the
            recipes never put one (`clutter.UNLIKELY`).

    Raises:
        InvalidInputError: bad arguments, or no valid apartment for this seed (try another).
    """
    if min_objects is None:
        min_objects = HOUSE_MIN_OBJECTS if house else MIN_OBJECTS
    if max_objects is None:
        max_objects = HOUSE_MAX_OBJECTS if house else MAX_OBJECTS
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise InvalidInputError(f"seed={seed!r} must be a non-negative integer.")
    if not 1 <= min_objects <= max_objects:
        raise InvalidInputError(
            f"min_objects={min_objects} and max_objects={max_objects} need "
            "1 <= min_objects <= max_objects."
        )
    if not 0.0 <= unlikely_rate <= 1.0:
        raise InvalidInputError(f"unlikely_rate={unlikely_rate!r} must be in [0, 1].")
    rng = np.random.default_rng([int(seed), 1])
    if n_rooms is None:
        n_rooms = int(rng.integers(3, 8)) if not house else int(rng.integers(7, 12))
    name = "house" if house else "apartment"
    for plan in range(PLAN_TRIES):
        try:
            rooms, openings = generate_floorplan(
                n_rooms, rng, area_scale=area_scale, hallway=hallway, house=house
            )
        except InvalidInputError:
            if not house or plan == PLAN_TRIES - 1:
                raise
            continue  # houses: many small rooms; the stream has moved on, draw again
        for attempt in range(FURNISH_TRIES):
            sub = np.random.default_rng([int(seed), 2, plan, attempt])
            extras = None
            if house:
                extras = (
                    np.random.default_rng([int(seed), 4, plan, attempt]),
                    np.random.default_rng([int(seed), 5, plan, attempt]),
                    unlikely_rate,
                )
            planners, regions, unlikely = _furnish(rooms, openings, sub, min_objects, extras)
            _trim(planners, regions, max_objects, unlikely)
            data = _layout_dict(seed, rooms, openings, planners, regions, name)
            layout = layout_from_dict(data)
            if _connected(layout):
                return layout
    raise InvalidInputError(
        f"seed {seed}: no furnishing left every room reachable in {PLAN_TRIES} floor plans x "
        f"{FURNISH_TRIES} tries; try another seed."
    )


def generate_house(seed: int, n_rooms: int | None = None, **options: Any) -> Layout:
    """A house from `seed`: `generate_apartment(seed, n_rooms, house=True, **options)`."""
    return generate_apartment(seed, n_rooms, house=True, **options)
