"""What people write around a situation's parts, taken apart before the clauses are read.

- relative clauses inside an object phrase: "the door that is on my right" is the door
  plus a constraint (door, right); "the shelf where the books are kept", "the chair that
  is closest to the door" are the shelf and the chair (the clause is dropped);
- egocentric tails: "within arm's reach" (and a duration, "for an hour") says nothing
  about a side and goes; "by my left
  foot", "by my right hand" are the left and the right side;
- negation: "I cannot see the tv", "I don't see the sink" say where I am not looking and
  give no position, facing or constraint;
- leading adverbial clauses: "After entering the room, ...", "While waiting for the
  kettle, ..." set the scene; the place comes after them;
- "on either side of me": one object on my left and one on my right;
- "on the other side of the room": across the room from me, in front;
- a comma-set relative clause on the last object, ", which is to my left": the object's
  side, as if written "the dishwasher to my left"; any other one gives no place;
- the anchor's own relations ("a stool at the kitchen island", "the chair closest to the
  fireplace", "the rug between the sofa and the fireplace"): said in the words the
  locator reads ("next to", "near"), so the anchor's name stays the object's;
- an activity on an object in place ("watering the plant near the window"): the object
  worked on is where I am, not the thing it is near.

Pure string functions over lower-cased text; `glmap_tools.sqa.reading` applies them.
"""

from __future__ import annotations

import re

_EGO_SIDE = r"(?:to|on|at|by) (?:my|the) (?P<s>left|right)(?:[- ]hand)?(?: side)?(?: of me)?"
_EGO_HOUR = (
    r"(?:at|in|on|to) (?:my |the )?(?P<h>\d{1,2}|one|two|three|four|five|six|seven|eight|"
    r"nine|ten|eleven|twelve)\s*o'clock(?: (?:direction|position))?"
)
_EGO_BEHIND = r"(?P<b>behind me|at my back)"
_EGO_FRONT = r"(?P<f>in front of me|ahead of me|straight ahead)"
EGO = r"(?:" + _EGO_SIDE + "|" + _EGO_HOUR + "|" + _EGO_BEHIND + "|" + _EGO_FRONT + ")"

# "that is on my right", "which stands behind me", "that i have to my left", or the place
# alone ("the window to my left"), but not "to the left of the fridge"
_REL_EGO = re.compile(
    r"^(?P<head>.+?)\s+(?:(?:that|which|who)\s+(?:(?:is|are|stands|sits|lies|hangs|i have)\s+)?)?"
    r"(?:located\s+|placed\s+|right\s+|directly\s+|just\s+)?" + EGO + r"(?! of\b)(?P<rest>.*)$"
)
# Any other relative clause ends the object's words: "the shelf where the books are kept".
_REL_ANY = re.compile(
    r"\s+(?:that|which|who|where|whose)\s+(?!is (?:next to|near|beside|by|on|in)\b).*$"
)
# "that is next to the fridge": a relation the locator uses ("cabinet next to the fridge").
_REL_KEEP = re.compile(r"\s+(?:that|which) is (next to|near|beside|by|on|in)\s+")
# Words that add nothing about where the object is.
_REACH = re.compile(
    r"(?:\s+with\s+(?:(?!\bwith\b)[\w' -])+?)?"  # "with the remote within arm's reach"
    r"\s+(?:(?:within|in) (?:arm'?s'? |my )?reach|within arm'?s'? length|close at hand)\b"
)
# How long or how often: "for an hour", "for a while", "all evening" say nothing of where.
_DURATION = re.compile(
    r"\s+(?:for (?:a|an|the|some|about|almost|over|nearly|several|a few|\d+|one|two|three|"
    r"five|ten|twenty)(?: \w+)?? (?:while|moment|minute|minutes|hour|hours|time|bit|second|"
    r"seconds|day|days|now)|all (?:day|evening|morning|night|afternoon)(?: long)?)\b"
)
_LIMB = re.compile(r"\bby my (?P<s>left|right) (?:foot|feet|hand|arm|elbow|shoulder|leg|knee)\b")
NEGATION = re.compile(
    r"\b(?:not|n't|cannot|never|no longer|nowhere)\b|\b(?:can|do|does|is|am|are)not\b"
)
_LEADING = re.compile(
    r"^(?:after|before|while|whilst|when|once|upon|having|as soon as|as|since|just after)\b"
)
EITHER = re.compile(r"\bon (?:either|both|each) side(?:s)? of me\b")
# Where another thing is from the one just named: "and the mirror is above it".
_OF_IT = re.compile(
    r"^(?:the |a |an |some )?[\w' -]+? (?:is|are|hangs?|sits?|stands?|lies|lie|rests?)"
    r"(?: right| just| directly)? (?:above|over|below|under|underneath|beneath|next to|beside|"
    r"on top of|on|behind|in front of|inside|in) (?:it|them)$"
)
# A time before "i" with no verb of its own: "after my shower i am drying off ...".
_LEAD_TIME = re.compile(
    r"^(?:after|before|during) (?:my |the |a |an |our )?(?:\w+ ){0,2}?\w+,? (?=i\b|i'm\b)"
)
# What covers me, not where: "on the bed under the duvet".
COVERED = re.compile(
    r"\s+under (?:the|a|an|my) (?:duvet|blanket|quilt|covers|sheets|comforter|throw)s?\b.*$"
)
# Verbs that act on a thing where it stands: I am at what I water, wipe or open.
IN_PLACE = (
    "watering|wiping|cleaning|dusting|polishing|fixing|repairing|opening|closing|adjusting|"
    "inspecting|examining|unlocking|locking|scrubbing|mopping|vacuuming|tidying|checking"
)
NEAR_WORDS = ("near", "next to", "right next to", "beside", "besides", "by", "close to")
_RELATIVE_EGO = re.compile(
    r"^(?:which|that|who)\s+(?:(?:is|are|stands|sits|lies|hangs)\s+)?"
    r"(?:located\s+|placed\s+|right\s+|directly\s+|just\s+)?(?P<ego>" + EGO + r")$"
)
RELATIVE = re.compile(r"^(?:which|that|who|where|whose)\b")
ACROSS = re.compile(r"\b(?:on|at|to) the (?:other|opposite|far) (?:side|end) of the room\b")


