"""A situation text read into one structured form: where I am, what I face, what is around.

People write situations many ways (SQA3D style): a posture at an object ("I am sitting on
the couch"), an activity ("I am rinsing a cup at the kitchen sink", "I am closing the
curtains"), a leading facing clause ("I am facing a bookshelf, and a lamp is on my right"),
egocentric clauses ("the door is on my left", "to my right is a desk", "the bed is behind
me", "my back is facing the window", "the lamp is in my 2 o'clock direction"). They all
say the same three things, which `SituationReading` holds:

- position: the anchor object (its words, with any qualifying relations: "white cabinet
  next to the fridge"), the relation to it ("at", "on", "in front of", "between", ...),
  and the posture or activity;
- facing: the object faced, or None;
- constraints: (object, side) with side left / right / behind / front, or (object, clock
  hour), 12 o'clock straight ahead and 3 o'clock to the right.

`read_situation` is the offline reader: rules over clauses, no model. An LLM (or a caller)
can produce the same form and hand it to `situate` (`glmap_tools.sqa.situate`) directly.
"""

from __future__ import annotations

import re
from typing import Any

from glmap_tools.errors import InvalidInputError
from glmap_tools.sqa import asides
from glmap_tools.sqa.clauses import split_clauses
from glmap_tools.sqa.reading_form import SIDE_BEARING as SIDE_BEARING
from glmap_tools.sqa.reading_form import SIDES as SIDES
from glmap_tools.sqa.reading_form import Constraint, SituationReading
from glmap_tools.sqa.reading_form import Side as Side
from glmap_tools.sqa.relations import relation_phrases
from glmap_tools.sqa.situation_words import (
    BASE_POSTURES,
    HOUR_WORDS,
    POSTURES,
    RELATIONS,
    ROOMS,
    SEATS,
)

_DET = re.compile(r"^(?:the|a|an|some|my|this|that|one|two|three|several|few|of)\s+")
_LEAD = re.compile(
    r"^(?:(?:i am|i'm|im|i|am|we are|currently|right now|now|just|here|also|there)\b\s*)+"
)
_FACE_VERB = (
    r"(?:facing away from|facing towards?|facing|face|"
    r"look(?:s|ing)? (?:up |down |over |across |out )?(?:at|towards?|into|out of)|looking out|"
    r"watching|turned (?:to|towards?)|"
    r"(?:oriented|orientated|pointed|pointing) (?:to|towards?|at)|staring at|gazing at|"
    r"with my (?:face|eyes) (?:to|towards?)|my face is towards?|i see|i can see)"
)
_NUM = r"(?P<h>\d{1,2}|" + "|".join(HOUR_WORDS[1:12]) + r"|twelve)"
_CLOCK_TAIL = r"(?:\s*o'?clock)(?:\s+(?:direction|position|orientation))?"
_SIDE = r"(?P<s>left|right)(?:[- ]hand)?(?: side)?(?: of me)?"

