"""The offline answerer: situated questions answered from the map alone, and EM scoring.

No model: the question's type is read from its wording, the object it names is matched to
unit labels, and the answer comes from `Surroundings` (bearings, distances, heights,
region members, descriptions). It is honest about what it cannot do: a question type it
has no rule for, or one the map cannot answer, comes back with `supported=False` and the
reason, never a guess dressed as an answer. The map holds no room names: "which room" is
inferred from what stands near the pose through a common-sense table of what each kind of
room holds (`ROOM_CUES`, the knowledge an MLLM brings), nearer units weighing more.
Units a wall hides from the pose (`Surroundings.walled`, from the map's structure layer)
are in another room: no directional or room answer names them.

Exact match (EM) after normalisation — the rules, applied to prediction and answers alike:
1. lower case; strip punctuation except inner hyphens; collapse spaces;
2. drop articles (a, an, the) and a leading "it is"/"there is"/"its";
3. number words zero..twenty become digits;
4. British and American spellings fold (grey/gray, colour/color);
5. a trailing plural "s"/"es" is dropped (chairs -> chair) for words longer than three letters.
EM-1 scores the first answer against every reference answer. EM-R1 (relaxed) also accepts
a prediction whose words contain a reference answer as a whole phrase, or that equals a
listed synonym (sofa/couch, tv/television, fridge/refrigerator, bin/trash can,
forward/front/ahead, backward/back/behind).
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import replace
from typing import TYPE_CHECKING

from glmap_tools.sqa.attributes import colour_phrase
from glmap_tools.sqa.families import NAMES, answer_family, family, in_side, split_side
from glmap_tools.sqa.records import MapAnswer
from glmap_tools.sqa.rewording import plain_question
from glmap_tools.sqa.situation_words import NUMBER_WORDS
from glmap_tools.sqa.surroundings import Nearby, Surroundings, surroundings
from glmap_tools.sqa.wording import variants

if TYPE_CHECKING:
    from glmap_tools.map.glmap import GLMap
    from glmap_tools.sqa.situate import Situation

SPELLING = {"gray": "grey", "color": "colour", "colored": "coloured"}
SYNONYMS = [
    {"sofa", "couch"},
    {"tv", "television", "tv screen"},
    {"fridge", "refrigerator"},
    {"bin", "trash can", "trashcan", "garbage can"},
    {"plant", "potted plant", "houseplant"},
    {"forward", "front", "ahead", "straight ahead", "straight"},
    {"backward", "back", "behind", "backwards"},
]
# What each kind of room typically holds (words of a unit's label or description). Common
# household knowledge, not read from any scene; a unit fitting several rooms splits its vote.
ROOM_CUES: dict[str, tuple[str, ...]] = {
    "kitchen": (
        "kitchen",
        "refrigerator",
        "fridge",
        "stove",
        "oven",
        "cooker",
        "microwave",
        "toaster",
        "coffee machine",
        "dishwasher",
        "kettle",
    ),
    "bathroom": ("bathroom", "toilet", "bathtub", "bath", "shower", "washbasin", "towel"),
    "bedroom": ("bedroom", "bed", "nightstand", "bedside", "wardrobe", "dresser", "pillow"),
    "living room": (
        "living room",
        "sofa",
        "couch",
        "armchair",
        "tv",
        "television",
        "tv stand",
        "coffee table",
    ),
    "office": ("office", "desk", "office chair", "monitor", "computer", "printer"),
    "dining room": ("dining", "dining table", "dining chair", "sideboard"),
    "hallway": ("hallway", "coat rack", "shoe rack", "umbrella stand", "front door"),
}
ROOM_DECAY = 1.5  # m: a unit's vote falls by e per this much distance from the pose
REACH_CONE = 20.0  # degrees either side of straight ahead
SIDE_SECTORS = {"left": (45.0, 135.0), "right": (-135.0, -45.0)}
BEHIND = 150.0  # |bearing| at least this is behind


def _singular(word: str) -> str:
    if len(word) > 4 and word.endswith("ies"):
        return word[:-3] + "y"
    if len(word) > 4 and word.endswith(("ches", "shes", "sses", "xes")):
        return word[:-2]
    if len(word) > 3 and word.endswith("s") and not word.endswith(("ss", "us", "is")):
        return word[:-1]
    return word


def normalise(text: str) -> str:
    """An answer in canonical form (the module docstring lists the rules)."""
    t = text.lower().strip()
    t = re.sub(r"[^\w\s-]", " ", t)
    t = re.sub(r"(?<!\w)-|-(?!\w)", " ", t)
    words = t.split()
    while words and words[0] in ("it", "is", "its", "there", "a", "an", "the"):
        words = words[1:]
    out = []
    for w in words:
        if w in ("a", "an", "the"):
            continue
        w = SPELLING.get(w, w)
        if w in NUMBER_WORDS:
            w = str(NUMBER_WORDS.index(w))
        out.append(_singular(w))
    return " ".join(out)


def em1(prediction: str, answers: Sequence[str]) -> bool:
    """Exact match of the normalised prediction with any normalised reference answer."""
    p = normalise(prediction)
    return bool(p) and any(p == normalise(a) for a in answers)


def em_r1(prediction: str, answers: Sequence[str]) -> bool:
    """Relaxed exact match: EM-1, or a whole-phrase containment, or a listed synonym."""
    if em1(prediction, answers):
        return True
    p = normalise(prediction)
    if not p:
        return False
    for a in answers:
        n = normalise(a)
        if n and re.search(rf"(?<!\w){re.escape(n)}(?!\w)", p):
            return True
        if any(
            p in {normalise(s) for s in group} and n in {normalise(s) for s in group}
            for group in SYNONYMS
        ):
            return True
    return False


_WHAT = (
    r"\b(?:what|which)(?: kind of| type of| sort of| piece of)?(?: object| thing| furniture| item"
    r"| piece of furniture)?(?:'s| is| are| is there| are there| can i see| do i see| do i have"
    r"| (?:can|do|will|would|could) i (?:find|see|spot)| stands| lies| sits)?"
    r"(?: the (?:object|thing|item|furniture))?"
)
_AT = r"(?: (?:located|placed|standing|directly|right|immediately))?"
QUESTION_TYPES: list[tuple[str, re.Pattern[str]]] = [
    ("left", re.compile(_WHAT + _AT + r" (?:to|on|at) (?:my|the) left\b(?![- ]side of)")),
    ("right", re.compile(_WHAT + _AT + r" (?:to|on|at) (?:my|the) right\b(?![- ]side of)")),
    ("behind", re.compile(_WHAT + _AT + r" (?:behind me|at my back)\b")),
    (
        "front",
        re.compile(
            _WHAT + _AT + r" (?:in front of me|ahead of me|straight ahead)\b"
            r"|\bwhat am i (?:facing|looking at)\b"
        ),
    ),
    ("room", re.compile(r"\bwhich room\b|\bwhat (?:kind of |type of )?room\b|^where am i\b")),
    (
        "color",
        re.compile(
            r"\bwhat colou?r (?:is|are|does) (?:the )?(?P<object>.+?)(?: in the (?P<room>.+?))?"
            r"(?: have)?\?"
            r"|\bwhat is the colou?r of (?:the )?(?P<object2>.+?)(?: in the (?P<room2>.+?))?\?"
        ),
    ),
    (
        "count",
        re.compile(
            r"\bhow many (?P<object>.+?) are (?:there )?(?:in|on|at) (?:the )?(?P<where>.+?)\?"
        ),
    ),
    (
        "on",
        re.compile(r"\bwhat (?:is|are|sits|stands|lies) on (?:top of )?(?:the )?(?P<object>.+?)\?"),
    ),
    (
        "reach",
        re.compile(
            r"\bcan i (?:reach|get to|walk to) (?:the )?(?P<object>.+?)"
            r"(?: by walking straight ahead| straight ahead|$)"
        ),
    ),
]


def question_type(question: str) -> tuple[str, dict[str, str]]:
    """(type, named parts) of a question; ("unknown", {}) when no rule reads it."""

    q = " ".join(question.lower().replace("’", "'").split())
    q = plain_question(q)
    for text in (q, *variants(q)):  # as written first, then other wordings of it
        found = family(text)
        if found is not None:
            return found
        for name, pattern in QUESTION_TYPES:
            m = pattern.search(text)
            if m:
                parts = {k.rstrip("2"): v for k, v in m.groupdict().items() if v}
                return name, parts
    return "unknown", {}


def _match_label(phrase: str, labels: Sequence[str]) -> str | None:
    """The longest label that occurs in `phrase` as whole words (plurals folded)."""
    words = " ".join(_singular(w) for w in phrase.lower().split())
    short = " ".join(re.sub(r"^(\w\w)s$", r"\1", w) for w in words.split())  # "tvs", "pcs"
    best = None
    for label in set(labels):
        lab = " ".join(_singular(w) for w in label.lower().split())
        if (
            lab
            and any(re.search(rf"(?<!\w){re.escape(lab)}(?!\w)", t) for t in (words, short))
            and (best is None or len(lab) > len(best))
        ):
            best = label
    return best


def _pick(nearby: Sequence[Nearby], label: str | None, phrase: str) -> Nearby | None:
    """The unit labelled `label` whose description shares most words with `phrase`
    ("blue chair" picks the blue one), nearest first on ties."""
    cands = [n for n in nearby if n.label == label]
    if not cands:
        return None
    extra = {w for w in re.findall(r"[a-z]+", phrase.lower())} - set((label or "").split())

    def shared(n: Nearby) -> int:
        return len(extra & set(re.findall(r"[a-z]+", n.text.lower())))

    best = max(shared(n) for n in cands)
    return next(n for n in cands if shared(n) == best)


def _nearest_in(nearby: Sequence[Nearby], lo: float, hi: float, exclude: set[int]) -> Nearby | None:
    for n in nearby:
        if n.unit_id not in exclude and lo <= n.bearing <= hi:
            return n
    return None


def _nearest_towards(kind: str, where: Surroundings, skip: set[int]) -> tuple[Nearby | None, str]:
    """(the nearest unit on the asked side, the rule used): left, right, front or behind."""
    if kind in ("left", "right"):
        lo, hi = SIDE_SECTORS[kind]
        return _nearest_in(where.nearby, lo, hi, skip), f"nearest unit {lo:.0f}..{hi:.0f} deg"
    if kind == "front":
        n = _nearest_in(where.nearby, -45.0, 45.0, skip)
        return n, "nearest unit within 45 deg of straight ahead"
    n = next(
        (x for x in where.nearby if x.unit_id not in skip and abs(x.bearing) >= BEHIND),
        None,
    )
    return n, f"nearest unit at |bearing| >= {BEHIND:.0f} deg"


def _colour(label: str | None, obj: str | None, where: Surroundings) -> MapAnswer:
    """The first colour word in the descriptions of the label's units, nearest first."""
    kind = "color"
    if label is None:
        return MapAnswer("", kind, False, f"no unit is a {obj!r}")
    cands = [n for n in where.nearby if n.label == label] or [
        Nearby(uid, lab, "", math.inf, 0.0, "", 0.0, 0.0, (0, 0, 0, 0))
        for uid, lab in where.labels.items()
        if lab == label
    ]

    for n in cands:
        text = n.text or where_text(where, n.unit_id)
        colour = colour_phrase(text)  # "teal", "light brown", "black and white"
        if colour:
            return MapAnswer(colour, kind, True, f"unit {n.unit_id}: {text[:80]!r}")
    return MapAnswer("", kind, False, f"no colour in the description of the {label}")


