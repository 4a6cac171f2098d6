"""Houses: clutter, and now and then a goal-category object in a room one would not expect.

Real homes are not furnished by recipe alone. After the room recipes, a house gets
(`furnish_house_extras`, each from its own seeded stream so the rates below hold whatever the
recipes drew):

- one goal-category object (HM3D's ObjectNav categories, `GOAL_CATEGORIES`) in a room where
  the recipes never put that category (`UNLIKELY`: a TV in a bedroom or a kitchen, a sofa or a
  guest bed in an office, a chair in a bathroom or a hallway, a toilet in a laundry room), in
  each room with probability `UNLIKELY_RATE`;
- small objects on free surfaces (`SMALL_ON_SURFACES`: books, a vase, a bowl, a small plant)
  with probability `SURFACE_RATE` per surface, pillows on sofas, armchairs and beds
  (`PILLOW_RATE`);
- one extra piece of furniture per room (`EXTRA_FURNITURE`) with probability `EXTRA_RATE`,
  and a thing left on the floor (a box, a laundry basket) with probability `FLOOR_RATE`.

No extra piece is of a category `UNLIKELY` lists for its room, so an unlikely object in a
generated house is exactly one that this pass placed (the tests count them that way).
"""

from __future__ import annotations

import numpy as np

from glmap_tools.worlds.placement import Placed, RoomPlanner
from glmap_tools.worlds.specs import KINDS, SpecMaker

GOAL_CATEGORIES = ("chair", "bed", "plant", "toilet", "tv", "sofa")  # HM3D ObjectNav goals
UNLIKELY_RATE = 0.15  # per room: one goal-category object where the recipes never put one
SURFACE_RATE = 0.35  # per free surface: a small object on it
PILLOW_RATE = 0.6  # per sofa, armchair or bed: a pillow on it
EXTRA_RATE = 0.6  # per room: one extra piece of furniture
FLOOR_RATE = 0.3  # per room: a box or basket on the floor

# Room type -> kinds of goal-category objects the recipes never place there.
UNLIKELY: dict[str, tuple[str, ...]] = {
    "living room": ("single bed",),
    "kitchen": ("flat tv", "sofa"),
    "bedroom": ("flat tv", "sofa"),
    "bathroom": ("chair",),
    "office": ("sofa", "single bed", "flat tv", "chair"),
    "dining room": ("flat tv", "sofa"),
    "hallway": ("chair",),
    "laundry room": ("chair", "toilet"),
}
SURFACES = (
    "table",
    "desk",
    "dresser",
    "nightstand",
    "side table",
    "coffee table",
    "kitchen cabinet",
)
SMALL_ON_SURFACES = ("books", "vase", "bowl", "small plant")
SOFT = ("sofa", "armchair", "bed")
EXTRA_FURNITURE: dict[str, tuple[str, ...]] = {
    "living room": ("armchair", "bookcase", "side table", "floor lamp", "cabinet"),
    "kitchen": ("cabinet", "trash can"),
    "bedroom": ("bookcase", "dresser", "desk", "floor lamp", "armchair"),
    "bathroom": ("cabinet", "laundry basket"),
    "office": ("cabinet", "armchair", "floor lamp", "side table"),
    "dining room": ("cabinet", "bookcase", "plant"),
    "hallway": ("side table", "doormat"),
    "laundry room": ("cabinet", "box"),
}
FLOOR_CLUTTER = ("box", "laundry basket")


def unlikely_categories(room_type: str) -> frozenset[str]:
    """The goal categories the generator's recipes never put in a room of this type."""
    return frozenset(KINDS[k].category for k in UNLIKELY.get(room_type, ()))


def _pick(rng: np.random.Generator, options: tuple[str, ...]) -> str:
    return options[int(rng.integers(len(options)))]


def place_unlikely(planner: RoomPlanner, maker: SpecMaker, kind: str) -> Placed | None:
    """One goal-category object of `kind` somewhere it fits in the room (a TV on a stand of
    its own, or on the wall)."""
    spec = maker.make(kind)
    if KINDS[kind].category == "tv":
        stand = planner.against_wall(maker.make("tv stand"))
        if stand is not None:
            return planner.on_top(spec, stand, jitter=0.0)
        return planner.on_wall(spec, z=float(planner.rng.uniform(1.0, 1.2)))
    return planner.against_wall(spec) or planner.corner(spec) or planner.anywhere(spec)


def furnish_house_extras(
    planners: list[RoomPlanner],
    maker: SpecMaker,
    unlikely_rng: np.random.Generator,
    clutter_rng: np.random.Generator,
    unlikely_rate: float = UNLIKELY_RATE,
) -> list[Placed]:
    """Unlikely goal objects first (each room draws once from `unlikely_rng`), then clutter
    (`clutter_rng`). Returns the unlikely objects placed (the caller keeps them)."""
    unlikely: list[Placed] = []
    for planner in planners:
        options = UNLIKELY.get(planner.room.type, ())
        hit = bool(unlikely_rng.random() < unlikely_rate)
        kinds = [options[int(i)] for i in unlikely_rng.permutation(len(options))]
        if not hit:
            continue
        own, planner.rng = planner.rng, unlikely_rng
        for kind in kinds:  # the first kind that fits the room
            placed = place_unlikely(planner, maker, kind)
            if placed is not None:
                unlikely.append(placed)
                break
        planner.rng = own
    clutter_maker = SpecMaker(clutter_rng)
    clutter_maker.used = maker.used
    for planner in planners:
        own, planner.rng = planner.rng, clutter_rng
        _clutter_room(planner, clutter_maker, clutter_rng)
        planner.rng = own
    return unlikely


def _clutter_room(planner: RoomPlanner, maker: SpecMaker, rng: np.random.Generator) -> None:
    extras = EXTRA_FURNITURE.get(planner.room.type, ())
    if extras and rng.random() < EXTRA_RATE:
        spec = maker.make(_pick(rng, extras))
        if spec.flat:
            planner.anywhere(spec)
        else:
            planner.against_wall(spec) or planner.corner(spec)
    if rng.random() < FLOOR_RATE:
        spec = maker.make(_pick(rng, FLOOR_CLUTTER))
        planner.corner(spec) or planner.against_wall(spec)
    loaded = {id(p.support) for p in planner.placed if p.support is not None}
    for p in list(planner.placed):
        if p.support is not None:
            continue
        if p.spec.category in SURFACES and id(p) not in loaded and rng.random() < SURFACE_RATE:
            planner.on_top(maker.make(_pick(rng, SMALL_ON_SURFACES)), p, jitter=0.6)
        elif p.spec.category in SOFT and rng.random() < PILLOW_RATE:
            planner.on_top(maker.make("pillow"), p, jitter=0.6)