# "the lamp (is) on my left", "a coat is hanging behind me"
_IS = (
    r"(?:(?:is|are) (?:(?:standing|hanging|sitting|lying|placed|located|leaning|kept|resting"
    r"|mounted|set) )?|stands |sits |lies |hangs )?"
)
_THERE = r",? (?:is |are |there is |there are |there's |i (?:can )?see |i have |stands |sits )?"
_JUST = r"(?:right |directly |straight |immediately |just )?"
_AHEAD = r"(?:in front of me|ahead of me|before me|straight ahead|ahead)"
# Where the object rests, after its side: "a bag on my left on the floor".
# A participle after the object's noun starts an activity ("at the counter chopping onions");
# nouns that end in -ing are not one ("dining table", "washing machine", "ceiling light").
_ING_NOUNS = (
    "dining|washing|living|ceiling|sitting|painting|building|clothing|drawing|reading|sewing|"
    "changing|ironing|serving|baking|railing|landing|seating|heating|lighting|shelving|"
    "sleeping|dressing|recording|swing|string|ring|king|spring|wing|ceiling|pudding|bedding|"
    "thing|something|anything|nothing|everything|evening|morning|icing|siding|flooring"
)
_ACTIVITY_TAIL = re.compile(r"(?<=\w)\s+(?!(?:" + _ING_NOUNS + r")\b)[a-z]{2,}ing\b.*$")
# A part of the anchor is the anchor: "the far end of the bench", "the left side of the bed",
# "the right of the fridge" (from "to the right of").
_PART_OF = re.compile(
    r"^(?:the )?(?:far |near |other |very )?(?:left |right |front |back |upper |lower )?"
    r"(?:end|top|bottom|edge|side|corner|arm|armrest|back|foot|head|front|middle|center|centre"
    r"|left|right|left-hand side|right-hand side)( of (?:the |a |an |my )?)(?=\w)"
)
_PART_OWNED = re.compile(
    r"'s (?:far |near |other |left |right |front |back )?(?:end|top|bottom|edge|side|corner|arm"
    r"|armrest|back|foot|head|front|middle|center|centre)$"
)
# What one stands or sits on before the place: "on the floor next to the coffee table".
_GROUND = ("floor", "ground")  # a rug or a carpet can be a unit of its own
_PLACE_TAIL = r"(?: (?:on|by|near|next to|against|under|in) (?:the|a|an) [\w -]+)?"
_REL_START = r"^(?:" + "|".join(RELATIONS) + r") "
# A verb before the relation that is no posture: "i stopped next to the bookcase"; or the
# manner of a posture: "cross-legged on the mat", "stretched out on the sofa".
_VERB = re.compile(
    r"^(?:[\w-]+ed|was|got|went|came|remain|remains|stay|stays|am|is|sits|stands|lies)"
    r"(?: (?:up|over|back|down|out|here|there))? (?=(?:" + "|".join(RELATIONS) + r") )"
)
# A participle after the anchor starts another clause ("at the window looking outside").
_DOING = (
    r"(?:looking|watching|holding|reading|waiting|thinking|smiling|talking|listening|"
    r"working|resting|trying|getting|ready)"
)
_PATTERNS: list[tuple[str, re.Pattern[str]]] = [
    (
        "behind",
        re.compile(
            r"^(?:with )?my back (?:is )?(?:facing|turned to|to|towards?|against) (?P<x>.+)$"
        ),
    ),
    ("behind", re.compile(r"^(?:i am )?facing away from (?P<x>.+)$")),
    ("behind", re.compile(r"^(?:at|behind) my back" + _THERE + r"(?P<x>.+)$")),
    ("behind", re.compile(r"^" + _JUST + r"behind me" + _THERE + r"(?P<x>.+)$")),
    ("behind", re.compile(r"^(?P<x>.+?) " + _IS + _JUST + r"behind (?:me|my back|my head)$")),
    ("behind", re.compile(r"^(?:i have )?(?P<x>.+?) " + _IS + r"at my back$")),
    (
        "clock",
        re.compile(r"^(?:at|in|on|to) (?:my |the )?" + _NUM + _CLOCK_TAIL + _THERE + r"(?P<x>.+)$"),
    ),
    (
        "clock",
        re.compile(
            r"^(?P<x>.+?) " + _IS + r"(?:at|in|on|to) (?:my |the )?" + _NUM + _CLOCK_TAIL + r"$"
        ),
    ),
    ("clock", re.compile(r"^(?P<x>.+?) " + _IS + _NUM + _CLOCK_TAIL + r"(?: (?:of|from) me)?$")),
    ("side", re.compile(r"^(?:to|on|at) (?:my|the) " + _SIDE + _THERE + r"(?P<x>.+)$")),
    ("side", re.compile(r"^my " + _SIDE + r" (?:is|faces|is facing|is next to|has) (?P<x>.+)$")),
    (
        "side",
        re.compile(
            r"^(?:i have )?(?P<x>.+?) "
            + _IS
            + r"(?:located )?"
            + _JUST
            + r"(?:to|on|at|by) (?:my|the) "
            + _SIDE
            + _PLACE_TAIL
            + r"$"
        ),
    ),
    ("side", re.compile(r"^(?:i have )?(?P<x>.+?) " + _IS + r"(?P<s>left|right) of me$")),
    ("front", re.compile(r"^" + _JUST + _AHEAD + _THERE + r"(?P<x>.+)$")),
    ("front", re.compile(r"^(?:i have )?(?P<x>.+?) " + _IS + _JUST + _AHEAD + r"$")),
]


def object_words(phrase: str) -> str:
    """The object's words: no leading article or 'there is', no trailing 'of me'."""
    p = phrase.strip(" .,;:!?\"'")
    p = re.sub(r"^(?:there (?:is|are)|there's|i (?:can )?see|i have|is|are)\s+", "", p)
    p = re.sub(r"\s+(?:of me|from me|to me|as well|too)$", "", p)
    p = re.sub(r"\s+(?:standing|hanging|sitting|lying|placed|leaning|resting)$", "", p)
    prev = None
    while prev != p:
        prev = p
        p = _DET.sub("", p)
    return p.strip(" .,;:")


def _hour(h: str) -> int:
    if h.isdigit():
        return int(h) % 12 or 12
    return HOUR_WORDS.index(h) or 12