def _count_in_region(label: str | None, region_text: str, where: Surroundings) -> MapAnswer:
    """How many units of the label the best-matching region holds."""
    kind = "count"
    region = _best_region(region_text, where)
    if label is None or region is None:
        return MapAnswer("", kind, False, "no matching unit label or region")
    rid, text, members = region
    count = sum(where.labels.get(m) == label for m in members)
    return MapAnswer(str(count), kind, True, f"region {rid} {text[:60]!r}: {count} x {label}")


def _on(base: Nearby | None, obj: str | None, where: Surroundings) -> MapAnswer:
    """The nearest unit resting on `base` (above its top, over its footprint)."""
    kind = "on"
    if base is None:
        return MapAnswer("", kind, False, f"no {obj!r} nearby")
    on = [
        n
        for n in where.nearby
        if n.unit_id != base.unit_id
        and n.z_min >= base.z_max - 0.1
        and _overlap(n.footprint, base.footprint)
    ]
    if not on:
        return MapAnswer("nothing", kind, True, f"nothing above unit {base.unit_id}")
    return MapAnswer(on[0].label, kind, True, f"unit {on[0].unit_id} on {base.unit_id}")


def _reach(target: Nearby | None, obj: str | None) -> MapAnswer:
    """Whether the target lies within the reaching cone ahead."""
    kind = "reach"
    if target is None:
        return MapAnswer("no", kind, True, f"no {obj!r} within reach")
    ok = abs(target.bearing) <= REACH_CONE
    return MapAnswer(
        "yes" if ok else "no",
        kind,
        True,
        f"unit {target.unit_id}: {target.bearing:.0f} deg, {target.distance:.1f} m",
    )


