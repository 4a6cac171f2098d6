"""Which module answers which of the newer question families (`glmap_tools.sqa.wording`):
sides, hours, turns and counts in `egocentric`, comparisons in `compare`, attributes in
`attributes`; intents ("if I want to leave the room") by the object that serves them."""

from __future__ import annotations

from collections.abc import Callable, Sequence

from glmap_tools.sqa import attributes, egocentric
from glmap_tools.sqa.compare import compare
from glmap_tools.sqa.records import MapAnswer
from glmap_tools.sqa.surroundings import Nearby, Surroundings
from glmap_tools.sqa.wording import intent_object

MORE = {
    "clock",
    "compare",
    "count_on",
    "divisible",
    "turn_see",
    "turn_angle",
    "which_side",
    "up_down",
    "attribute",
    "either",
    "state",
    "on_exists",
    "nearest",
    "next_to",
    "under",
    "material",
    "between",
    "which_of",
}


def answer_more(
    kind: str,
    parts: dict[str, str],
    where: Surroundings,
    near: list[Nearby],
    match: Callable[[str, Sequence[str]], str | None],
) -> MapAnswer:
    """The round-two families (`wording`): answers in `egocentric`, `compare`, `attributes`."""
    if kind == "clock":
        return egocentric.clock(parts, near)
    if kind == "compare":
        return compare(parts, where, near, match)
    if kind == "count_on":
        return egocentric.count_on(parts, where, near, match)
    if kind == "on_exists":
        return egocentric.on_exists(parts, where, match)
    if kind == "nearest":
        return egocentric.nearest(near)
    if kind == "between":
        return egocentric.between(parts, near, match, list(where.labels.values()))
    if kind == "which_of":
        return egocentric.which_of(parts, near, match, list(where.labels.values()))
    if kind in ("next_to", "under"):
        return egocentric.next_to(kind, parts, where, near, match)
    obj = parts.get("object", "")
    label = match(obj, list(where.labels.values()))
    if kind == "divisible":
        return egocentric.divisible(parts, near, label, obj)
    if kind == "material":
        unit = egocentric.pick(where.nearby, label, obj) if label else None
        return attributes.material(unit, obj)
    if kind in ("attribute", "either", "state"):
        unit = egocentric.pick(where.nearby, label, obj) if label else None  # the anchor too
        if "value" in parts or "part" in parts:
            return attributes.attribute(parts, unit, obj, kind)
        return attributes.either(kind, [parts.get("a", ""), parts.get("b", "")], unit, obj)
    if label is None:
        if kind == "turn_see":
            return MapAnswer("no", kind, True, f"no unit is a {obj!r}")
        return MapAnswer("", kind, False, f"no unit is a {obj!r}")
    cands = [n for n in near if n.label == label]
    if kind == "turn_see":
        return egocentric.turn_see(parts, label, cands)
    if kind == "turn_angle":
        return egocentric.turn_angle(label, cands)
    if kind == "which_side":
        return egocentric.which_side(parts, label, cands)
    return egocentric.up_down(parts, label, cands)


def intent(
    intent: str,
    where: Surroundings,
    near: list[Nearby],
    match: Callable[[str, Sequence[str]], str | None],
) -> MapAnswer:
    """Which way to the nearest unit serving an intent ("leave the room": a door)."""
    wanted = intent_object(intent)
    labels = {match(w, list(where.labels.values())) for w in wanted.split("|")} - {None}
    cands = [n for n in near if n.label in labels]
    if not cands:
        return MapAnswer("", "direction", False, f"no {wanted!r} to {intent!r} nearby")
    return egocentric.direction("direction", cands[0].label, cands)