def _position(clause: str, out: dict[str, Any]) -> None:
    """Fill posture / activity / relation / anchor from a position clause."""
    rest, present = _place_words(clause, out)
    words = rest.split()
    if words and (words[0] in POSTURES or words[0] in BASE_POSTURES):
        w = BASE_POSTURES.get(words[0], words[0])
        out.setdefault("posture", "sitting" if w in ("seated", "sat") else w)
        rest = " ".join(words[1:])
        rest = re.sub(r"^(?:up|down|here|there)\s+", "", rest)
        # "resting my elbows on the windowsill": the body part is not the place
        rest = re.sub(
            r"^my (?:elbows?|arms?|hands?|feet|foot|legs?|head|chin|back|knees?)\s+(?="
            + _REL_START[1:]
            + ")",
            "",
            rest,
        )
        # an adverb between the posture and the place: "sitting cross-legged on the rug"
        if not re.match(_REL_START, rest):
            rest = re.sub(r"^(?!(?:the|a|an|my)\b)[\w-]+\s+(?=" + _REL_START[1:] + ")", "", rest)
    elif words and (
        words[0].endswith("ing")
        and words[0] not in ("facing", "looking")
        or present is not None
        and words[0] == present
    ):
        loc = _activity(rest, words, out)
        if loc is None:
            return
        rest = loc
    _anchor(rest, out)


def _place_words(clause: str, out: dict[str, Any]) -> tuple[str, str | None]:
    """The position clause without its subject and auxiliaries, a verb before the place
    taken as the activity (into `out`), a leading room moved after the place; and the
    present-tense verb the clause starts with ("i wash dishes at the sink"), or None."""
    rest = _LEAD.sub("", clause).strip()
    # "i have just sat down on the couch": the perfect's auxiliary goes
    rest = re.sub(
        r"^(?:have|has|had)\s+(?:(?:just|already|finally|now|recently)\s+)*(?:been\s+)?"
        r"(?=(?:\w+ed|sat|stood|knelt|lain|\w+ing)\b)",
        "",
        rest,
    )
    rest = _VERB.sub("", rest)
    # "i wash dishes at the sink": a verb with its object before the place; "while i cook":
    # a verb alone
    present = re.match(
        r"^(?:i|we)\s+(?!(?:am|are|was|were|have|has|had|can|could|will|would|do|did|may|"
        r"might|must|should|see|look|face)\b)([a-z]+)(?:\s+(?!" + _REL_START[1:] + r")|$)",
        clause,
    )
    # "i relax in the armchair": after "i", a word before the place is a verb
    verb = re.match(
        r"^(?:i|we)\s+(?!(?:am|are|was|were|have|had)\b)([a-z]+)\s+" + _REL_START[1:], clause
    )
    if verb and verb.group(1) not in POSTURES and verb.group(1) not in BASE_POSTURES:
        out.setdefault("activity", verb.group(1))
        rest = re.sub(r"^" + verb.group(1) + r"\s+", "", rest)
    room_first = re.match(
        r"^(?:in|inside) (?:the |my )?(?P<room>"
        + "|".join(ROOMS)
        + r") (?P<pose>(?:"
        + "|".join(POSTURES)
        + r") .+)$",
        rest,
    )
    if room_first:  # "in the living room sitting on the sofa": the sofa, in the living room
        rest = f"{room_first.group('pose')} in the {room_first.group('room')}"
    return rest, present.group(1) if present is not None else None


def _activity(rest: str, words: list[str], out: dict[str, Any]) -> str | None:
    """An activity ("rinsing a cup at the kitchen sink", "closing the curtains") into `out`;
    the place after it, or None when the clause names none (what is worked on, if anything,
    is then the anchor)."""
    # "putting on my shoes by the door": the particle is the verb's, not a place
    # "drying off next to the rack": a particle before another relation
    particle = re.match(
        r"^(?:(?:putting|taking|trying|pulling|slipping|picking|turning|switching) (?:on|off|up)"
        r"|[a-z]+ing (?:on|off|up)(?= (?:" + "|".join(re.escape(r) for r in RELATIONS) + r") ))\s",
        rest,
    )
    relation = re.compile(r"\s(" + "|".join(re.escape(r) for r in RELATIONS) + r")\s")
    padded = " " + rest + " "
    m = relation.search(padded, particle.end() if particle else 0)
    while m and padded[m.end() :].startswith("my "):
        # "working on my laptop at the kitchen table": the place is after what is mine
        later = relation.search(padded, m.end())
        if later is None:
            break
        m = later
    loc = None
    if m and m.start() > 0:
        head = rest[: m.start() - 1].strip() if m.start() > 0 else ""
        tail = rest[m.start() :].strip()
        # "getting a glass of water from the sink": the place after "from" / "out of"
        if m.group(1) not in ("with", "to", "into", "over") or not head.split()[1:]:
            out.setdefault("activity", head or words[0])
            loc = tail
        worked = object_words(" ".join(head.split()[1:]))
        if re.match(r"(?:" + asides.IN_PLACE + r")$", words[0]) and m.group(1) in (
            asides.NEAR_WORDS
        ):  # "watering the plant near the window": I am at the plant
            loc = f"at the {worked} {tail}" if worked else loc
    if loc is None:
        out.setdefault("activity", rest)
        obj = object_words(" ".join(words[1:]))
        if obj and not out.get("anchor") and words[1:2] != ["my"]:  # "washing my hands"
            out["anchor"], out["relation"] = asides.qualifiers(obj), "at"
    return loc


