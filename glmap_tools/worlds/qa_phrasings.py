"""Many phrasings of the generated situated QA, with one family per kind held out.

`generate_qa(..., phrasings=True)` rewrites each situation in one of SITUATION_FORMS
(activities, leading facing clauses, egocentric side clauses, clock directions, "my back
to") and each question in one of QUESTION_FORMS per kind, and adds questions of the SQA3D
families the templates lack (direction, is-there, parity, turning, am-I-in). Choices come
from their own random stream, so the poses, anchors and answers are those of the plain set.

Held out (never looked at while tuning the reader and the answerer): per situation kind and
per question kind the form marked in HELD_OUT. Every record says which forms it uses and
whether either is held out, and `reading` gives what a correct reading of its situation is.
"""

from __future__ import annotations

import math
import re
from typing import Any

import numpy as np

from glmap_tools.sim.describe import plural
from glmap_tools.sim.layout import Layout, SceneObject

# Situation forms: kind -> [(name, template)]. Slots: {prep} {A} anchor, {F} facing,
# {S} side object, {s} its side, {C} clock object, {h} its hour, {B} object behind,
# {act} an activity at the anchor.
SITUATION_FORMS: dict[str, list[tuple[str, str]]] = {
    "facing": [
        ("template", "I am standing {prep} the {A}, facing the {F}."),
        ("activity", "I am {act} at the {A}, facing the {F}."),
        ("leading-facing", "I am facing the {F} while standing next to the {A}."),
        ("front-of-me", "The {F} is in front of me and I am next to the {A}."),
        ("looking-at", "Standing in front of the {A}, I am looking at the {F}."),
    ],
    "side": [
        ("side-clause", "I am next to the {A}. The {S} is on my {s}."),
        ("to-my-side", "I am standing by the {A} and to my {s} is the {S}."),
    ],
    "clock": [
        ("clock-at", "I am at the {A}, the {C} is at my {h} o'clock."),
        ("clock-direction", "I am standing near the {A}. In my {h} o'clock direction is the {C}."),
    ],
    "behind": [
        ("back-to", "I am next to the {A} with my back to the {B}."),
        ("behind-me", "I am {act} at the {A} and the {B} is behind me."),
    ],
}
QUESTION_FORMS: dict[str, list[str]] = {
    "left": ["What is to my left?", "What is on my left-hand side?", "What can I see on my left?"],
    "right": ["What is to my right?", "What is on my right side?", "What do I see to my right?"],
    "behind": ["What is behind me?", "What is directly behind me?", "What is at my back?"],
    "room": ["Which room am I in?", "What room am I in?", "Where am I?"],
    "color": [
        "What colour is the {o}?",
        "What is the color of the {o}?",
        "What color does the {o} have?",
    ],
    "count": ["How many {p} are in the {w}?", "How many {p} are there in the {w}?"],
    "on": ["What is on the {b}?", "What is on top of the {b}?", "What sits on the {b}?"],
    "reach": [
        "Can I reach the {x} by walking straight ahead?",
        "Can I walk to the {x} straight ahead?",
    ],
    "direction": [
        "Which direction should I go to reach the {x}?",
        "Which way is the {x}?",
        "Which way should I turn to see the {x}?",
    ],
    "exists": ["Is there a {c} on my {s}?", "Is there any {c} to my {s}?"],
    "parity": [
        "Is the number of {p} around me even or odd?",
        "Is the amount of {p} in this room even or odd?",
    ],
    "turn": ["If I turn around, what is in front of me?", "If I turn around, what will I see?"],
    "in_room": ["Am I in the {r}?", "Am I standing in the {r}?"],
}
# The held-out form of each kind: the last one.
HELD_OUT = {k: forms[-1][0] for k, forms in SITUATION_FORMS.items()} | {
    k: len(forms) - 1 for k, forms in QUESTION_FORMS.items()
}
ACTIVITIES = {
    "sink": "washing my hands",
    "stove": "cooking",
    "desk": "working",
    "bed": "making the bed",
    "bookcase": "looking for a book",
    "refrigerator": "getting a drink",
    "kitchen cabinet": "putting away plates",
    "sofa": "folding a blanket",
    "table": "wiping the surface",
    "dining table": "setting the plates",
}
AROUND = 4.0
SIDES = {"left": (45.0, 135.0), "right": (-135.0, -45.0)}
EDGE = 12.0  # deg: objects this close to a sector edge are not asked about


