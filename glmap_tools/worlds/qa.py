"""Situated question answering (SQA3D-like) generated from a layout's facts.

A situation is a standing position and heading next to an object, facing another ("I am
standing at the kitchen sink, facing the refrigerator."). Questions about it have short
answers derived from the layout: what is to my left/right/behind, what colour something is,
how many chairs a region has, what stands on something, which room I am in, and whether I can
walk straight ahead to something. JSON (format "glmap-sim-sqa")::

    {"format": "glmap-sim-sqa", "version": 3, "scene": ..., "scene_seed": ...,
     "questions": [{"question_id": 0, "scene_id": ..., "situation": ..., "question": ...,
                    "question_type": "left", "answers": [{"answer": "chair",
                    "answer_confidence": "yes", "answer_id": 1}],
                    "position": {"_x": ..., "_y": ..., "_z": 0.0},
                    "rotation": {"_w": ..., "_x": 0.0, "_y": 0.0, "_z": ...},
                    "heading": ..., "room": ..., "object_ids": [...]}]}

The situation names its anchor so that only one object of the layout fits the words (the
anchor's shortest phrase when it is unique, else an InstNav description with "next to the X",
"on the X" or "in the <room>", `situation_phrase`); an anchor nothing singles out is not used
(the draw moves on). The facing object must likewise be the only one in the anchor's room
that fits its words, so the heading is determined. Version 1 used the shortest phrase even
when several objects fitted it ("the navy kitchen cabinet" in a row of navy cabinets) and
picked among them uniformly, so no locator could tell which was meant; everything else is
as in version 1 (same random stream up to the first anchor or facing object it rejects).
Version 3 accepts a numbered room by its kind too ("second bedroom" or "bedroom"): which
bedroom is the second is the generator's count, nothing one could see; the rest is as in 2.

`position` is on the floor (z = 0, metres, z-up world); `rotation` is the quaternion of the
yaw `heading` (radians counter-clockwise from +x) the person faces.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any, NamedTuple

import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.sim.describe import number_word, plural
from glmap_tools.sim.instnav import anchor_phrase, describe_instance
from glmap_tools.sim.layout import Layout, Room, SceneObject
from glmap_tools.sim.motion import wrap_angle
from glmap_tools.sim.navgrid import NavGrid, build_nav_grid
from glmap_tools.worlds import qa_phrasings as ph
from glmap_tools.worlds.qa_phrasings import HELD_OUT

FORMAT = "glmap-sim-sqa"
VERSION = 3
AROUND = 4.0  # metres: objects farther away are not "to my left"
STAND_NEAR = (0.3, 1.0)  # metres from the anchor's footprint
AT_CATEGORIES = {"sink", "stove", "desk", "kitchen cabinet", "bookcase", "refrigerator"}


def _landmarks(layout: Layout) -> list[SceneObject]:
    return [
        o
        for o in layout.objects
        if o.supported_by is None and o.size[2] >= 0.3 and o.category not in ("picture", "rug")
    ]


def _name(layout: Layout, obj: SceneObject) -> str:
    return anchor_phrase(layout, obj)[0]


def situation_phrase(layout: Layout, obj: SceneObject, room: int | None = None) -> str | None:
    """Words (no article) that fit `obj` alone among the layout's objects, or among those in
    room `room` when given; None when nothing singles it out.

    The shortest phrase ("navy kitchen cabinet") if only `obj` fits it, else
    `describe_instance` ("white kitchen cabinet next to the refrigerator").
    """
    text, fits = anchor_phrase(layout, obj)
    pool = [o for o in layout.objects if room is None or o.room == room]
    if sum(1 for o in pool if fits(o)) == 1:
        return text
    unique = describe_instance(layout, obj)
    return unique.removeprefix("the ") if unique is not None else None


def bearing(position: np.ndarray, heading: float, obj: SceneObject) -> float:
    """Angle of `obj` from the facing direction, radians, positive to the left."""
    d = obj.position[:2] - position
    return wrap_angle(math.atan2(d[1], d[0]) - heading)


def _quaternion(heading: float) -> dict[str, float]:
    return {
        "_w": round(math.cos(heading / 2), 6),
        "_x": 0.0,
        "_y": 0.0,
        "_z": round(math.sin(heading / 2), 6),
    }


def _stand_point(
    layout: Layout, grid: NavGrid, anchor: SceneObject, rng: np.random.Generator
) -> np.ndarray | None:
    xs, ys = grid.cell_centers()
    pts = np.column_stack([xs[grid.navigable], ys[grid.navigable]])
    d = anchor.distance_to(pts)
    ok = (d >= STAND_NEAR[0]) & (d <= STAND_NEAR[1])
    room = layout.room(anchor.room)
    ok &= room.contains(pts)
    front = np.array([math.cos(anchor.heading), math.sin(anchor.heading)])
    in_front = ok & ((pts - anchor.position[:2]) @ front > anchor.size[1] / 2)
    choice = np.nonzero(in_front if in_front.any() else ok)[0]
    if len(choice) == 0:
        return None
    return pts[int(choice[rng.integers(len(choice))])]


def _sector(
    layout: Layout, position: np.ndarray, heading: float, room: int, lo: float, hi: float
) -> list[tuple[float, SceneObject]]:
    out = []
    for o in _landmarks(layout):
        if o.room != room:
            continue
        dist = float(o.distance_to(position[None])[0])
        b = bearing(position, heading, o)
        if dist <= AROUND and lo <= b <= hi:
            out.append((dist, o))
    return sorted(out, key=lambda t: (t[0], t[1].id))


def _clear_answer(hits: list[tuple[float, SceneObject]]) -> SceneObject | None:
    """The nearest object, when no other category is nearly as close."""
    if not hits:
        return None
    first = hits[0][1]
    for dist, o in hits[1:]:
        if o.category != first.category and dist - hits[0][0] < 0.5:
            return None
    return first


def _questions(
    layout: Layout,
    grid: NavGrid,
    position: np.ndarray,
    heading: float,
    anchor: SceneObject,
    facing: SceneObject,
    rng: np.random.Generator,
) -> Iterator[tuple[str, str, list[str], list[int]]]:
    room = layout.room(anchor.room)
    sectors = {
        "left": ("What is to my left?", math.radians(45), math.radians(135)),
        "right": ("What is to my right?", -math.radians(135), -math.radians(45)),
        "behind": ("What is behind me?", math.radians(150), math.radians(181)),
    }
    behind: SceneObject | None = None
    for kind, (question, lo, hi) in sectors.items():
        hits = _sector(layout, position, heading, room.id, lo, hi)
        if kind == "behind":
            hits += _sector(layout, position, heading, room.id, -math.radians(181), -lo)
            hits.sort(key=lambda t: (t[0], t[1].id))
        obj = _clear_answer([h for h in hits if h[1].id != anchor.id])
        if obj is not None:
            yield kind, question, [obj.category], [obj.id]
            if kind == "behind":
                behind = obj
    yield "room", "Which room am I in?", list(dict.fromkeys([room.name, room.type])), []
    in_room = [o for o in layout.objects if o.room == room.id and "color" in o.attributes]
    rng.shuffle(in_room)
    for o in in_room:
        same = [p for p in layout.objects if p.category == o.category]
        where = "" if len(same) == 1 else f" in the {room.name}"
        if where and sum(p.room == room.id for p in same) > 1:
            continue
        yield "color", f"What colour is the {o.category}{where}?", [o.attributes["color"]], [o.id]
        break
    count = _count_question(layout, room)
    if count is not None:
        yield count
    supports = [o for o in layout.objects if o.room == room.id and o.supported_by is not None]
    for o in supports:
        base = layout.object(o.supported_by or 0)
        on_base = [p for p in layout.objects if p.supported_by == base.id]
        if len(on_base) == 1 and sum(p.category == base.category for p in layout.objects) == 1:
            yield "on", f"What is on the {base.category}?", [o.category], [o.id]
            break
    yield _reach_question(layout, grid, position, heading, facing, behind, rng)


def _count_question(layout: Layout, room: Room) -> tuple[str, str, list[str], list[int]] | None:
    """How many of a category the room's first region holds (one it has several of, if
    any), or None when the room has no region."""
    for region in layout.regions:
        if region.room != room.id:
            continue
        members = [layout.object(i) for i in region.members]
        counts: dict[str, int] = {}
        for m in members:
            counts[m.category] = counts.get(m.category, 0) + 1
        several = sorted(c for c in counts if counts[c] >= 2)
        category = several[0] if several else members[0].category
        name = region.name
        if sum(g.name == name for g in layout.regions) > 1:
            name = f"{name} of the {room.name}"
        n = counts[category]
        return (
            "count",
            f"How many {plural(category)} are in the {name}?",
            [number_word(n), str(n)],
            [m.id for m in members if m.category == category],
        )
    return None


def _reach_question(
    layout: Layout,
    grid: NavGrid,
    position: np.ndarray,
    heading: float,
    facing: SceneObject,
    behind: SceneObject | None,
    rng: np.random.Generator,
) -> tuple[str, str, list[str], list[int]]:
    """Can I reach an object by walking straight ahead: the one I face (yes when the way
    is clear), or, half the time when there is one, the one behind me (no)."""
    dist = float(facing.distance_to(position[None])[0])
    direction = np.array([math.cos(heading), math.sin(heading)])
    end = position + direction * max(dist - 0.6, 0.0)
    clear = grid.segment_is_free(position, end) and abs(bearing(position, heading, facing)) < 0.35
    if behind is not None and rng.random() < 0.5:
        return (
            "reach",
            f"Can I reach the {_name(layout, behind)} by walking straight ahead?",
            ["no"],
            [behind.id],
        )
    else:
        return (
            "reach",
            f"Can I reach the {_name(layout, facing)} by walking straight ahead?",
            ["yes" if clear else "no"],
            [facing.id],
        )


def generate_qa(
    layout: Layout,
    situations: int,
    seed: int,
    grid: NavGrid | None = None,
    phrasings: bool = False,
) -> dict[str, Any]:
    """A situated QA set with up to `situations` situations and several questions each.

    With `phrasings`, situations and questions come in many phrasings and more question
    families (`glmap_tools.worlds.qa_phrasings`); each record then also has
    `situation_form`, `question_form`, `held_out` and `reading` (the correct reading of
    its situation). The poses and the plain questions' answers are the same either way.

    Raises:
        InvalidInputError: `situations` < 1, or no object with floor to stand on next to it.
    """
    if isinstance(situations, bool) or not isinstance(situations, int) or situations < 1:
        raise InvalidInputError(f"situations={situations!r} must be a positive integer.")
    grid = grid or build_nav_grid(layout)
    rng = np.random.default_rng([int(seed), 11])
    prng = np.random.default_rng([int(seed), 23])  # phrasing choices: their own stream
    landmarks = _landmarks(layout)
    questions: list[dict[str, Any]] = []
    made = 0
    for _ in range(situations * 4):
        if made >= situations or not landmarks:
            break
        stand = _stand(layout, grid, landmarks, rng)
        if stand is None:
            continue
        anchor, anchor_text, position, facing, facing_text, heading = stand
        made += 1
        prep = "at" if anchor.category in AT_CATEGORIES else "next to"
        situation = f"I am standing {prep} the {anchor_text}, facing the {facing_text}."
        items = [(*q, 0) for q in _questions(layout, grid, position, heading, anchor, facing, rng)]
        extra: dict[str, Any] = {}
        if phrasings:
            situation, items, extra = _phrased(layout, landmarks, stand, prep, items, prng)
        questions += _records(layout, len(questions), stand, situation, items, extra, phrasings)
    if not questions:
        raise InvalidInputError(
            f"layout {layout.name!r} has no object with navigable floor next to it to stand at."
        )
    return {
        "format": FORMAT,
        "version": VERSION,
        "scene": layout.name,
        "scene_seed": layout.seed,
        "questions": questions,
    }


class _Stand(NamedTuple):
    """Where a situation puts the agent: at the anchor, facing an object (with their words)."""

    anchor: SceneObject
    anchor_text: str
    position: np.ndarray  # [2] m
    facing: SceneObject
    facing_text: str | None
    heading: float  # radians


def _stand(
    layout: Layout, grid: NavGrid, landmarks: list[SceneObject], rng: np.random.Generator
) -> _Stand | None:
    """A situation at a random landmark; None when nothing singles the anchor out, there is
    no floor beside it, or nothing in its room can be named to face."""
    anchor = landmarks[int(rng.integers(len(landmarks)))]
    anchor_text = situation_phrase(layout, anchor)
    if anchor_text is None:  # nothing singles it out: the text could not say which
        return None
    position = _stand_point(layout, grid, anchor, rng)
    if position is None:
        return None
    others = [o for o in landmarks if o.room == anchor.room and o.id != anchor.id]
    others = [o for o in others if o.distance_to(position[None])[0] > 0.5]
    named = [(o, situation_phrase(layout, o, anchor.room)) for o in others]
    named = [(o, t) for o, t in named if t is not None]
    if not named:
        return None
    facing, facing_text = named[int(rng.integers(len(named)))]
    d = facing.position[:2] - position
    heading = math.atan2(d[1], d[0])
    return _Stand(anchor, anchor_text, position, facing, facing_text, heading)


def _phrased(
    layout: Layout,
    landmarks: list[SceneObject],
    stand: _Stand,
    prep: str,
    items: list[tuple[str, str, list[str], list[int], int]],
    prng: np.random.Generator,
) -> tuple[str, list[tuple[str, str, list[str], list[int], int]], dict[str, Any]]:
    """(situation, items, extra fields) in many phrasings (`glmap_tools.worlds.qa_phrasings`):
    the situation and the questions rewritten, the extra families' questions added."""
    anchor, anchor_text, position, facing, facing_text, heading = stand
    situation, s_kind, s_form, reading = ph.rewrite_situation(
        layout,
        landmarks,
        situation_phrase,
        position,
        heading,
        anchor,
        facing,
        anchor_text,
        facing_text or "",
        prep,
        prng,
    )
    rewritten = []
    for k, q, a, i, _ in items:
        text, form = ph.rewrite_question(k, q, prng)
        rewritten.append((k, text, a, i, form))
    items = rewritten
    items += ph.extra_questions(
        layout, landmarks, situation_phrase, position, heading, anchor, prng
    )
    return (
        situation,
        items,
        {"situation_kind": s_kind, "situation_form": s_form, "reading": reading},
    )