def hands_to_sides(text: str) -> str:
    """'by my left foot' -> 'on my left'; 'within arm's reach' and 'for an hour' dropped."""
    text = _LIMB.sub(lambda m: f"on my {m.group('s')}", text)
    return _DURATION.sub("", _REACH.sub("", text))


def side_words(text: str) -> str:
    """One wording per side: 'towards my left' and 'to the left of me' -> 'to my left';
    'beside me on my right' -> 'on my right'."""
    text = re.sub(r"\btowards? (?:my|the) (left|right)\b", r"to my \1", text)
    text = re.sub(r"\b(on|to) the (left|right)(?:[- ]hand side| side)? of me\b", r"\1 my \2", text)
    return re.sub(
        r"\b(?:right |just )?(?:next to|beside|by|near|close to) me,? "
        r"((?:on|to|at) my (?:left|right))\b",
        r"\1",
        text,
    )


def negated(clause: str) -> bool:
    """Does the clause deny something ("i cannot see the tv", "the door is not open")?"""
    return bool(NEGATION.search(clause.replace("can't", "can not").replace("n't", " not")))


PRONOUNS = ("it", "them", "this", "that", "this one", "that one", "one of them", "one of those")
_THERE_IS = re.compile(
    r"^there (?:is|are) (?P<x>(?:(?:a|an|one|some|the|two|three|four|several|a few) )?[a-z].+)$"
    # "the cat is on the bed": a scene around me, said of something else
    r"|^(?P<y>(?:the|a|an|my) [\w' -]+?) (?:is|are) (?:[a-z]+ed (?:back |up |out |away )?)?"
    r"(?:on|in|at|by|next to|near|under|above|beside|against|behind|in front of|inside|from"
    r"|across from|opposite(?: to)?|to the (?:left|right) of) (?P<z>(?:the|a|an|my) .+)$"
)
# Where I was, not where I am: "i just got off the couch".
_LEFT = re.compile(
    r"^i (?:just |have just |had )?(?:got off|got up from|got out of|left|stepped off|stepped out"
    r" of|came out of|walked away from|came from)\b"
)


def introduced(clause: str) -> str | None:
    """The thing a "there is ..." clause brings in, when I am not in it ("there is a sofa
    against the wall", "there is a mat under my feet"); a later "it" is that thing."""
    m = _THERE_IS.match(clause)
    if m is None or re.search(r"\bi\b", clause):  # egocentric ones are read before
        return None
    return m.group("x") or m.group("y")


# How I came, naming no place: "i have just walked in", "i got home".
_CAME = re.compile(
    r"^i (?:have |had )?(?:just |only just )?(?:walked|came|come|got|stepped|wandered|arrived"
    r"|moved|entered)(?: (?:in|inside|back|home|here|over|up|down))?(?: (?:in|inside|home|here))?"
    r"(?: now)?$"
)