def _bearing(position: np.ndarray, heading: float, o: SceneObject) -> float:
    d = o.position[:2] - position
    return math.degrees(math.remainder(math.atan2(d[1], d[0]) - heading, math.tau))


def _around(
    layout: Layout, landmarks: list[SceneObject], position: np.ndarray, heading: float, room: int
) -> list[tuple[float, float, SceneObject]]:
    """(distance, bearing deg, object) of the room's landmarks within AROUND, nearest first."""
    out = []
    for o in landmarks:
        if o.room != room:
            continue
        dist = float(o.distance_to(position[None])[0])
        if dist <= AROUND:
            out.append((dist, _bearing(position, heading, o), o))
    return sorted(out, key=lambda t: (t[0], t[2].id))


def rewrite_situation(
    layout: Layout,
    landmarks: list[SceneObject],
    named: Any,
    position: np.ndarray,
    heading: float,
    anchor: SceneObject,
    facing: SceneObject,
    anchor_text: str,
    facing_text: str,
    prep: str,
    rng: np.random.Generator,
) -> tuple[str, str, str, dict[str, Any]]:
    """(text, kind, form name, the correct reading) of a situation in a drawn phrasing."""
    around = [
        t
        for t in _around(layout, landmarks, position, heading, anchor.room)
        if t[2].id not in (anchor.id, facing.id)
    ]

    def phrase(o: SceneObject) -> str | None:
        return named(layout, o, anchor.room)

    side = [
        (s, o)
        for _, b, o in around
        for s, (lo, hi) in SIDES.items()
        if lo + EDGE <= b <= hi - EDGE and phrase(o)
    ]
    clock = [
        (round(-b / 30.0) % 12 or 12, o)
        for _, b, o in around
        if abs(-b / 30.0 - round(-b / 30.0)) < 0.3 and phrase(o) and abs(b) > 20.0
    ]
    behind = [o for _, b, o in around if abs(b) >= 150.0 and phrase(o)]
    kinds = ["facing", "facing"] + (["side"] if side else []) + (["clock"] if clock else [])
    kinds += ["behind"] if behind else []
    kind = kinds[int(rng.integers(len(kinds)))]
    forms = SITUATION_FORMS[kind]
    name, template = forms[int(rng.integers(len(forms)))]
    slots = {
        "prep": prep,
        "A": anchor_text,
        "F": facing_text,
        "act": ACTIVITIES.get(anchor.category, "tidying up"),
    }
    reading: dict[str, Any] = {"anchor": anchor_text, "facing": None, "constraints": []}
    if kind == "facing":
        reading["facing"] = facing_text
    elif kind == "side":
        s, o = side[int(rng.integers(len(side)))]
        slots |= {"S": phrase(o) or "", "s": s}
        reading["constraints"] = [[slots["S"], s]]
    elif kind == "clock":
        h, o = clock[int(rng.integers(len(clock)))]
        slots |= {"C": phrase(o) or "", "h": str(h)}
        reading["constraints"] = [[slots["C"], h]]
    else:
        o = behind[0]
        slots |= {"B": phrase(o) or ""}
        reading["constraints"] = [[slots["B"], "behind"]]
    return template.format(**slots), kind, name, reading


def rewrite_question(kind: str, question: str, rng: np.random.Generator) -> tuple[str, int]:
    """(question, form index) of a plain generated question in a drawn phrasing."""
    forms = QUESTION_FORMS.get(kind)
    if not forms:
        return question, 0
    k = int(rng.integers(len(forms)))
    slots: dict[str, str] = {}
    patterns = {
        "color": r"What colour is the (?P<o>.+)\?",
        "count": r"How many (?P<p>.+) are in the (?P<w>.+)\?",
        "on": r"What is on the (?P<b>.+)\?",
        "reach": r"Can I reach the (?P<x>.+) by walking straight ahead\?",
    }
    if kind in patterns:
        m = re.fullmatch(patterns[kind], question)
        if m is None:
            return question, 0
        slots = m.groupdict()
    return forms[k].format(**slots), k