def _anchor(rest: str, out: dict[str, Any]) -> None:
    """The anchor and the relation to it (into `out`) from the place words ("on the couch",
    "between the sofa & the table", "in the kitchen next to the fridge")."""
    m = re.match(r"^(" + "|".join(re.escape(r) for r in RELATIONS) + r")\s+(.+)$", rest)
    if not m:
        obj = object_words(rest)
        mine = re.match(r"^\w+ my\b", rest)  # "(i) brush my teeth": no place
        if obj and not out.get("anchor") and len(obj.split()) <= 6 and not mine:
            out["anchor"], out["relation"] = obj, out.get("relation") or "at"
        return
    rel, obj = m.group(1), m.group(2)
    if rel == "between" and "&" in obj:
        a, b = (object_words(x) for x in obj.split("&", 1))
        out.setdefault("near", []).append(b)
        obj = a
    obj, ego = asides.split_relative(obj)
    obj = object_words(re.sub(r"\s+" + _DOING + r"\b.*$", "", obj))
    obj = _ACTIVITY_TAIL.sub("", obj)  # "the counter chopping onions"
    obj = asides.COVERED.sub("", obj)  # "the bed under the duvet"
    if rel != "on":  # "at the desk on a stool": what I sit on, not the place's name
        obj = re.sub(r"(?<=\w) on (?:a|an) [\w -]+$", "", obj)
    obj = _PART_OF.sub("", obj)
    obj = _PART_OWNED.sub("", obj)  # "the bed's edge"
    if obj in asides.PRONOUNS and out.get("named"):  # "there is a sofa ...; i sit on it"
        obj = out["named"]
        place = out.get("named_place")
        if place and _seat(place) and not _seat(obj) and out.get("posture") is not None:
            obj = place  # "the lamp is next to the sofa, and i am sitting on it"
    if ego is not None and obj:
        out.setdefault("ego", []).append((obj, ego))
    # "in the kitchen next to the fridge": the object, not the room, is the anchor.
    sub = re.match(r"^(.+?)\s+(next to|beside|near|by|at|in front of|close to|on)\s+(.+)$", obj)
    if sub and object_words(sub.group(1)) in ROOMS:
        room, rel, obj = object_words(sub.group(1)), sub.group(2), object_words(sub.group(3))
        obj = f"{obj} in the {room}"
    elif sub and object_words(sub.group(1)) in _GROUND and sub.group(2) != "on":
        rel, obj = sub.group(2), object_words(sub.group(3))  # the floor is no place
    obj = asides.qualifiers(obj)  # "a stool at the kitchen island": stool next to the island
    if obj and (not out.get("anchor") or out.get("relation") == "in" and obj not in ROOMS):
        if out.get("anchor") and out.get("relation") == "in":
            obj = f"{obj} in the {out['anchor']}"
        out["anchor"], out["relation"] = obj, rel


def _seat(phrase: str) -> bool:
    """Is it something one sits, lies or stands on (by the last word of its own name, before
    any relation: "lamp near the bed" is a lamp)?"""
    words = relation_phrases(phrase)[0].split()
    return bool(words) and words[-1] in SEATS