def _records(
    layout: Layout,
    first_id: int,
    stand: _Stand,
    situation: str,
    items: list[tuple[str, str, list[str], list[int], int]],
    extra: dict[str, Any],
    phrasings: bool,
) -> list[dict[str, Any]]:
    """The situation's question records, SQA3D style, numbered from `first_id`; with
    `phrasings`, each with the phrasing fields of `extra` and its own form."""
    anchor, _, position, facing, _, heading = stand
    out: list[dict[str, Any]] = []
    for kind, question, answers, ids, form in items:
        if phrasings:
            extra |= {
                "question_form": f"{kind}/{form}",
                "held_out": extra["situation_form"] == HELD_OUT[extra["situation_kind"]]
                or form == HELD_OUT.get(kind, -1),
            }
        out.append(
            {
                "question_id": first_id + len(out),
                "scene_id": layout.name,
                "situation": situation,
                "alternative_situation": [],
                "question": question,
                "question_type": kind,
                "answers": [
                    {"answer": a, "answer_confidence": "yes", "answer_id": i + 1}
                    for i, a in enumerate(answers)
                ],
                "position": {
                    "_x": round(float(position[0]), 4),
                    "_y": round(float(position[1]), 4),
                    "_z": 0.0,
                },
                "rotation": _quaternion(heading),
                "heading": round(heading, 5),
                "room": layout.room(anchor.room).name,
                "object_ids": [anchor.id, facing.id, *ids],
                **extra,
            }
        )
    return out


def heading_from_rotation(rotation: dict[str, float]) -> float:
    """The yaw (radians) of an SQA3D-style quaternion {_w, _x, _y, _z} about +z."""
    return 2.0 * math.atan2(float(rotation["_z"]), float(rotation["_w"]))