def extra_questions(
    layout: Layout,
    landmarks: list[SceneObject],
    named: Any,
    position: np.ndarray,
    heading: float,
    anchor: SceneObject,
    rng: np.random.Generator,
) -> list[tuple[str, str, list[str], list[int], int]]:
    """(kind, question, answers, object ids, form index) of the families the plain set lacks,
    answered from the layout at the true pose."""
    out: list[tuple[str, str, list[str], list[int], int]] = []
    room = layout.room(anchor.room)
    around = [
        t
        for t in _around(layout, landmarks, position, heading, anchor.room)
        if t[2].id != anchor.id
    ]
    # Which way to an object; is there a <category> on my <side>?
    for question in (
        _direction_question(layout, around, named, room.id, rng),
        _exists_question(around, rng),
    ):
        if question is not None:
            out.append(question)
    # Parity of a category around me.
    counts: dict[str, int] = {}
    for _, _, o in around:
        counts[o.category] = counts.get(o.category, 0) + 1
    if counts:
        c = sorted(counts)[int(rng.integers(len(counts)))]
        n = counts[c] + (anchor.category == c and 0)
        t, k = _form(rng, "parity")
        out.append(("parity", t.format(p=plural(c)), ["even" if n % 2 == 0 else "odd"], [], k))
    # Turning around: what was behind me (when one object clearly is).
    behind = [(d, o) for d, b, o in around if abs(b) >= 150.0]
    if behind and (
        len(behind) == 1
        or behind[1][0] - behind[0][0] >= 0.5
        or behind[1][1].category == behind[0][1].category
    ):
        t, k = _form(rng, "turn")
        out.append(("turn", t, [behind[0][1].category], [behind[0][1].id], k))
    # Am I in the <room kind>?
    kinds = sorted({r.type for r in layout.rooms})
    asked = (
        room.type
        if rng.random() < 0.5 or len(kinds) < 2
        else next(k for k in kinds[int(rng.integers(len(kinds))) :] + kinds if k != room.type)
    )
    t, k = _form(rng, "in_room")
    out.append(("in_room", t.format(r=asked), ["yes" if asked == room.type else "no"], [], k))
    return out


def _form(rng: np.random.Generator, kind: str) -> tuple[str, int]:
    """A random question form of `kind`, with its index."""
    k = int(rng.integers(len(QUESTION_FORMS[kind])))
    return QUESTION_FORMS[kind][k], k


def _direction_question(
    layout: Layout,
    around: list[tuple[float, float, SceneObject]],
    named: Any,
    room: int,
    rng: np.random.Generator,
) -> tuple[str, str, list[str], list[int], int] | None:
    """Which way to an object singled out in the room, clear of the sector edges."""
    clear = [
        (b, o)
        for _, b, o in around
        if all(abs(abs(b) - e) > EDGE for e in (45.0, 135.0)) and named(layout, o, room)
    ]
    if clear:
        b, o = clear[int(rng.integers(len(clear)))]
        word = (
            "forward"
            if abs(b) < 45
            else "backward"
            if abs(b) > 135
            else ("left" if b > 0 else "right")
        )
        t, k = _form(rng, "direction")
        return "direction", t.format(x=named(layout, o, room)), [word], [o.id], k
    return None


def _exists_question(
    around: list[tuple[float, float, SceneObject]], rng: np.random.Generator
) -> tuple[str, str, list[str], list[int], int] | None:
    """Is there a <category> on my <side>? (None when one is near the sector's edge.)"""
    cats = sorted({o.category for _, _, o in around})
    if cats:
        c = cats[int(rng.integers(len(cats)))]
        s = "left" if rng.random() < 0.5 else "right"
        lo, hi = SIDES[s]
        near_edge = any(
            o.category == c and abs(b - lo) < EDGE or o.category == c and abs(b - hi) < EDGE
            for _, b, o in around
        )
        if not near_edge:
            yes = any(o.category == c and lo <= b <= hi for _, b, o in around)
            t, k = _form(rng, "exists")
            return "exists", t.format(c=c, s=s), ["yes" if yes else "no"], [], k
    return None