def read_situation(text: str) -> SituationReading:
    """The offline reading of a situation text (rules, no model).

    >>> r = read_situation("I am facing a bookshelf, and a lamp is on my right.")
    >>> (r.anchor, r.facing, [(c.object, c.side) for c in r.constraints])
    ('', 'bookshelf', [('lamp', 'right')])

    Raises:
        InvalidInputError: empty text.
    """
    if not isinstance(text, str) or not text.strip():
        raise InvalidInputError(
            "the situation text is empty; describe where you are, e.g. 'sitting on the "
            "bed, facing the window'."
        )
    out: dict[str, Any] = {}
    cons: list[Constraint] = []
    fronts: list[str] = []
    clauses = split_clauses(text)
    for i, clause in enumerate(clauses):
        if (
            asides.negated(clause)
            or asides.leading_adverbial(clause, i, len(clauses))
            or asides.of_another(clause)
            or asides.left_behind(clause)
        ):
            continue  # "i cannot see the tv", "after entering the room", "a mirror above it"
        clause = asides.without_lead_time(clause)
        clause = re.sub(r"^(?:and|while|with|but|so|also|then)\s+", "", clause)
        both = asides.either_side(clause)
        if both is not None:  # "a nightstand on either side of me"
            obj = object_words(both)
            cons += [Constraint(obj, side="left"), Constraint(obj, side="right")]
            continue
        if _egocentric(clause, cons, fronts):
            continue
        named = asides.introduced(clause)
        if named is not None:  # "there is a sofa against the wall (and i sit on it)"
            out["named"] = asides.qualifiers(object_words(named))
            place = asides.introduced_place(clause)
            out["named_place"] = object_words(place) if place is not None else None
            continue
        rest = _facing(clause, out, cons, fronts)
        if rest is not None:
            _position(rest, out)
    for obj, (kind, value) in out.get("ego", []):  # "the door that is on my right"
        if kind == "side":
            cons.append(Constraint(obj, side=value))  # type: ignore[arg-type]
        elif kind == "clock":
            cons.append(Constraint(obj, clock=_hour(value)))
        elif kind == "behind":
            cons.append(Constraint(obj, side="behind"))
        else:
            fronts.append(obj)
    facing = fronts[0] if fronts else None
    cons += [Constraint(f, side="front") for f in fronts[1:]]
    return SituationReading(
        anchor=out.get("anchor", ""),
        relation=out.get("relation", ""),
        posture=out.get("posture"),
        activity=out.get("activity"),
        near=tuple(out.get("near", ())),
        facing=facing,
        constraints=tuple(cons),
    )


def _egocentric(clause: str, cons: list[Constraint], fronts: list[str]) -> bool:
    """Read an egocentric clause ("the door is on my left", "behind me is the bed", "the
    lamp is at my 2 o'clock") into `cons`, or what is ahead into `fronts`; False when the
    clause is none."""
    for kind, pat in _PATTERNS:
        m = pat.match(clause)
        if not m:
            continue
        obj = object_words(asides.split_relative(m.group("x"))[0])
        if not obj or obj in ("i", "me", "it") or re.match(r"(?:i|we)\b", obj):
            continue  # "I am on the couch facing the tv in front of me": not an object
        if kind == "behind":
            cons.append(Constraint(obj, side="behind"))
        elif kind == "clock":
            hour = _hour(m.group("h"))
            if hour == 12:
                fronts.append(obj)
            else:
                cons.append(Constraint(obj, clock=hour))
        elif kind == "side":
            cons.append(Constraint(obj, side=m.group("s")))  # type: ignore[arg-type]
        else:
            fronts.append(obj)
        return True
    return False


def _facing(
    clause: str, out: dict[str, Any], cons: list[Constraint], fronts: list[str]
) -> str | None:
    """Read a facing clause ("facing the window", "watching tv on the couch") into `fronts`
    (or `cons`, facing away), and the position before or after it into `out`; None when
    read, else the clause (without a repeated "in front of me") for the position reader."""
    m = re.search(r"(?:^|\s)" + _FACE_VERB + r"\s+(?P<x>.+)$", clause)
    if m:  # "facing the tv (right) in front of me": the tail says it twice
        clause = re.sub(r"\s+" + _JUST + _AHEAD + r"$", "", clause)
        m = re.search(r"(?:^|\s)" + _FACE_VERB + r"\s+(?P<x>.+)$", clause)
    if not m:
        return clause
    before = clause[: m.start()].strip()
    target = asides.split_relative(m.group("x"))[0]
    verb = clause[m.start() : m.start("x")].strip()
    if not _LEAD.sub("", before).strip():
        # "Watching tv on the couch": the place after what is watched ("facing the
        # cabinet next to the fridge" is one object).
        split = re.match(r"^(.+?)\s+((?:on|at|from|in)\s+.+)$", target)
        if split and verb.startswith(("watching", "looking", "staring", "gazing")):
            target, before = split.group(1), "i am " + split.group(2)
    if verb.startswith("facing away"):
        cons.append(Constraint(object_words(target), side="behind"))
    elif object_words(target):
        fronts.append(object_words(target))
    if before:
        _position(before, out)
    return None
