"""The SQA3D question families beyond 'what is on my left': directions, visibility, counts
and parity with egocentric filters, yes/no, turning, arm's reach, shape and state.

Each family is a pattern over the lower-cased question and an answer from `Surroundings`
(bearings in degrees, + = left; distances in metres):

- direction: "Which direction should I go/turn to reach the X?" -> forward (|b| <= 45),
  left (45..135), right (-135..-45) or backward, for the nearest X no wall hides;
- see: "Can I see the X?" -> yes when an X no wall hides lies within FOV/2 of ahead;
- count / parity: "How many X are on my left / behind me / around me?", "Is the number of
  X in this room even or odd?" -> the Xs within AROUND m no wall hides, in the sector;
- exists: "Is there (another) X on my right / near me?" -> yes/no, same filter;
- in_room: "Am I in the kitchen?" -> yes when the room read from what stands around
  (`answer._room`) is that kind;
- turn: "If I turn around / to my left, what is in front of me / on my right?" -> the
  nearest unit at the direction asked after the turn;
- touch: "Can I touch/reach the X without getting up / moving?" -> yes within ARM m;
- beside: "What is on the left side of the wardrobe?" -> the nearest unit within BESIDE m
  of it on that side as I see it;
- shape / state: "What shape is the X?", "Is the X open or closed?" -> the word when the
  unit's description says it, else supported=False: the map cannot tell.

A side filter ("the chair on my left") also narrows which unit the colour and 'on'
questions are about (`side_of`, `pick_at`). The newer families (attributes, either/or,
clock hours, comparisons, counts on an object, divisibility, intents, turning angles) are
worded in `sqa.wording` and answered through `sqa.more_answers`.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

from glmap_tools.sqa.egocentric import direction, in_sector, sector_of
from glmap_tools.sqa.more_answers import MORE, answer_more, intent
from glmap_tools.sqa.records import MapAnswer
from glmap_tools.sqa.wording import EARLY, LATE, either_or

if TYPE_CHECKING:
    from glmap_tools.sqa.surroundings import Nearby, Surroundings

FOV = 120.0  # deg: what one sees without turning the head far
ARM = 0.9  # m: within reach without getting up or stepping
AROUND = 4.0  # m: "around me", "in this room" (walls cut it further)
BESIDE = 1.5  # m between centres: "on the left side of the wardrobe"
DIRECTION_OF = {"front": 0.0, "left": 90.0, "right": -90.0, "behind": 180.0}
SHAPES = ("round", "circular", "square", "rectangular", "oval", "triangular", "l-shaped")
STATES = ("open", "closed", "shut", "on", "off")

_SIDE = (
    r"(?:(?:on|to|at) (?:my|the) (?P<side>left|right)(?:[- ]hand)?(?: side)?(?: of me)?"
    r"|(?P<behind>behind me)|(?P<front>in front of me|ahead of me)"
    r"|(?P<around>around me|near me|nearby|close to me|in (?:this|the) room|here|in here))"
)
_OBJ = r"(?:the |a |an |any |some |another |other )*(?P<object>[a-z][a-z -]*?)"
_STATE = r"(?:open|opened|closed|shut|on|off)"
_TURN = (
    r"^(?:if|when|after) i (?:turn|rotate|spin)(?: myself)? (?P<turn>around|back|180 degrees|"
    r"(?:to )?(?:my |the )?left|(?:to )?(?:my |the )?right|(?:90 degrees )?(?:to (?:my |the )?)?"
    r"(?:left|right))"
)
FAMILIES: list[tuple[str, re.Pattern[str]]] = [
    (
        "turn",
        re.compile(
            _TURN + r",? (?:what|which object)(?: is| will be|'s| would be| do i see| will i see)?"
            r"(?: (?:directly |right )?(?P<ask>in front of me|ahead|on my left|to my left|"
            r"on my right|to my right|behind me))?"
        ),
    ),
    (
        "direction",
        re.compile(
            r"^(?:which|what) (?:direction|way|side)(?: should| do| would| can| must)? i "
            r"(?:go|turn|walk|head|move|face|look)(?: to| towards?| in order to)?"
            r"(?: (?:go to|get to|reach|find|see|face|look at|sit on|use|open|get))? "
            + _OBJ
            + r"\?*$"
        ),
    ),
    (
        "direction",
        re.compile(
            r"^(?:which|what) (?:direction|way|side) is " + _OBJ + r"(?: in| from me| at)?\?*$"
        ),
    ),
    ("direction", re.compile(r"^where is " + _OBJ + r" (?:from|relative to) me\?*$")),
    (
        "direction",
        re.compile(
            r"^should i (?:go|turn|walk) (?:left|right)(?: or (?:left|right|forward|straight))?"
            r"(?: to (?:go to|get to|reach|find|see))? " + _OBJ + r"\?*$"
        ),
    ),
    (
        "parity",
        re.compile(
            r"^is the (?:number|amount|count) of " + _OBJ + r"(?: " + _SIDE + r")?"
            r" (?:even or odd|odd or even)\?*$"
        ),
    ),
    (
        "parity",
        re.compile(
            r"^(?:do|are) (?:the )?" + _OBJ + r"(?: " + _SIDE + r")? (?:come in|number) "
            r"(?:an )?(?:even or odd|odd or even)(?: number)?\?*$"
        ),
    ),
    (  # "is the number of lamps odd?": yes or no
        "parity",
        re.compile(
            r"^is the (?:number|amount|count) of " + _OBJ + r"(?: " + _SIDE + r")?"
            r" (?:an? )?(?P<value>even|odd)(?: number)?\?*$"
        ),
    ),
    (
        "count",
        re.compile(
            r"^how many " + _OBJ + r" (?:are|is|can i see|do i see|do i have|are there)"
            r"(?: there)? " + _SIDE + r"\?*$"
        ),
    ),
    (
        "in_room",
        re.compile(
            r"^am i (?:in|inside|standing in|sitting in) (?:the |a |an )?(?P<room>[a-z ]+?)\?*$"
        ),
    ),
    (
        "exists",
        re.compile(r"^(?:is|are) there " + _OBJ + r"(?: " + _SIDE + r")?\?*$"),
    ),
    (
        "see",
        re.compile(
            r"^(?:can|could|do) i (?:see|spot|view|notice) " + _OBJ + r"(?: (?:from (?:here|where"
            r" i(?: am)?(?: standing| sitting| seated| lying| stand| sit| lie)?)|without turning"
            r"(?: around)?|right now|now))?\?*$"
        ),
    ),
    (
        "see",
        re.compile(
            r"^is " + _OBJ + r" (?:visible|in (?:my )?(?:view|sight|field of view))"
            r"(?: (?:from (?:here|where i(?: am)?(?: standing| sitting| seated| lying| stand| sit"
            r"| lie)?)|to me))?\?*$"
        ),
    ),
    (
        "touch",
        re.compile(
            r"^can i (?:touch|reach|grab|get|pick up|put my hand on|open|close|use|switch on|"
            r"turn on|switch off|turn off) "
            + _OBJ
            + r" (?:without (?:getting up|standing up|moving|walking|taking a step|stepping)"
            r"|from (?:here|where i (?:am|sit|stand))|with my hands?|by (?:just )?stretching"
            r"(?: out)?(?: my arms?)?)\?*$"
            r"|^(?:is|are) " + _OBJ.replace("object", "object2") + r" (?:within (?:arm'?s'? )?reach"
            r"|within arm'?s'? length|close enough to (?:touch|reach))(?: from here)?\?*$"
        ),
    ),
    (
        "beside",
        re.compile(
            r"^what(?: object)? is (?:on|to|at) the (?P<side>left|right)(?: side| hand side)? "
            r"of " + _OBJ + r"\?*$"
        ),
    ),
    ("shape", re.compile(r"^what (?:shape|form) (?:is|are|does) " + _OBJ + r"(?: have)?\?*$")),
    (
        "state",
        re.compile(
            r"^(?:is|are) " + _OBJ + r" (?:(?P<a>" + _STATE + r") or (?P<b>" + _STATE + r")"
            r"|(?P<value>" + _STATE + r"|(?:turned|switched) (?:on|off)))\?*$"
        ),
    ),
]
NAMES = (
    {name for name, _ in FAMILIES}
    | {name for name, _ in EARLY + LATE}
    | {
        "which_side",
        "up_down",
        "either",
    }
)


def family(question: str) -> tuple[str, dict[str, str]] | None:
    """(family, named parts) when one of FAMILIES reads the question, else None."""
    q = " ".join(question.lower().replace("’", "'").split()).strip(" ?.!")
    q = re.sub(r"\bo ?clock\b|\bo' clock\b", "o'clock", q)
    for name, pattern in EARLY + FAMILIES:
        m = pattern.search(q)
        if m:  # a pattern's second alternative names its parts "object2"
            return name, {k.rstrip("2"): v for k, v in m.groupdict().items() if v}
    found = either_or(q)
    if found is not None:
        return found
    for name, pattern in LATE:
        m = pattern.search(q)
        if m:  # a pattern's second alternative names its parts "object2"
            return name, {k.rstrip("2"): v for k, v in m.groupdict().items() if v}
    return None


def side_of(parts: dict[str, str]) -> str | None:
    """left / right / behind / front / around from a matched side phrase, or None."""
    if "side" in parts:
        return parts["side"]
    for k in ("behind", "front", "around"):
        if k in parts:
            return k
    return None


def in_side(n: Nearby, side: str | None) -> bool:
    """Is the unit in the sector (sides 45..135 degrees; front / behind within 45)."""
    if side is None or side == "around":
        return n.distance <= AROUND
    b = n.bearing
    if side == "left":
        return 45.0 <= b <= 135.0
    if side == "right":
        return -135.0 <= b <= -45.0
    if side == "front":
        return abs(b) <= 45.0
    return abs(b) >= 135.0


def split_side(phrase: str) -> tuple[str, str | None]:
    """('chair', 'left') from 'chair on my left'; (phrase, None) without a side."""
    m = re.search(r"\s+" + _SIDE + r"\s*$", phrase)
    if not m:
        return phrase, None
    return phrase[: m.start()], side_of({k: v for k, v in m.groupdict().items() if v})


def answer_family(
    kind: str,
    parts: dict[str, str],
    where: Surroundings,
    skip: set[int],
    match: Callable[[str, Sequence[str]], str | None],
    room: Callable[[Surroundings], MapAnswer],
) -> MapAnswer:
    """The answer to a question of family `kind` (see the module docstring).

    Args:
        kind, parts: from `family`.
        where: the map around the pose.
        skip: units not to answer with (the anchor; what walls hide).
        match: the label matcher (`answer._match_label`).
        room: the room reader (`answer._room`).
    """

    near = [n for n in where.nearby if n.unit_id not in skip]
    if kind in MORE:
        return answer_more(kind, parts, where, near, match)
    if kind == "in_room":
        return _in_room(parts, room(where))
    if kind == "turn":
        return _turn(parts, near)
    if kind == "direction" and "intent" in parts:
        return intent(parts["intent"], where, near, match)
    obj = parts.get("object", "")
    label = match(obj, list(where.labels.values()))
    if kind in ("count", "parity", "exists"):
        return _count(kind, parts, near, obj, label)
    if label is None:
        if kind == "see":
            return MapAnswer("no", kind, True, f"no unit is a {obj!r}")
        return MapAnswer("", kind, False, f"no unit is a {obj!r}")
    cands = [n for n in near if n.label == label]
    by_label = {
        "direction": direction,
        "see": _see,
        "touch": _touch,
        "shape": _described,
    }
    if kind in by_label:
        found = by_label[kind](kind, label, cands)
        if "lr" in parts and found.answer in ("forward", "backward"):  # "left or right?"
            turn = "left" if cands[0].bearing > 0 else "right"
            return MapAnswer(turn, kind, True, found.evidence)
        return found
    if kind == "beside":
        return _beside(parts, label, near, cands)
    return MapAnswer("", kind, False, "no rule for this kind of question")


def _in_room(parts: dict[str, str], r: MapAnswer) -> MapAnswer:
    """Whether the room read from the map is the room asked about."""

    if not r.supported:
        return MapAnswer("", "in_room", False, r.evidence)
    asked = parts.get("room", "")
    same = asked.replace("room", "").strip() in r.answer or r.answer in asked
    return MapAnswer("yes" if same else "no", "in_room", True, f"I am in the {r.answer}")


def _turn(parts: dict[str, str], near: list[Nearby]) -> MapAnswer:
    """The nearest unit within 45 degrees of the asked direction after the turn."""

    turn = parts.get("turn", "around")
    t = (
        180.0
        if ("around" in turn or "back" in turn or "180" in turn)
        else (90.0 if "left" in turn else -90.0)
    )
    ask = parts.get("ask", "in front of me")
    a = next((v for k, v in DIRECTION_OF.items() if k in ask), 0.0)
    if "ahead" in ask:
        a = 0.0
    centre = math.remainder(math.radians(a + t), math.tau)
    c = math.degrees(centre)
    hits = [
        n for n in near if abs(math.remainder(math.radians(n.bearing - c), math.tau)) <= math.pi / 4
    ]
    if not hits:
        return MapAnswer("nothing", "turn", True, f"nothing within 45 deg of {c:.0f} deg")
    h = hits[0]
    return MapAnswer(h.label, "turn", True, f"after a {t:.0f} deg turn: unit {h.unit_id}")


def _count(
    kind: str, parts: dict[str, str], near: list[Nearby], obj: str, label: str | None
) -> MapAnswer:
    """count / parity / exists: the units of the label around (on the asked side)."""

    side = side_of(parts) or (f"{parts['hour']} o'clock" if "hour" in parts else None)
    sector = sector_of(parts)
    if label is None:
        if kind == "exists":
            return MapAnswer("no", kind, True, f"no unit is a {obj!r}")
        return MapAnswer("", kind, False, f"no unit is a {obj!r}")
    units = [n for n in near if n.label == label and n.distance <= AROUND and in_sector(n, sector)]
    count = len(units)
    why = f"{count} x {label} ({side or 'around'}, within {AROUND:.0f} m)"
    if kind == "count":
        return MapAnswer(str(count), kind, True, why)
    if kind == "parity":
        word = "even" if count % 2 == 0 else "odd"
        if "value" in parts:  # "is the number of lamps odd?"
            return MapAnswer("yes" if parts["value"] == word else "no", kind, True, why)
        return MapAnswer(word, kind, True, why)
    return MapAnswer("yes" if count else "no", kind, True, why)


def _see(kind: str, label: str, cands: list[Nearby]) -> MapAnswer:
    """Whether a unit of the label lies within the field of view, no wall between."""

    seen = [n for n in cands if abs(n.bearing) <= FOV / 2]
    why = f"{len(seen)} {label} within {FOV / 2:.0f} deg of ahead, no wall between"
    return MapAnswer("yes" if seen else "no", kind, True, why)


def _touch(kind: str, label: str, cands: list[Nearby]) -> MapAnswer:
    """Whether the nearest unit of the label is within reach of an arm."""

    if not cands:
        return MapAnswer("no", kind, True, f"no {label} nearby")
    n = cands[0]
    ok = n.distance <= ARM
    return MapAnswer("yes" if ok else "no", kind, True, f"unit {n.unit_id} {n.distance:.1f} m")


def _beside(
    parts: dict[str, str], label: str, near: list[Nearby], cands: list[Nearby]
) -> MapAnswer:
    """The unit closest to the nearest unit of the label, on the asked side of it."""

    kind = "beside"
    if not cands:
        return MapAnswer("", kind, False, f"no {label} nearby")
    base = cands[0]
    sign = 1.0 if parts.get("side") == "left" else -1.0
    bx, by = (
        (base.footprint[0] + base.footprint[2]) / 2,
        (base.footprint[1] + base.footprint[3]) / 2,
    )
    by_it = []
    for n in near:
        if n.unit_id == base.unit_id:
            continue
        cx, cy = (n.footprint[0] + n.footprint[2]) / 2, (n.footprint[1] + n.footprint[3]) / 2
        gap = math.hypot(cx - bx, cy - by)
        if gap <= BESIDE and sign * (n.bearing - base.bearing) > 0:
            by_it.append((gap, n))
    if not by_it:
        return MapAnswer("nothing", kind, True, f"nothing within {BESIDE} m of unit {base.unit_id}")
    gap, n = min(by_it, key=lambda t: t[0])
    return MapAnswer(n.label, kind, True, f"unit {n.unit_id} {gap:.1f} m from {base.unit_id}")


def _described(kind: str, label: str, cands: list[Nearby]) -> MapAnswer:
    """shape / state: the first such word in the descriptions of the label's units."""

    words = SHAPES if kind == "shape" else STATES
    for n in cands or []:
        found = [w for w in re.findall(r"[a-z-]+", n.text.lower()) if w in words]
        if found:
            w = "closed" if found[0] == "shut" else found[0]
            return MapAnswer(w, kind, True, f"unit {n.unit_id}: {n.text[:60]!r}")
    return MapAnswer(
        "", kind, False, f"cannot tell from the map: no {kind} in the {label}'s description"
    )