def introduced_place(clause: str) -> str | None:
    """What the thing a scene clause brings in stands by ("the lamp is next to the sofa":
    the sofa), or None."""
    m = _THERE_IS.match(clause)
    if m is None or m.group("z") is None or re.search(r"\bi\b", clause):
        return None
    return m.group("z")


def left_behind(clause: str) -> bool:
    """Does the clause say where I was ("i just got off the couch") or only that I came ("i
    have just walked in")? It is not where I am."""
    return bool(_LEFT.match(clause) or _CAME.match(clause))


def of_another(clause: str) -> bool:
    """Does the clause place another thing by the one just named ("the mirror is above
    it")? It says nothing of where I am."""
    return bool(_OF_IT.match(clause))


def without_lead_time(clause: str) -> str:
    """The clause without a leading time that has no verb ("before dinner i am ...")."""
    return _LEAD_TIME.sub("", clause)


def leading_adverbial(clause: str, index: int, count: int) -> bool:
    """A leading "after ...", "while ..." clause that only sets the scene: the first clause
    of several, without "i" in it ("while waiting for the kettle", "after entering")."""
    if index != 0 or count < 2 or not _LEADING.match(clause):
        return False
    return not re.search(r"\b(?:i|i am|my)\b", clause)


def split_relative(phrase: str) -> tuple[str, tuple[str, str] | None]:
    """(object words, an egocentric part or None) of an object phrase with a relative clause.

    The egocentric part is ("side", "left"/"right"), ("clock", hour word), ("behind", "")
    or ("front", "").

    >>> split_relative("the door that is on my right")
    ('the door', ('side', 'right'))
    >>> split_relative("the shelf where the books are kept")
    ('the shelf', None)
    """
    m = _REL_EGO.match(phrase)
    if m:
        if m.group("s"):
            ego: tuple[str, str] = ("side", m.group("s"))
        elif m.group("h"):
            ego = ("clock", m.group("h"))
        elif m.group("b"):
            ego = ("behind", "")
        else:
            ego = ("front", "")
        return m.group("head").strip(), ego
    phrase = _REL_KEEP.sub(lambda k: f" {k.group(1)} ", phrase)
    return _REL_ANY.sub("", phrase).strip(), None


def either_side(clause: str) -> str | None:
    """The object of "X on either side of me" / "on either side of me is X", else None."""
    if not EITHER.search(clause):
        return None
    rest = EITHER.sub(" ", clause)
    rest = re.sub(
        r"^\s*(?:with |there (?:is|are) |there's |i have |i see )?|\s+(?:is|are|stands)\s*$",
        "",
        rest.strip(),
    )
    rest = re.sub(r"^(?:is|are|there (?:is|are))\s+", "", rest.strip())
    return rest.strip() or None


def relative_ego(clause: str) -> str | None:
    """The egocentric place of a comma-set relative clause (", which is to my left" ->
    "to my left"), else None."""
    m = _RELATIVE_EGO.match(clause.strip())
    return m.group("ego") if m else None


def qualifiers(obj: str) -> str:
    """An anchor's own relations in the words the locator reads.

    >>> qualifiers("stool at the kitchen island")
    'stool next to the kitchen island'
    >>> qualifiers("rug between the sofa & the fireplace")
    'rug near the sofa near the fireplace'
    >>> qualifiers("chair closest to the fireplace")
    'chair near the fireplace'
    """
    obj = re.sub(
        r"(?<=\w) between (?:the |a |an )?([\w -]+?) & (?:the |a |an )?([\w -]+)$",
        r" near the \1 near the \2",
        obj,
    )
    obj = re.sub(
        r"(?<=\w) (?:(?:that|which) is )?(?:closest|nearest|closer|nearer|close) to (?:the|a|an) ",
        " near the ",
        obj,
    )
    obj = re.sub(r"(?<=\w) (?:nearest|closest) (?:the|a|an) ", " near the ", obj)
    # "the shelf against the wall", "the cupboard above the stove", "the wall opposite the
    # window", "the stool in front of the island": the locator reads them as near
    obj = re.sub(
        r"(?<=\w) (?:against|above|over|below|under|underneath|beneath|opposite(?: to)?"
        r"|across from|in front of|to the (?:left|right)(?: side)? of) (?:the|a|an) ",
        " near the ",
        obj,
    )
    return re.sub(r"(?<=\w) (?:at|by) (?:the|a|an) ", " next to the ", obj)