class OfflineAnswerer:
    """Answers situated questions from `Surroundings` (see the module docstring)."""

    def answer(self, question: str, where: Surroundings, exclude: Sequence[int] = ()) -> MapAnswer:
        """Answer `question` at the situated pose.

        Args:
            question: the question text T_q.
            where: the map around the situated pose.
            exclude: unit ids not to answer with (the anchor one stands at).
        """

        kind, parts = question_type(question)
        skip = set(exclude) | set(where.walled)  # what one stands at; what a wall hides
        labels = list(where.labels.values())
        if kind in NAMES:
            return answer_family(kind, parts, where, skip, _match_label, _room)
        # "the chair on my left": the side picks which chair.
        phrase, side = split_side(parts.get("object", ""))
        if side is not None:
            parts["object"] = phrase
            where = replace(where, nearby=tuple(n for n in where.nearby if in_side(n, side)))
        if kind in ("left", "right", "front", "behind"):
            return self._object(kind, *_nearest_towards(kind, where, skip))
        if kind == "room":
            return _room(where)
        obj = parts.get("object", "")
        label = _match_label(obj, labels)
        asked = parts.get("object")  # as the question named it, for the evidence
        if kind == "color":
            return _colour(label, asked, where)
        if kind == "count":
            return _count_in_region(label, parts.get("where", ""), where)
        if kind == "on":
            return _on(_pick(where.nearby, label, obj), asked, where)
        if kind == "reach":
            return _reach(_pick(where.nearby, label, obj), asked)
        return MapAnswer("", kind, False, "no rule for this kind of question")

    @staticmethod
    def _object(kind: str, n: Nearby | None, rule: str) -> MapAnswer:
        if n is None:
            return MapAnswer("nothing", kind, True, f"{rule}: none within reach")
        return MapAnswer(
            n.label,
            kind,
            True,
            f"{rule}: unit {n.unit_id} at {n.distance:.1f} m, {n.bearing:.0f} deg",
        )


