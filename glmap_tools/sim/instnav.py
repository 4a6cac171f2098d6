"""InstNav goal descriptions: attributes plus a spatial relation that single out one instance.

"the blue metal chair next to the round table" is accepted for a target only if no other
object of the layout matches it: same category and attributes, and the relation holds.
Relations: next to (footprints within `NEAR` metres), on (its support), in (its room).
"""

from __future__ import annotations

from collections.abc import Callable

from glmap_tools.sim.describe import object_phrase
from glmap_tools.sim.layout import Layout, SceneObject, rects_overlap

NEAR = 1.0  # metres between footprints for "next to"
ANCHOR_KEYS = ("shape", "color", "style", "material", "size")

Predicate = Callable[[SceneObject], bool]


def footprint_gap(a: SceneObject, b: SceneObject) -> float:
    """Planar distance (metres) between two objects' footprints (0 when they overlap)."""
    fa, fb = a.footprint(), b.footprint()
    if rects_overlap(fa, fb):
        return 0.0
    return float(min(a.distance_to(fb).min(), b.distance_to(fa).min()))


def _is_landmark(obj: SceneObject) -> bool:
    return obj.size[2] >= 0.05 and obj.category not in ("picture", "rug")


def anchor_phrase(layout: Layout, anchor: SceneObject) -> tuple[str, Predicate]:
    """The shortest phrase naming `anchor` ("round table"), and which objects it fits."""
    same = [o for o in layout.objects if o.category == anchor.category]
    options: list[dict[str, str]] = [
        {k: anchor.attributes[k]} for k in ANCHOR_KEYS if k in anchor.attributes
    ]
    options.append({})
    attrs = options[0]
    for option in options:  # one salient attribute that singles it out, if any
        fits = [o for o in same if all(o.attributes.get(k) == v for k, v in option.items())]
        if len(fits) == 1:
            attrs = option
            break
    fixed = dict(attrs)

    def matches(o: SceneObject) -> bool:
        return o.category == anchor.category and all(
            o.attributes.get(k) == v for k, v in fixed.items()
        )

    return object_phrase(anchor.category, fixed), matches


def _nearest_anchor(layout: Layout, target: SceneObject) -> SceneObject | None:
    best, best_gap = None, NEAR
    for o in layout.objects:
        if o.id == target.id or o.category == target.category or not _is_landmark(o):
            continue
        if o.room != target.room:  # "next to" never reaches through a wall
            continue
        if o.supported_by == target.id:
            continue
        gap = footprint_gap(target, o)
        if gap <= best_gap:
            best, best_gap = o, gap
    return best


def describe_instance(layout: Layout, target: SceneObject) -> str | None:
    """A description matching only `target` in the layout, or None if none is found."""
    phrase = object_phrase(target.category, target.attributes)
    same = [
        o
        for o in layout.objects
        if o.category == target.category and o.attributes == target.attributes
    ]
    # Each relation: its words and the ids of same-looking objects for which it holds.
    relations: list[tuple[str, set[int]]] = []
    anchor = _nearest_anchor(layout, target)
    if anchor is not None:
        text, fits = anchor_phrase(layout, anchor)
        near = {
            o.id
            for o in same
            if any(
                fits(a) and a.room == o.room and footprint_gap(o, a) <= NEAR
                for a in layout.objects
                if a.id != o.id
            )
        }
        relations.append((f"next to the {text}", near))
    if target.supported_by is not None:
        text, fits = anchor_phrase(layout, layout.object(target.supported_by))
        on = {
            o.id for o in same if o.supported_by is not None and fits(layout.object(o.supported_by))
        }
        relations.append((f"on the {text}", on))
    room = layout.room(target.room)
    in_room = (f"in the {room.name}", {o.id for o in same if o.room == target.room})
    combos = [[r] for r in relations] + [[r, in_room] for r in relations] + [[in_room]]
    for combo in combos:
        matching = set.intersection(*(ids for _, ids in combo))
        if matching == {target.id}:
            return " ".join(["the", phrase, *(text for text, _ in combo)])
    return None


def instance_goals(layout: Layout, candidates: list[SceneObject] | None = None) -> dict[int, str]:
    """Object id -> unique description, for every object that can be singled out."""
    out = {}
    for obj in candidates if candidates is not None else layout.objects:
        text = describe_instance(layout, obj)
        if text is not None:
            out[obj.id] = text
    return out
