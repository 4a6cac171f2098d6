"""The phrased bench's second set of forms: situations and questions as people write them
beyond `glmap_tools.worlds.qa_phrasings`, with the answers read from the layout at the true
pose.

`more_questions(layout, qa, seed)` takes a set from `generate_qa(..., phrasings=True)` and
returns new records, one more situation text per stand point (the same pose, in one of
SITUATION_FORMS) with questions of the families in QUESTION_FORMS. The first set's records
are left as they are, so its figures stay comparable. Per kind, the last form is held out:
written with the others, never used to tune the reader or the answerer. Every record says
`round: 2`, its forms, whether either is held out, and the correct reading of its text.

Answers come from the layout (categories, attributes, sizes, what rests on what), asked
only where they are clear: no object within EDGE degrees of a sector's edge, a nearest
object 0.5 m ahead of the next, distances 0.6 m apart, volumes twice as large.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from glmap_tools.sim.describe import plural
from glmap_tools.sim.layout import Layout, SceneObject

SITUATION_FORMS: dict[str, list[tuple[str, str]]] = {
    "glued-side": [
        ("anchor-that-is", "I am standing by the {A} that is on my {s}, facing the {F}."),
        (
            "anchor-which-is",
            "I am waiting beside the {A} which is to my {s}; the {F} is in front of me.",
        ),
    ],
    "relative-clause": [
        ("facing-that", "I am next to the {A}, facing the {F} that stands across from me."),
        ("anchor-where", "I am at the {A} where I usually stand, looking at the {F}."),
    ],
    "activity-tail": [
        ("at-doing", "I am at the {A} tidying up, facing the {F}."),
        ("doing-on", "I am putting my keys down on the {A}, and the {F} is in front of me."),
    ],
    "two-sides": [
        ("with-both", "I am next to the {A} with the {S} on my {s} and the {S2} on my {s2}."),
        ("both-while", "The {S} is on my {s} and the {S2} is on my {s2} while I stand at the {A}."),
    ],
    "leading": [
        ("after-stopped", "After walking in, I stopped next to the {A}, facing the {F}."),
        ("while-paused", "While tidying up, I paused by the {A} with the {F} in front of me."),
    ],
    "negation": [
        ("cannot-because", "I cannot see the {N} because I am next to the {A}, facing the {F}."),
        ("dont-see", "I don't see the {N}; I am next to the {A} and I am facing the {F}."),
    ],
    "across": [
        ("other-side", "I am at the {A} and the {F} is on the other side of the room."),
        ("opposite-side", "I am next to the {A}; at the opposite side of the room is the {F}."),
    ],
}  # fmt: skip
QUESTION_FORMS: dict[str, list[str]] = {
    "attribute": ["Is the {o} {v}?", "Is the {o} made of {v}?", "Is the {o} in this room {v}?"],
    "either": ["Is the {o} {v} or {w}?", "Is the {o} {v}, or is it {w}?"],
    "clock": ["What is at my {h} o'clock?", "Which object can I find at {h} o'clock?"],
    "which_side": [
        "Is the {o} on my left or on my right?",
        "Is the {o} in front of me or behind me?",
        "Is the {o} to my left or to my right?",
    ],
    "turn_see": [
        "Can I see the {o} if I turn around?",
        "If I turned around, would I see the {o}?",
    ],
    "compare": [
        "Which is closer to me, the {o} or the {q}?",
        "Is the {o} bigger than the {q}?",
        "Of the {o} and the {q}, which one is nearer to me?",
    ],
    "count": ["How many {p} on my {s}?", "Number of {p} on my {s}?"],
    "divisible": [
        "Is the number of {p} around me divisible by {k}?",
        "Can the number of {p} in this room be divided by {k}?",
    ],
    "count_on": ["How many {p} are on the {b}?", "Number of {p} on the {b}?"],
    "direction": [
        "If I want to {i}, which way should I go?",
        "I need to {i}; which direction do I go?",
    ],
    "turn_angle": [
        "How many degrees should I turn to face the {o}?",
        "How far do I have to turn to face the {o}?",
    ],
}
HELD_OUT = {k: forms[-1][0] for k, forms in SITUATION_FORMS.items()} | {
    k: len(forms) - 1 for k, forms in QUESTION_FORMS.items()
}
INTENTS = {  # category -> what one wants of it
    "sink": "wash my hands",
    "bed": "lie down",
    "stove": "cook",
    "refrigerator": "get a drink",
    "tv": "watch tv",
    "toilet": "use the toilet",
    "bathtub": "take a bath",
    "desk": "work",
    "bookcase": "find a book",
}
COLOURS = ("red", "blue", "green", "white", "black", "grey", "brown", "yellow", "beige")
MATERIALS = {"wood": ("wood", "oak", "walnut"), "metal": ("metal",), "leather": ("leather",)}
SHAPES = ("round", "rectangular")
AROUND = 4.0
EDGE = 12.0  # deg: no object this close to a sector's edge is asked about
SIDES = {"left": (45.0, 135.0), "right": (-135.0, -45.0)}
HOUR_WORDS = ("twelve", "one", "two", "three", "four", "five", "six", "seven", "eight", "nine",
              "ten", "eleven")  # fmt: skip
Named = Callable[[Layout, SceneObject, "int | None"], "str | None"]
Row = tuple[float, float, SceneObject]  # distance (m), bearing (deg, + = left), object


def _landmarks(layout: Layout) -> list[SceneObject]:
    """The objects the plain set asks about: on the floor, 0.3 m tall or more, no pictures."""
    return [
        o
        for o in layout.objects
        if o.supported_by is None and o.size[2] >= 0.3 and o.category not in ("picture", "rug")
    ]


def _bearing(position: np.ndarray, heading: float, o: SceneObject) -> float:
    d = o.position[:2] - position
    return math.degrees(math.remainder(math.atan2(d[1], d[0]) - heading, math.tau))


def _rows(layout: Layout, position: np.ndarray, heading: float, room: int) -> list[Row]:
    out = []
    for o in _landmarks(layout):
        if o.room != room:
            continue
        b = _bearing(position, heading, o)
        dist = float(o.distance_to(position[None])[0])
        if dist <= AROUND:
            out.append((dist, b, o))
    return sorted(out, key=lambda t: (t[0], t[2].id))


def _off_edges(b: float, edges: tuple[float, ...] = (45.0, 135.0)) -> bool:
    return all(abs(abs(b) - e) > EDGE for e in edges)


def _unique(layout: Layout, o: SceneObject) -> bool:
    """Is `o` the only object of its category in its room (its category names it)?"""
    return sum(p.category == o.category and p.room == o.room for p in layout.objects) == 1


def _side(b: float) -> str | None:
    for s, (lo, hi) in SIDES.items():
        if lo + EDGE <= b <= hi - EDGE:
            return s
    return None


def _situation(
    layout: Layout,
    named: Named,
    rows: list[Row],
    anchor: SceneObject,
    facing: SceneObject,
    position: np.ndarray,
    heading: float,
    rng: np.random.Generator,
) -> tuple[str, str, str, dict[str, Any]] | None:
    """(text, kind, form, reading) of the stand point in a drawn round-two form."""
    a_text = named(layout, anchor, None)
    f_text = named(layout, facing, anchor.room)
    if not a_text or not f_text:
        return None
    a_side = _side(_bearing(position, heading, anchor))
    others = [(dist, b, o) for dist, b, o in rows if o.id not in (anchor.id, facing.id)]
    sided = {s: [o for _, b, o in others if _side(b) == s and named(layout, o, o.room)]
             for s in SIDES}  # fmt: skip
    unseen = [o for _, b, o in others if abs(b) >= 150.0 and named(layout, o, o.room)]
    far = float(facing.distance_to(position[None])[0]) >= 2.0
    kinds = ["relative-clause", "activity-tail", "leading"]
    kinds += ["glued-side"] if a_side else []
    kinds += ["two-sides"] if sided["left"] and sided["right"] else []
    kinds += ["negation"] if unseen else []
    kinds += ["across"] if far else []
    kind = kinds[int(rng.integers(len(kinds)))]
    forms = SITUATION_FORMS[kind]
    name, template = forms[int(rng.integers(len(forms)))]
    slots = {"A": a_text, "F": f_text}
    reading: dict[str, Any] = {"anchor": a_text, "facing": f_text, "constraints": []}
    if kind == "glued-side":
        slots["s"] = a_side or ""
        reading["constraints"] = [[a_text, a_side]]
    elif kind == "two-sides":
        s, s2 = ("left", "right") if rng.random() < 0.5 else ("right", "left")
        o, o2 = sided[s][0], sided[s2][0]
        slots |= {"s": s, "s2": s2, "S": named(layout, o, o.room) or "",
                  "S2": named(layout, o2, o2.room) or ""}  # fmt: skip
        reading["facing"] = None
        reading["constraints"] = [[slots["S"], s], [slots["S2"], s2]]
    elif kind == "negation":
        slots["N"] = named(layout, unseen[0], unseen[0].room) or ""
    return template.format(**slots), kind, name, reading


def _form(kind: str, rng: np.random.Generator, only: tuple[int, ...] | None = None) -> int:
    choices = only if only is not None else tuple(range(len(QUESTION_FORMS[kind])))
    return int(choices[int(rng.integers(len(choices)))])


def _questions(
    layout: Layout,
    rows: list[Row],
    anchor: SceneObject,
    position: np.ndarray,
    heading: float,
    rng: np.random.Generator,
) -> list[tuple[str, str, list[str], int]]:
    """(kind, question, answers, form) of the round-two families at the stand point."""
    out: list[tuple[str, str, list[str], int]] = []
    near = [(dist, b, o) for dist, b, o in rows if o.id != anchor.id]
    unique = [(dist, b, o) for dist, b, o in near if _unique(layout, o)]

    def ask(kind: str, form: int, answers: list[str], **slots: str) -> None:
        out.append((kind, QUESTION_FORMS[kind][form].format(**slots), answers, form))

    _ask_attributes(ask, layout, anchor, unique, rng)
    _ask_clock(ask, layout, anchor, near, position, heading, rng)
    # Which side: left/right for a unique object in a side sector, front/behind straight.
    for _, b, o in unique:
        if _side(b):
            k = _form("which_side", rng, (0, 2))
            ask("which_side", k, [_side(b) or ""], o=o.category)
            break
    for _, b, o in unique:
        if abs(b) <= 35.0 or abs(b) >= 145.0:
            ask("which_side", 1, ["front" if abs(b) <= 35.0 else "behind"], o=o.category)
            break
    # Turning around: in view within 60 deg of behind, clear of that edge.
    for _, b, o in unique:
        off = 180.0 - abs(b)
        if abs(off - 60.0) > EDGE:
            ask("turn_see", _form("turn_see", rng), ["yes" if off <= 60.0 else "no"], o=o.category)
            break
    # Comparisons: distances 0.6 m apart; volumes twice as large.
    if len(unique) >= 2:
        i, j = (int(x) for x in rng.choice(len(unique), 2, replace=False))
        (da, _, a), (db, _, b2) = unique[i], unique[j]
        if abs(da - db) >= 0.6:
            k = _form("compare", rng, (0, 2))
            ask("compare", k, [a.category if da < db else b2.category], o=a.category, q=b2.category)
        va, vb = float(np.prod(a.size)), float(np.prod(b2.size))
        if max(va, vb) >= 2.0 * min(va, vb):
            ask("compare", 1, ["yes" if va > vb else "no"], o=a.category, q=b2.category)
    _ask_counts(ask, layout, rows, near, rng)
    # Intents: which way to the object serving one, clear of the sector edges.
    for _, b, o in near:
        if o.category in INTENTS and _off_edges(b) and _unique(layout, o):
            word = "forward" if abs(b) < 45 else "backward" if abs(b) > 135 else (
                "left" if b > 0 else "right")  # fmt: skip
            ask("direction", _form("direction", rng), [word], i=INTENTS[o.category])
            break
    # Turning angles: to the nearest 90 degrees, clear of 45 and 135.
    for _, b, o in unique:
        if _off_edges(b) and abs(b) > 20.0:
            deg = int(round(abs(b) / 90.0)) * 90
            ask("turn_angle", _form("turn_angle", rng), [f"{deg} degrees"], o=o.category)
            break
    return out


def _ask_attributes(
    ask: Callable[..., None],
    layout: Layout,
    anchor: SceneObject,
    unique: list[Row],
    rng: np.random.Generator,
) -> None:
    """Attribute and either-or questions on a colour, a material and a shape."""
    # Attributes: a colour said or another one; a material (wood, metal, leather).
    coloured = [o for _, _, o in unique if o.attributes.get("color") in COLOURS]
    if coloured:
        o = coloured[int(rng.integers(len(coloured)))]
        c = o.attributes["color"]
        v = c if rng.random() < 0.5 else next(x for x in rng.permutation(COLOURS) if x != c)
        k = _form("attribute", rng, (0, 2))
        ask("attribute", k, ["yes" if v == c else "no"], o=o.category, v=str(v))
        w = str(next(x for x in rng.permutation(COLOURS) if x != c))
        v, w = (c, w) if rng.random() < 0.5 else (w, c)
        ask("either", _form("either", rng), [c], o=o.category, v=v, w=w)
    made = [o for _, _, o in unique if o.attributes.get("material") in sum(MATERIALS.values(), ())]
    if made:
        o = made[int(rng.integers(len(made)))]
        m = str(rng.choice(list(MATERIALS)))
        ask("attribute", 1, ["yes" if o.attributes["material"] in MATERIALS[m] else "no"],
            o=o.category, v=m)  # fmt: skip
    shaped = [o for o in layout.objects if o.room == anchor.room and _unique(layout, o)
              and o.attributes.get("shape") in SHAPES]  # fmt: skip
    if shaped:
        o = shaped[0]
        v, w = SHAPES if rng.random() < 0.5 else SHAPES[::-1]
        ask("either", _form("either", rng), [o.attributes["shape"]], o=o.category, v=v, w=w)


def _ask_clock(
    ask: Callable[..., None],
    layout: Layout,
    anchor: SceneObject,
    near: list[Row],
    position: np.ndarray,
    heading: float,
    rng: np.random.Generator,
) -> None:
    """What is at a clock hour: the first near object clearly at one."""
    # Clock hours: the nearest object within 10 deg of an hour, clear of every other object
    # in the room (pictures and what stands on furniture too: the map holds them).
    everything = [
        (float(p.distance_to(position[None])[0]), _bearing(position, heading, p), p)
        for p in layout.objects
        if p.room == anchor.room and p.id != anchor.id and p.category != "rug"
    ]
    for dist, b, o in near:
        h = round(-b / 30.0) % 12
        if h in (0, 6) or abs(-b / 30.0 - round(-b / 30.0)) * 30.0 > 10.0:
            continue
        centre = -30.0 * h
        rivals = [x for x in everything if x[2].id != o.id
                  and abs(math.remainder(math.radians(x[1] - centre), math.tau)) <= math.radians(30)
                  and x[0] - dist < 0.5 and x[2].category != o.category]  # fmt: skip
        if not rivals:
            ask("clock", _form("clock", rng), [o.category], h=HOUR_WORDS[h])
            break


def _ask_counts(
    ask: Callable[..., None],
    layout: Layout,
    rows: list[Row],
    near: list[Row],
    rng: np.random.Generator,
) -> None:
    """Counts on a side, divisibility, and what rests on a base."""
    # Counts on a side and divisibility, by category.
    cats = sorted({o.category for _, _, o in near})
    if cats:
        c = cats[int(rng.integers(len(cats)))]
        s = "left" if rng.random() < 0.5 else "right"
        lo, hi = SIDES[s]
        same = [b for _, b, o in near if o.category == c]
        if all(abs(b - lo) > EDGE and abs(b - hi) > EDGE for b in same):
            n = sum(lo <= b <= hi for b in same)
            ask("count", _form("count", rng), [str(n)], p=plural(c), s=s)
        kk = int(rng.integers(2, 4))
        ask("divisible", _form("divisible", rng), ["yes" if len(same) % kk == 0 else "no"],
            p=plural(c), k=["two", "three"][kk - 2])  # fmt: skip
    # What rests on a base the room has one of.
    bases = [o for d, _, o in rows if d <= AROUND - 0.5 and _unique(layout, o)]
    for base in bases:
        on = [p for p in layout.objects if p.supported_by == base.id]
        if on:
            c = on[0].category
            n = sum(p.category == c for p in on)
            ask("count_on", _form("count_on", rng), [str(n)], p=plural(c), b=base.category)
            break


def more_questions(
    layout: Layout, qa: dict[str, Any], seed: int, named: Named
) -> list[dict[str, Any]]:
    """The round-two records for the stand points of `qa` (a `generate_qa` set).

    Args:
        layout: the scene.
        qa: its QA set; records are read, not changed.
        seed: the choices' seed (their own stream: the first set is not touched).
        named: words that single an object out in a room (`worlds.qa.situation_phrase`).
    """
    rng = np.random.default_rng([int(seed), 43])
    stands: dict[tuple[float, float, float], dict[str, Any]] = {}
    for q in qa["questions"]:
        key = (q["position"]["_x"], q["position"]["_y"], q["heading"])
        stands.setdefault(key, q)
    out: list[dict[str, Any]] = []
    for (x, y, heading), q in stands.items():
        position = np.array([x, y])
        anchor, facing = layout.object(q["object_ids"][0]), layout.object(q["object_ids"][1])
        rows = _rows(layout, position, heading, anchor.room)
        drawn = _situation(layout, named, rows, anchor, facing, position, heading, rng)
        if drawn is None:
            continue
        text, kind, form, reading = drawn
        for qkind, question, answers, k in _questions(layout, rows, anchor, position, heading, rng):
            out.append(
                q
                | {
                    "question_id": len(qa["questions"]) + len(out),
                    "situation": text,
                    "question": question,
                    "question_type": qkind,
                    "answers": [
                        {"answer": a, "answer_confidence": "yes", "answer_id": i + 1}
                        for i, a in enumerate(answers)
                    ],
                    "round": 2,
                    "situation_kind": kind,
                    "situation_form": f"r2:{form}",
                    "question_form": f"r2:{qkind}/{k}",
                    "held_out": form == HELD_OUT[kind] or k == HELD_OUT[qkind],
                    "reading": reading,
                }
            )
    return out
