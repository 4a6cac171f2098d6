"""The mesh catalog: Kenney furniture (CC0) rescaled to real sizes, plus trimesh primitives.

Every mesh lives in a unit local frame once loaded (see `meshes.py`): footprint centred on the
origin, x = width, y = depth, z = up from 0, the front facing local -y. A layout object gives
its real size in metres and the mesh is stretched to it; `default_size` is the real size used
when a layout leaves it out (the table of real sizes the Kenney models are rescaled to).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from glmap_tools.errors import InvalidInputError, did_you_mean

KENNEY_PREFIX = "kenney/"
PRIMITIVE_PREFIX = "primitive/"


@dataclass(frozen=True)
class MeshSpec:
    """One renderable mesh.

    Attributes:
        name: "kenney/<model>" or "primitive/<shape>".
        default_size: real (width, depth, height) in metres.
        tint: material (Kenney) or part (primitive) names painted in the object's colour.
    """

    name: str
    default_size: tuple[float, float, float]
    tint: tuple[str, ...]

    @property
    def is_kenney(self) -> bool:
        return self.name.startswith(KENNEY_PREFIX)

    @property
    def model(self) -> str:
        """The file stem (Kenney) or shape name (primitive)."""
        return self.name.split("/", 1)[1]


def _k(model: str, size: tuple[float, float, float], *tint: str) -> MeshSpec:
    return MeshSpec(KENNEY_PREFIX + model, size, tuple(tint))


def _p(shape: str, size: tuple[float, float, float]) -> MeshSpec:
    return MeshSpec(PRIMITIVE_PREFIX + shape, size, ("main",))


_SPECS = [
    # Kenney Furniture Kit 2.0: the real sizes each model is rescaled to.
    _k("loungeSofa", (2.0, 0.9, 0.85), "carpet"),
    _k("chairCushion", (0.45, 0.5, 0.9), "carpet"),
    _k("chairDesk", (0.62, 0.62, 1.05), "carpet"),
    _k("bedSingle", (1.0, 2.05, 0.65), "carpet"),
    _k("bookcaseOpen", (0.8, 0.35, 1.8), "wood"),
    _k("bookcaseClosed", (1.0, 0.5, 1.9), "wood"),
    _k("cabinetTelevision", (1.6, 0.45, 0.5), "wood"),
    _k("desk", (1.3, 0.65, 0.75), "wood"),
    _k("sideTable", (0.5, 0.45, 0.55), "wood"),
    _k("tableCoffee", (1.1, 0.6, 0.42), "wood"),
    _k("tableRound", (1.1, 1.1, 0.75), "wood"),
    _k("kitchenCabinet", (0.6, 0.6, 0.9), "wood"),
    _k("kitchenSink", (0.8, 0.6, 0.9), "wood"),
    _k("kitchenFridgeSmall", (0.7, 0.7, 1.8), "metalLight"),
    _k("kitchenCoffeeMachine", (0.25, 0.3, 0.35), "metalMedium"),
    _k("toaster", (0.3, 0.2, 0.2), "metal"),
    _k("televisionVintage", (0.8, 0.45, 0.6), "wood"),
    _k("lampRoundFloor", (0.4, 0.4, 1.6), "lamp"),
    _k("lampRoundTable", (0.3, 0.3, 0.5), "lamp"),
    _k("pottedPlant", (0.5, 0.5, 1.2), "wood"),
    _k("plantSmall2", (0.25, 0.25, 0.35), "wood"),
    _k("rugRound", (2.0, 2.0, 0.02), "carpet"),
    _k("rugDoormat", (0.8, 0.5, 0.02), "wood"),
    _k("trashcan", (0.35, 0.35, 0.6), "metal"),
    _k("cardboardBoxOpen", (0.5, 0.4, 0.35)),
    _k("books", (0.25, 0.18, 0.22), "carpetDarker"),
    _k("pillowBlue", (0.5, 0.15, 0.4), "carpetBlue"),
    # Primitives built from trimesh boxes and cylinders (see primitives.py).
    _p("box", (1.0, 1.0, 1.0)),
    _p("cylinder", (1.0, 1.0, 1.0)),
    _p("sphere", (1.0, 1.0, 1.0)),
    _p("table", (1.6, 0.9, 0.75)),
    _p("toilet", (0.4, 0.65, 0.8)),
    _p("bathtub", (0.8, 1.7, 0.55)),
    _p("stove", (0.6, 0.6, 0.9)),
    _p("tv", (1.2, 0.25, 0.75)),
    _p("picture", (0.8, 0.04, 0.6)),
    _p("wardrobe", (1.2, 0.6, 2.0)),
    _p("washer", (0.6, 0.6, 0.85)),
    _p("dresser", (1.0, 0.5, 0.8)),
    _p("shelf", (1.0, 0.3, 0.04)),
]

MESHES: dict[str, MeshSpec] = {spec.name: spec for spec in _SPECS}

# Mesh used for a scanned object of this category (synonyms included); others become boxes.
CATEGORY_MESH: dict[str, str] = {
    "sofa": "kenney/loungeSofa",
    "couch": "kenney/loungeSofa",
    "armchair": "kenney/loungeSofa",
    "chair": "kenney/chairCushion",
    "dining chair": "kenney/chairCushion",
    "office chair": "kenney/chairDesk",
    "desk chair": "kenney/chairDesk",
    "bed": "kenney/bedSingle",
    "bookcase": "kenney/bookcaseOpen",
    "bookshelf": "kenney/bookcaseOpen",
    "shelves": "kenney/bookcaseOpen",
    "tv stand": "kenney/cabinetTelevision",
    "desk": "kenney/desk",
    "nightstand": "kenney/sideTable",
    "side table": "kenney/sideTable",
    "end table": "kenney/sideTable",
    "coffee table": "kenney/tableCoffee",
    "round table": "kenney/tableRound",
    "table": "primitive/table",
    "dining table": "primitive/table",
    "kitchen cabinet": "kenney/kitchenCabinet",
    "cabinet": "kenney/kitchenCabinet",
    "counter": "kenney/kitchenCabinet",
    "sink": "kenney/kitchenSink",
    "refrigerator": "kenney/kitchenFridgeSmall",
    "fridge": "kenney/kitchenFridgeSmall",
    "coffee maker": "kenney/kitchenCoffeeMachine",
    "coffee machine": "kenney/kitchenCoffeeMachine",
    "toaster": "kenney/toaster",
    "tv": "primitive/tv",
    "television": "primitive/tv",
    "monitor": "primitive/tv",
    "lamp": "kenney/lampRoundTable",
    "floor lamp": "kenney/lampRoundFloor",
    "table lamp": "kenney/lampRoundTable",
    "plant": "kenney/pottedPlant",
    "potted plant": "kenney/pottedPlant",
    "rug": "kenney/rugRound",
    "carpet": "kenney/rugRound",
    "doormat": "kenney/rugDoormat",
    "trash can": "kenney/trashcan",
    "trashcan": "kenney/trashcan",
    "box": "kenney/cardboardBoxOpen",
    "books": "kenney/books",
    "pillow": "kenney/pillowBlue",
    "toilet": "primitive/toilet",
    "bathtub": "primitive/bathtub",
    "stove": "primitive/stove",
    "oven": "primitive/stove",
    "picture": "primitive/picture",
    "wardrobe": "primitive/wardrobe",
    "closet": "primitive/wardrobe",
    "washing machine": "primitive/washer",
    "dresser": "primitive/dresser",
    # Houses' clutter (generator categories drawn with primitives).
    "vase": "primitive/cylinder",
    "bowl": "primitive/cylinder",
    "laundry basket": "primitive/cylinder",
    "dryer": "primitive/washer",
}


def mesh_spec(name: str, where: str = "mesh") -> MeshSpec:
    """Look up a mesh by name; an unknown name raises with the closest known one."""
    spec = MESHES.get(name)
    if spec is None:
        raise InvalidInputError(
            f"{where} {name!r} is not a known mesh.{did_you_mean(name, MESHES)} Known meshes: "
            f"'kenney/<model>' ({', '.join(s.model for s in _SPECS if s.is_kenney)}) or "
            f"'primitive/<shape>' ({', '.join(s.model for s in _SPECS if not s.is_kenney)})."
        )
    return spec


# Scan labels that name a category above in other words; `resolve_category` also tries the
# label with "-"/"_" as spaces, without a plural "s", and its last word (the head noun:
# "area rug" -> rug). Documented in sim/design.md.
CATEGORY_ALIASES: dict[str, str] = {
    "book": "books",
    "indoor plant": "plant",
    "house plant": "plant",
    "houseplant": "plant",
    "plant pot": "plant",
    "flower pot": "plant",
    "bin": "trash can",
    "trash bin": "trash can",
    "garbage bin": "trash can",
    "garbage can": "trash can",
    "waste bin": "trash can",
    "wastebasket": "trash can",
    "recycling bin": "trash can",
    "tv screen": "tv",
    "tv monitor": "tv",
    "screen": "tv",
    "computer monitor": "monitor",
    "display": "monitor",
    "sofa chair": "armchair",
    "couch chair": "armchair",
    "stool": "chair",
    "chair desk": "office chair",
    "night stand": "nightstand",
    "bedside table": "nightstand",
    "bedside cabinet": "nightstand",
    "tv cabinet": "tv stand",
    "tv table": "tv stand",
    "media console": "tv stand",
    "shelf": "shelves",
    "cupboard": "cabinet",
    "kitchen counter": "counter",
    "countertop": "counter",
    "chest of drawers": "dresser",
    "drawers": "dresser",
    "bath": "bathtub",
    "tub": "bathtub",
    "washer": "washing machine",
    "fridge freezer": "refrigerator",
    "painting": "picture",
    "poster": "picture",
    "picture frame": "picture",
    "desk lamp": "table lamp",
    "standing lamp": "floor lamp",
    "mat": "doormat",
    "bath mat": "doormat",
    "floor mat": "doormat",
    "cushion": "pillow",
    "throw pillow": "pillow",
}


def _normalise(label: str) -> str:
    return " ".join(label.strip().lower().replace("-", " ").replace("_", " ").split())


def resolve_category(category: str, aliases: Mapping[str, str] | None = None) -> str | None:
    """The catalog category (a key of `CATEGORY_MESH`) a scan label means, or None.

    Tries the label, then its last word (the head noun: "area rug" -> rug), each as it is and
    without a plural "es"/"s", in the caller's `aliases` (from `load_aliases`), then in
    `CATEGORY_MESH` and then in `CATEGORY_ALIASES`.
    """
    name = _normalise(category)
    words = name.split()
    mine = {_normalise(k): v for k, v in (aliases or {}).items()}
    for label in (name, words[-1] if len(words) > 1 else ""):
        singulars = [label] + [label[: -len(end)] for end in ("es", "s") if label.endswith(end)]
        for candidate in singulars if label else []:
            if candidate in mine:
                return mine[candidate]
            if candidate in CATEGORY_MESH:
                return candidate
            if candidate in CATEGORY_ALIASES:
                return CATEGORY_ALIASES[candidate]
    return None


def mesh_for_category(category: str, aliases: Mapping[str, str] | None = None) -> str:
    """The mesh a scanned object of `category` is drawn with (a box when none fits)."""
    resolved = resolve_category(category, aliases)
    return CATEGORY_MESH[resolved] if resolved is not None else "primitive/box"


def check_aliases(aliases: object, where: str = "aliases") -> dict[str, str]:
    """A user's alias table {scan label: catalog category}, checked.

    Raises:
        InvalidInputError: not a JSON object of strings, or a target the catalog does not
            have (the message names it and the closest categories).
    """
    if not isinstance(aliases, Mapping) or not all(
        isinstance(k, str) and isinstance(v, str) for k, v in aliases.items()
    ):
        raise InvalidInputError(
            f"{where} must be a JSON object of scan label -> catalog category, e.g. "
            '{"plant-stand": "side table", "candle": "table lamp"}.'
        )
    out = {}
    for label, target in aliases.items():
        resolved = resolve_category(target)
        if resolved is None:
            raise InvalidInputError(
                f"{where}: {label!r} -> {target!r}, which the catalog does not know."
                f"{did_you_mean(_normalise(target), list(CATEGORY_MESH))} The categories are: "
                f"{', '.join(sorted(CATEGORY_MESH))}."
            )
        out[label] = resolved
    return out