def _room(where: Surroundings) -> MapAnswer:
    """The room kind whose typical contents stand nearest the pose (ROOM_CUES)."""
    votes = dict.fromkeys(ROOM_CUES, 0.0)
    why: dict[str, list[str]] = {room: [] for room in ROOM_CUES}
    for n in where.nearby:
        if n.unit_id in where.walled:  # another room
            continue
        words = " ".join(_singular(w) for w in re.findall(r"[a-z]+", f"{n.label} {n.text}".lower()))
        rooms = [
            room
            for room, cues in ROOM_CUES.items()
            if any(re.search(rf"(?<!\w){re.escape(c)}(?!\w)", words) for c in cues)
        ]
        for room in rooms:
            votes[room] += math.exp(-n.distance / ROOM_DECAY) / len(rooms)
            why[room].append(f"{n.label} {n.distance:.1f} m")
    best = max(votes, key=lambda r: votes[r])
    if votes[best] <= 0.0:
        return MapAnswer("", "room", False, "nothing nearby says what kind of room this is")
    return MapAnswer(best, "room", True, f"{best} {votes[best]:.2f}: {', '.join(why[best][:4])}")


def answer_at(
    glmap: GLMap,
    situation: Situation,
    question: str,
    answerer: OfflineAnswerer | None = None,
    where: Surroundings | None = None,
) -> tuple[MapAnswer, Surroundings]:
    """Answer `question` at a situated pose, never with the unit one stands at.

    The unit excluded is `situation.anchor_id` (the one l_a was placed at), not the best
    H_r unit `situation.anchors[0]`, which may be a region or another same-named object.

    Returns:
        (the answer, the surroundings it was read from).
    """
    s = situation
    where = where or surroundings(glmap, s.x, s.y, s.heading)
    exclude = [s.anchor_id] if s.anchor_id is not None else []
    return (answerer or OfflineAnswerer()).answer(question, where, exclude), where


def where_text(where: Surroundings, unit_id: int) -> str:
    return next((n.text for n in where.nearby if n.unit_id == unit_id), "")


def _overlap(a: tuple[float, float, float, float], b: tuple[float, float, float, float]) -> bool:
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


def _best_region(phrase: str, where: Surroundings) -> tuple[int, str, tuple[int, ...]] | None:
    """The region whose text shares most words with `phrase` (ties: the lowest id)."""
    want = {_singular(w) for w in re.findall(r"[a-z]+", phrase.lower())} - {"the", "of", "a"}
    best, best_score = None, 0.0
    for region in where.regions:
        have = {_singular(w) for w in re.findall(r"[a-z]+", region[1].lower())}
        score = len(want & have) / max(len(want), 1)
        if score > best_score:
            best, best_score = region, score
    return best if best_score >= 0.5 else None
