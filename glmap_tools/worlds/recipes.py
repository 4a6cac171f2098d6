"""How each room type is furnished: which objects, by which placement rule, in which region.

A recipe fills a `RoomPlanner` and returns its regions as (name, purpose, members). Optional
objects are skipped when they do not fit or by chance (`p`), so apartments differ.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from glmap_tools.worlds.placement import SIDES, ObjectSpec, Placed, RoomPlanner
from glmap_tools.worlds.specs import SpecMaker

RegionPlan = tuple[str, str, list[Placed]]
Recipe = Callable[[RoomPlanner, SpecMaker], list[RegionPlan]]


def _chance(planner: RoomPlanner, p: float) -> bool:
    return bool(planner.rng.random() < p)


def _keep(*items: Placed | None) -> list[Placed]:
    return [p for p in items if p is not None]


def _long_sides(planner: RoomPlanner) -> tuple[str, ...]:
    w, h = planner.hi - planner.lo
    return ("south", "north") if w >= h else ("west", "east")


def _decorate(planner: RoomPlanner, maker: SpecMaker, plant: float, picture: float) -> None:
    if _chance(planner, plant):
        planner.corner(maker.make("plant"))
    if _chance(planner, picture):
        planner.on_wall(maker.make("picture"), z=float(planner.rng.uniform(1.25, 1.5)))


def dining_set(
    planner: RoomPlanner, maker: SpecMaker, at: np.ndarray | None = None, big: bool = True
) -> list[RegionPlan]:
    """A table with chairs around it, near `at` (default: the room centre)."""
    kind = "dining table" if big and _chance(planner, 0.65) else "round table"
    spec = maker.make(kind)
    center = planner.center if at is None else at
    w, h = planner.hi - planner.lo
    heading = math.pi / 2 if w >= h else 0.0
    table = None
    for _ in range(12):
        jitter = planner.rng.uniform(-0.3, 0.3, size=2)
        cand = Placed(spec, np.array([*(center + jitter), 0.0]), heading, planner.room.id)
        if planner.fits(cand, margin=0.7):
            table = planner.add(cand)
            break
    if table is None:
        return []
    chair = maker.make("chair")
    count = 6 if kind == "dining table" and spec.size[0] > 1.6 else 4
    if not big:
        count = 2
    chairs = planner.around(chair, table, count)
    members = [table, *chairs]
    if _chance(planner, 0.5):
        members += _keep(planner.on_top(maker.make("small plant"), table, jitter=0.2))
    name = "dining area" if big else "breakfast nook"
    purpose = "for eating meals" if big else "for quick meals and coffee"
    return [(name, purpose, members)]


def living_room(planner: RoomPlanner, maker: SpecMaker) -> list[RegionPlan]:
    sofa_spec, stand_spec = maker.make("sofa"), maker.make("tv stand")
    sofa, stand = None, None
    for attempt in range(8):  # a sofa with a TV stand across the room, facing each other
        sides = _long_sides(planner) if attempt < 4 else ("south", "east", "north", "west")
        sofa = planner.against_wall(sofa_spec, sides)
        if sofa is None:
            continue
        stand = planner.facing(stand_spec, sofa)
        if stand is not None:
            break
        planner.remove(sofa)
        sofa = None
    if sofa is None:
        sofa = planner.against_wall(sofa_spec)
    seating = _keep(sofa)
    if sofa is not None:
        stand = stand or planner.against_wall(stand_spec)
        tv_kind = "flat tv" if _chance(planner, 0.75) else "vintage tv"
        tv = planner.on_top(maker.make(tv_kind), stand, jitter=0.0) if stand else None
        table = planner.in_front_of(maker.make("coffee table"), sofa, 0.4, turn=0.0)
        seating += _keep(stand, tv, table)
        if table is not None and _chance(planner, 0.6):
            rug = maker.make("rug")
            seating += _keep(planner.add(Placed(rug, table.position.copy(), 0.0, planner.room.id)))
        if table is not None and _chance(planner, 0.5):
            seating += _keep(planner.on_top(maker.make("books"), table))
        if _chance(planner, 0.6):
            side = planner.beside(maker.make("side table"), sofa, int(planner.rng.choice([-1, 1])))
            seating += _keep(side)
            if side is not None and _chance(planner, 0.8):
                seating += _keep(planner.on_top(maker.make("table lamp"), side, jitter=0.2))
        if table is not None and _chance(planner, 0.6):
            arm = maker.make("armchair")
            for sign in (1, -1):
                left = np.array([-sofa.front[1], sofa.front[0]]) * sign
                xy = table.position[:2] + left * (table.spec.size[0] / 2 + 0.35 + arm.size[1] / 2)
                heading = math.atan2(-left[1], -left[0])
                cand = Placed(arm, np.array([*xy, 0.0]), heading, planner.room.id)
                if planner.fits(cand):
                    seating += _keep(planner.add(cand))
                    break
    regions = [("seating area", "for relaxing and watching TV", seating)] if seating else []
    if _chance(planner, 0.6):
        planner.corner(maker.make("floor lamp"))
    if _chance(planner, 0.6):
        planner.against_wall(maker.make("bookcase"))
    _decorate(planner, maker, plant=0.9, picture=0.8)
    if planner.room.area > 24 and _chance(planner, 0.5):
        regions += dining_set(planner, maker, big=False)
    return regions


def _counter_run(
    planner: RoomPlanner, side: str, specs: list[ObjectSpec]
) -> tuple[list[Placed], list[ObjectSpec]]:
    """Place specs side by side along one wall; returns (placed, what did not fit)."""
    axis = 0 if side in ("south", "north") else 1
    lo, hi = planner.lo[axis], planner.hi[axis]
    placed_run: list[Placed] = []
    cursor, pending = lo + 0.02, list(specs)
    while pending and cursor + pending[0].size[0] <= hi:
        spec = pending[0]
        placed = planner.against_wall(spec, (side,), at=cursor + spec.size[0] / 2, margin=0.0)
        if placed is None:
            cursor += 0.1
            continue
        placed_run.append(placed)
        pending.pop(0)
        cursor += spec.size[0] + 0.005
    return placed_run, pending


def kitchen(planner: RoomPlanner, maker: SpecMaker) -> list[RegionPlan]:
    cab_color = maker.pick("kitchen cabinet", "color", ["white", "grey", "navy", "green", "beige"])
    specs = [
        maker.make(kind, **({} if kind in ("fridge", "stove") else {"color": cab_color}))
        for kind in ("fridge", "kitchen cabinet", "kitchen sink", "kitchen cabinet", "stove")
    ]
    longest = float(max(planner.hi - planner.lo))
    while sum(sp.size[0] for sp in specs) < longest - 1.2 and len(specs) < 9:
        specs.append(maker.make("kitchen cabinet", color=cab_color))
    if _chance(planner, 0.5):
        specs = specs[::-1]
    sides = list(_long_sides(planner)) + [s for s in SIDES if s not in _long_sides(planner)]
    best_side, best_score = sides[0], -1
    for side in sides:  # the wall where the most appliances fit
        trial, _ = _counter_run(planner, side, specs)
        score = sum(1 + 2 * (p.spec.category != "kitchen cabinet") for p in trial)
        for p in trial:
            planner.remove(p)
        if score > best_score:
            best_side, best_score = side, score
    cooking, pending = _counter_run(planner, best_side, specs)
    for spec in pending:  # what did not fit the run goes against another wall
        if spec.category != "kitchen cabinet":
            cooking += _keep(planner.against_wall(spec))
    counters = [p for p in cooking if p.spec.category == "kitchen cabinet"]
    planner.rng.shuffle(counters)
    for kind, counter in zip(("coffee machine", "toaster"), counters, strict=False):
        if _chance(planner, 0.8):
            cooking += _keep(planner.on_top(maker.make(kind), counter, jitter=0.3))
    regions = [("cooking area", "for preparing food", cooking)] if cooking else []
    if planner.room.area > 10 and _chance(planner, 0.7):
        regions += dining_set(planner, maker, big=False)
    planner.corner(maker.make("trash can"))
    _decorate(planner, maker, plant=0.4, picture=0.5)
    return regions


def bedroom(planner: RoomPlanner, maker: SpecMaker) -> list[RegionPlan]:
    kind = "double bed" if planner.room.area > 11.5 else "single bed"
    bed = planner.against_wall(maker.make(kind))
    sleeping = _keep(bed)
    if bed is not None:
        lamp_color = maker.pick("table lamp", "color", ["white", "beige", "yellow", "grey"])
        stand_spec = maker.make("nightstand")
        for sign in (1, -1):
            if _chance(planner, 0.85):
                stand = planner.beside(maker.same_as(stand_spec), bed, sign)
                sleeping += _keep(stand)
                if stand is not None and _chance(planner, 0.8):
                    lamp = maker.make("table lamp", color=lamp_color)
                    sleeping += _keep(planner.on_top(lamp, stand, jitter=0.1))
        if _chance(planner, 0.4):
            sleeping += _keep(planner.in_front_of(maker.make("rug"), bed, -0.3, turn=0.0))
    regions = [("sleeping area", "for sleeping and resting", sleeping)] if sleeping else []
    storage = _keep(planner.against_wall(maker.make("wardrobe")))
    if _chance(planner, 0.5):
        dresser = planner.against_wall(maker.make("dresser"))
        storage += _keep(dresser)
        if dresser is not None and _chance(planner, 0.6):
            storage += _keep(planner.on_top(maker.make("small plant"), dresser))
    if len(storage) > 1:
        regions.append(("storage area", "for keeping clothes", storage))
    if _chance(planner, 0.4):
        planner.corner(maker.make("chair"))
    _decorate(planner, maker, plant=0.6, picture=0.7)
    return regions


def bathroom(planner: RoomPlanner, maker: SpecMaker) -> list[RegionPlan]:
    washing = _keep(planner.against_wall(maker.make("toilet")))
    washing += _keep(planner.against_wall(maker.make("bathroom sink")))
    if planner.room.area > 5.0:
        washing += _keep(planner.against_wall(maker.make("bathtub")))
    if _chance(planner, 0.5):
        planner.against_wall(maker.make("washing machine"))
    planner.corner(maker.make("trash can"))
    _decorate(planner, maker, plant=0.3, picture=0.3)
    return [("washing area", "for personal hygiene", washing)] if washing else []


def office(planner: RoomPlanner, maker: SpecMaker) -> list[RegionPlan]:
    desk = planner.against_wall(maker.make("desk"))
    work = _keep(desk)
    if desk is not None:
        work += _keep(planner.in_front_of(maker.make("office chair"), desk, -0.15))
        work += _keep(planner.on_top(maker.make("monitor"), desk, jitter=0.2))
        if _chance(planner, 0.7):
            work += _keep(planner.on_top(maker.make("table lamp"), desk, jitter=0.9))
    regions = [("work area", "for working at the computer", work)] if work else []
    shelves = _keep(planner.against_wall(maker.make("bookcase")))
    if _chance(planner, 0.6):
        shelves += _keep(planner.against_wall(maker.make("cabinet")))
    if _chance(planner, 0.5):
        planner.corner(maker.make("box"))
    if len(shelves) > 1:
        regions.append(("storage area", "for keeping books and files", shelves))
    planner.corner(maker.make("trash can"))
    _decorate(planner, maker, plant=0.7, picture=0.6)
    return regions


def dining_room(planner: RoomPlanner, maker: SpecMaker) -> list[RegionPlan]:
    regions = dining_set(planner, maker, big=True)
    if _chance(planner, 0.7):
        sideboard = planner.against_wall(maker.make("dresser"))
        if sideboard is not None and _chance(planner, 0.7):
            planner.on_top(maker.make("table lamp"), sideboard)
    if _chance(planner, 0.5):
        planner.corner(maker.make("floor lamp"))
    _decorate(planner, maker, plant=0.8, picture=0.8)
    return regions


def hallway(planner: RoomPlanner, maker: SpecMaker) -> list[RegionPlan]:
    """A corridor: kept clear for walking, with a few things along its walls."""
    for _ in range(2):
        if _chance(planner, 0.7):
            planner.on_wall(maker.make("picture"), z=float(planner.rng.uniform(1.3, 1.5)))
    if _chance(planner, 0.6):
        planner.corner(maker.make("plant"))
    if _chance(planner, 0.4):
        planner.corner(maker.make("trash can"))
    return []


def laundry_room(planner: RoomPlanner, maker: SpecMaker) -> list[RegionPlan]:
    """Houses: a washing machine (and often a dryer) with a basket and a cabinet."""
    washer = planner.against_wall(maker.make("washing machine"))
    laundry = _keep(washer)
    if washer is not None and _chance(planner, 0.7):
        laundry += _keep(
            planner.beside(maker.make("dryer"), washer, int(planner.rng.choice([-1, 1])))
        )
    laundry += _keep(planner.corner(maker.make("laundry basket")))
    if _chance(planner, 0.6):
        planner.against_wall(maker.make("cabinet"))
    if _chance(planner, 0.5):
        planner.corner(maker.make("trash can"))
    return [("laundry area", "for washing and drying clothes", laundry)] if laundry else []


RECIPES: dict[str, Recipe] = {
    "living room": living_room,
    "kitchen": kitchen,
    "bedroom": bedroom,
    "bathroom": bathroom,
    "office": office,
    "dining room": dining_room,
    "hallway": hallway,
    "laundry room": laundry_room,
}

DECOR = ["small plant", "picture", "trash can", "box", "plant"]


def add_decor(planner: RoomPlanner, maker: SpecMaker) -> Placed | None:
    """One extra decorative object somewhere in the room (to reach the object minimum)."""
    kind = DECOR[int(planner.rng.integers(len(DECOR)))]
    if kind == "picture":
        return planner.on_wall(maker.make(kind), z=float(planner.rng.uniform(1.25, 1.5)))
    tables = [p for p in planner.placed if p.spec.category in ("table", "desk", "dresser")]
    if kind == "small plant" and tables:
        return planner.on_top(maker.make(kind), tables[int(planner.rng.integers(len(tables)))])
    return planner.corner(maker.make(kind)) or planner.against_wall(maker.make(kind))
