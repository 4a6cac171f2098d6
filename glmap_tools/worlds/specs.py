"""Kinds of furniture the generator places: category, mesh, real size and attribute choices.

`SpecMaker.make(kind)` draws sizes and attributes from a seeded generator, preferring values
not yet used for the same category in the apartment, so instances differ.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from glmap_tools.worlds.placement import ObjectSpec

WOODS = ["wood", "oak", "walnut"]
FABRIC_COLORS = ["grey", "blue", "beige", "green", "red", "brown", "navy", "teal", "purple"]
CUSHION_COLORS = ["red", "blue", "green", "yellow", "grey", "black", "white", "orange", "teal"]
APPLIANCE_COLORS = ["white", "grey", "black"]
POT_COLORS = ["white", "grey", "brown", "blue", "orange", "black"]
SHADE_COLORS = ["white", "beige", "yellow", "grey", "blue", "green"]
ART_COLORS = ["blue", "orange", "green", "red", "yellow", "purple", "teal", "pink"]
CABINET_COLORS = ["white", "grey", "navy", "green", "beige"]


@dataclass(frozen=True)
class Kind:
    """A kind of object: its category, mesh, size range and attribute options."""

    category: str
    mesh: str
    size: tuple[float, float, float]
    jitter: float = 0.05  # relative size variation
    options: dict[str, list[str]] = field(default_factory=dict)
    fixed: dict[str, str] = field(default_factory=dict)
    flat: bool = False


KINDS: dict[str, Kind] = {
    "sofa": Kind(
        "sofa", "kenney/loungeSofa", (2.0, 0.9, 0.85), 0.08,
        {"color": FABRIC_COLORS, "material": ["fabric", "leather", "velvet"]},
    ),
    "armchair": Kind(
        "armchair", "kenney/loungeSofa", (0.95, 0.85, 0.85), 0.04,
        {"color": FABRIC_COLORS, "material": ["fabric", "leather", "velvet"]},
    ),
    "coffee table": Kind(
        "coffee table", "kenney/tableCoffee", (1.1, 0.6, 0.42), 0.06, {"material": WOODS}
    ),
    "tv stand": Kind(
        "tv stand", "kenney/cabinetTelevision", (1.6, 0.45, 0.5), 0.06, {"material": WOODS}
    ),
    "flat tv": Kind(
        "tv", "primitive/tv", (1.2, 0.25, 0.75), 0.12, {"color": ["black", "grey", "white"]},
        {"style": "flat-screen"},
    ),
    "vintage tv": Kind(
        "tv", "kenney/televisionVintage", (0.7, 0.45, 0.55), 0.05, {"material": WOODS},
        {"style": "vintage"},
    ),
    "rug": Kind(
        "rug", "kenney/rugRound", (2.0, 2.0, 0.02), 0.1, {"color": FABRIC_COLORS},
        {"shape": "round"}, flat=True,
    ),
    "floor lamp": Kind("floor lamp", "kenney/lampRoundFloor", (0.4, 0.4, 1.6), 0.05,
                       {"color": SHADE_COLORS}),
    "table lamp": Kind("table lamp", "kenney/lampRoundTable", (0.3, 0.3, 0.5), 0.08,
                       {"color": SHADE_COLORS}),
    "plant": Kind("plant", "kenney/pottedPlant", (0.5, 0.5, 1.2), 0.15, {"color": POT_COLORS},
                  {"size": "large"}),
    "small plant": Kind("plant", "kenney/plantSmall2", (0.25, 0.25, 0.35), 0.1,
                        {"color": POT_COLORS}, {"size": "small"}),
    "bookcase": Kind("bookcase", "kenney/bookcaseOpen", (0.8, 0.35, 1.8), 0.1,
                     {"material": WOODS}),
    "cabinet": Kind("cabinet", "kenney/bookcaseClosed", (1.0, 0.5, 1.9), 0.08,
                    {"color": CABINET_COLORS}),
    "side table": Kind("side table", "kenney/sideTable", (0.5, 0.45, 0.55), 0.05,
                       {"material": WOODS}),
    "nightstand": Kind("nightstand", "kenney/sideTable", (0.45, 0.4, 0.55), 0.05,
                       {"color": ["white", "grey", "brown", "black"]}),
    "picture": Kind("picture", "primitive/picture", (0.8, 0.04, 0.6), 0.25,
                    {"color": ART_COLORS}),
    "dining table": Kind(
        "table", "primitive/table", (1.6, 0.9, 0.75), 0.1,
        {"material": WOODS + ["marble"], "color": ["white", "black", "brown"]},
        {"shape": "rectangular"},
    ),
    "round table": Kind("table", "kenney/tableRound", (1.1, 1.1, 0.75), 0.08,
                        {"material": WOODS}, {"shape": "round"}),
    "chair": Kind("chair", "kenney/chairCushion", (0.45, 0.5, 0.9), 0.04,
                  {"color": CUSHION_COLORS, "material": WOODS + ["metal"]}),
    "office chair": Kind("office chair", "kenney/chairDesk", (0.62, 0.62, 1.05), 0.04,
                         {"color": CUSHION_COLORS}),
    "desk": Kind("desk", "kenney/desk", (1.3, 0.65, 0.75), 0.08, {"material": WOODS}),
    "monitor": Kind("monitor", "primitive/tv", (0.55, 0.2, 0.42), 0.08,
                    {"color": ["black", "grey", "white"]}),
    "double bed": Kind("bed", "kenney/bedSingle", (1.6, 2.1, 0.6), 0.05,
                       {"color": FABRIC_COLORS}, {"size": "double"}),
    "single bed": Kind("bed", "kenney/bedSingle", (1.0, 2.05, 0.6), 0.04,
                       {"color": FABRIC_COLORS}, {"size": "single"}),
    "wardrobe": Kind("wardrobe", "primitive/wardrobe", (1.2, 0.6, 2.0), 0.1,
                     {"color": ["white", "brown", "grey", "beige"]}),
    "dresser": Kind("dresser", "primitive/dresser", (1.0, 0.5, 0.8), 0.1,
                    {"color": ["white", "brown", "grey", "navy"]}),
    "kitchen cabinet": Kind("kitchen cabinet", "kenney/kitchenCabinet", (0.6, 0.6, 0.9), 0.0,
                            {"color": CABINET_COLORS}),
    "kitchen sink": Kind("sink", "kenney/kitchenSink", (0.8, 0.6, 0.9), 0.0,
                         {"color": CABINET_COLORS}, {"style": "kitchen"}),
    "bathroom sink": Kind("sink", "kenney/kitchenSink", (0.6, 0.45, 0.85), 0.05,
                          {"color": ["white", "grey", "beige"]}, {"style": "bathroom"}),
    "fridge": Kind("refrigerator", "kenney/kitchenFridgeSmall", (0.7, 0.7, 1.8), 0.05,
                   {"color": APPLIANCE_COLORS}),
    "stove": Kind("stove", "primitive/stove", (0.6, 0.6, 0.9), 0.0, {"color": APPLIANCE_COLORS}),
    "coffee machine": Kind("coffee machine", "kenney/kitchenCoffeeMachine", (0.25, 0.3, 0.35),
                           0.05, {"color": ["black", "grey", "red"]}),
    "toaster": Kind("toaster", "kenney/toaster", (0.3, 0.2, 0.2), 0.05,
                    {"color": ["red", "grey", "white", "black"]}),
    "trash can": Kind("trash can", "kenney/trashcan", (0.35, 0.35, 0.6), 0.1,
                      {"color": ["grey", "black", "white", "blue", "green"]}),
    "washing machine": Kind("washing machine", "primitive/washer", (0.6, 0.6, 0.85), 0.0,
                            {"color": ["white", "grey"]}),
    "toilet": Kind("toilet", "primitive/toilet", (0.4, 0.65, 0.8), 0.03, {"color": ["white"]},
                   {"material": "ceramic"}),
    "bathtub": Kind("bathtub", "primitive/bathtub", (1.7, 0.75, 0.55), 0.04,
                    {"color": ["white", "beige"]}),
    "box": Kind("box", "kenney/cardboardBoxOpen", (0.5, 0.4, 0.35), 0.15, {},
                {"material": "cardboard"}),
    "books": Kind("books", "kenney/books", (0.25, 0.18, 0.22), 0.1, {"color": ART_COLORS}),
    # Houses: clutter and the laundry room.
    "vase": Kind("vase", "primitive/cylinder", (0.16, 0.16, 0.3), 0.2, {"color": POT_COLORS}),
    "bowl": Kind("bowl", "primitive/cylinder", (0.25, 0.25, 0.08), 0.15,
                 {"color": ["white", "blue", "red", "green", "black"]}),
    "pillow": Kind("pillow", "kenney/pillowBlue", (0.5, 0.15, 0.4), 0.1,
                   {"color": CUSHION_COLORS}),
    "laundry basket": Kind("laundry basket", "primitive/cylinder", (0.45, 0.45, 0.5), 0.1,
                           {"color": ["white", "grey", "blue", "brown"]}),
    "dryer": Kind("dryer", "primitive/washer", (0.6, 0.6, 0.85), 0.0, {"color": ["white", "grey"]}),
    "doormat": Kind("doormat", "kenney/rugDoormat", (0.8, 0.5, 0.02), 0.1,
                    {"color": ["brown", "grey", "black"]}, flat=True),
}  # fmt: skip


class SpecMaker:
    """Draws object specs with sizes and attributes that vary across instances."""

    def __init__(self, rng: np.random.Generator) -> None:
        self.rng = rng
        self.used: dict[tuple[str, str], set[str]] = {}

    def pick(self, category: str, key: str, options: list[str]) -> str:
        """A value for attribute `key`, preferring ones unused for this category."""
        used = self.used.setdefault((category, key), set())
        fresh = [o for o in options if o not in used] or list(options)
        value = str(fresh[int(self.rng.integers(len(fresh)))])
        used.add(value)
        return value

    def make(self, kind: str, **attributes: str) -> ObjectSpec:
        """A spec of `kind`; `attributes` fix chosen attribute values (e.g. a matching set)."""
        k = KINDS[kind]
        scale = 1.0 + k.jitter * self.rng.uniform(-1.0, 1.0, size=3)
        scale[2] = 1.0 + (scale[2] - 1.0) * 0.5
        size = tuple(float(round(s, 3)) for s in np.asarray(k.size) * scale)
        attrs = dict(k.fixed)
        for key, options in k.options.items():
            attrs[key] = attributes.get(key) or self.pick(k.category, key, options)
        attrs.update({key: v for key, v in attributes.items() if v})
        return ObjectSpec(k.category, k.mesh, (size[0], size[1], size[2]), attrs, k.flat)

    def same_as(self, spec: ObjectSpec) -> ObjectSpec:
        """An identical spec (a matching chair of a set)."""
        return ObjectSpec(spec.category, spec.mesh, spec.size, dict(spec.attributes), spec.flat)
