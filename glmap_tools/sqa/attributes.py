"""Attributes read from a unit's description: colour, shape, material, size, state, parts.

The map knows what its descriptions say. "Is the rug round?" is yes when the rug's
description says round (or circular), no when it names another shape, and otherwise
unsupported (supported=False, "cannot tell from the map"), never a guess. Either/or
questions ("is the table round or square?", "is the bed made or messy?") answer with the
option the description bears out, in the words the question offered ("circle" when it
asked "a circle or a rectangle?"). A word's kind (VOCABULARY) says what counts as
"another" value: a white chair is not black; a chair whose description names no colour
may be any.
"""

from __future__ import annotations

import re
from collections.abc import Sequence

from glmap_tools.sqa.records import COLOURS, MapAnswer
from glmap_tools.sqa.surroundings import Nearby

SHADES = ("light", "dark", "pale", "bright", "deep")
# Words of one meaning: the first is the canonical word.
SAME = (
    ("round", "circular", "circle", "round-shaped"),
    ("rectangular", "rectangle", "oblong"),
    ("square", "squared"),
    ("oval", "elliptical", "ellipse"),
    ("triangular", "triangle"),
    ("wooden", "wood", "oak", "walnut", "pine", "timber", "birch"),
    ("metal", "metallic", "steel", "iron", "aluminium", "aluminum", "chrome"),
    ("fabric", "cloth", "upholstered", "velvet", "linen"),
    ("closed", "shut"),
    ("open", "opened", "ajar"),
    ("on", "switched on", "turned on", "lit"),
    ("off", "switched off", "turned off", "unlit"),
    ("tidy", "neat", "clean", "made", "orderly"),
    ("messy", "cluttered", "untidy", "unmade", "dirty"),
    ("grey", "gray"),
    ("large", "big", "huge", "double"),
    ("small", "little", "tiny", "single"),
)
VOCABULARY: dict[str, tuple[str, ...]] = {
    "colour": tuple(COLOURS),
    "shape": ("round", "rectangular", "square", "oval", "triangular", "l-shaped"),
    "material": ("wooden", "metal", "fabric", "leather", "glass", "plastic", "marble", "ceramic"),
    "state": ("open", "closed", "on", "off"),
    "tidiness": ("tidy", "messy"),
    "size": ("large", "small"),
}


def canonical(word: str) -> str:
    """The canonical word of a synonym group ('circle' -> 'round'), else the word."""
    w = word.strip().lower()
    for group in SAME:
        if w in group:
            return group[0]
    return w


def kind_of(word: str) -> str | None:
    """colour / shape / material / state / tidiness / size of a word, or None."""
    c = canonical(word.split()[-1] if word.split() else word)
    return next((k for k, words in VOCABULARY.items() if c in words), None)


def described(text: str) -> set[str]:
    """The canonical attribute words a description says ('round teal rug' -> {round, teal})."""
    t = text.lower()
    words = set(re.findall(r"[a-z-]+", t)) - {"on", "off"}  # "a lamp on the desk": no state
    words |= set(re.findall(r"\b(?:switched|turned|is|are|left) (on|off)\b", t))
    words |= {p for group in SAME for p in group if " " in p and p in t}
    return {canonical(w) for w in words}


def colour_phrase(text: str) -> str | None:
    """The first colour of a description with its shade or pair: 'light brown', 'black
    and white', 'teal'; None when it names no colour."""
    names = "|".join(COLOURS)
    m = re.search(
        rf"\b(?:(?P<shade>{'|'.join(SHADES)})[ -])?(?P<c>{names})\b"
        rf"(?: and (?P<d>{names})\b)?",
        text.lower(),
    )
    if m is None:
        return None
    if m.group("d"):
        return f"{m.group('c')} and {m.group('d')}"
    return f"{m.group('shade')} {m.group('c')}" if m.group("shade") else m.group("c")


def _value_in(value: str, n: Nearby) -> bool | None:
    """True when the description says the value, False when it says another of its kind,
    None when it says nothing of that kind."""
    has = described(f"{n.label} {n.text}")
    v = re.sub(r"^(?:made of |of |a |an )+", "", value.lower()).strip()
    if " and " in v or v.split()[0] in SHADES:  # "black and white", "light brown"
        said = colour_phrase(n.text)
        return None if said is None else said == v
    c = canonical(v)
    if c in has:
        return True
    kind = kind_of(v)
    if kind is None:
        return None
    return False if any(w in has for w in VOCABULARY[kind]) else None


def attribute(
    parts: dict[str, str], unit: Nearby | None, asked: str, kind: str = "attribute"
) -> MapAnswer:
    """yes / no for "is the X <value>?" and "does the X have <part>?" from the description."""
    if unit is None:
        return MapAnswer("", kind, False, f"no {asked!r} nearby")
    if "part" in parts:
        part = parts["part"]
        stem = re.sub(r"(?:es|s)$", "", part.split()[-1])
        if re.search(rf"\b{re.escape(stem)}", unit.text.lower()):
            return MapAnswer("yes", kind, True, f"unit {unit.unit_id}: {unit.text[:60]!r}")
        return MapAnswer(
            "",
            kind,
            False,
            f"cannot tell from the map: unit {unit.unit_id}'s description names no {part}",
        )
    value = parts["value"]
    said = _value_in(value, unit)
    if said is None:
        return MapAnswer(
            "",
            kind,
            False,
            f"cannot tell from the map: unit {unit.unit_id}'s "
            f"description says nothing of {value!r}",
        )
    return MapAnswer(
        "yes" if said else "no", kind, True, f"unit {unit.unit_id}: {unit.text[:60]!r}"
    )


def either(kind: str, options: Sequence[str], unit: Nearby | None, asked: str) -> MapAnswer:
    """The offered option the description bears out, in the question's words."""
    if unit is None:
        return MapAnswer("", kind, False, f"cannot tell from the map: no {asked!r} among its units")
    said = [(o, _value_in(o, unit)) for o in options]
    yes = [o for o, s in said if s]
    if len(yes) == 1:
        word = re.sub(r"^(?:made of |of |a |an )", "", yes[0])
        return MapAnswer(word, kind, True, f"unit {unit.unit_id}: {unit.text[:60]!r}")
    return MapAnswer(
        "",
        kind,
        False,
        f"cannot tell from the map: unit {unit.unit_id}'s "
        f"description ({unit.text[:60]!r}) says neither",
    )


MATERIAL_NOUNS = {"wooden": "wood"}  # the noun a material is named by


def material(unit: Nearby | None, asked: str) -> MapAnswer:
    """What the unit is made of, when its description says: "wood", "metal", "leather"."""
    if unit is None:
        return MapAnswer("", "material", False, f"no {asked!r} nearby")
    said = [w for w in VOCABULARY["material"] if w in described(f"{unit.label} {unit.text}")]
    if not said:
        return MapAnswer(
            "",
            "material",
            False,
            f"cannot tell from the map: unit {unit.unit_id}'s description names no material",
        )
    word = MATERIAL_NOUNS.get(said[0], said[0])
    return MapAnswer(word, "material", True, f"unit {unit.unit_id}: {unit.text[:60]!r}")
