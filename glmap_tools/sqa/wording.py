"""How people ask the round-two question families, and the words answers are made of.

`EARLY` is tried before `families.FAMILIES` (its patterns are narrower than the older ones
they would fall to: "can I see X if I turn around?" is no plain can-I-see, "how many
pillows on the bed?" no region count), `LATE` after them (broad yes/no shapes that the
older families must win first). `either_or` reads "is X A or B?" by what A and B are.

Families (named parts in brackets):

- turn_see: "can I see X if I turn around / to my left?" [object, turn];
- count_on: "how many X on the Y (at my two o'clock)?", "number of X on the Y?" [object,
  base, ego parts];
- divisible: "is the number of X (around me) divisible by three?" [object, k, ego parts];
- compare: "which is closer (to me), the X or the Y?", "is the X bigger than the Y?"
  [a, b, rel];
- which_side / up_down / state / either: "is X A or B?" with A, B directions (front,
  behind, left, right), heights (up, down, above, below), states (open, on, ...) or
  anything else (colours, shapes, tidy) [object, a, b];
- turn_angle: "how many degrees do I turn to face X?" [object];
- clock: "what is at my five o'clock?" [hour];
- attribute: "is the X round?", "is the X made of wood?", "does the X have armrests?"
  [object, value, part];
- direction (intents): "if I want to leave the room, which way should I go?" [intent or
  object];
- count (more forms): "how many chairs behind me?", "number of lamps on my left?", "how
  many chairs can I see?" [view], "how many lamps are there?" [around];
- on_exists: "is there anything on the table?" [base]; nearest: "what is the closest
  object to me?"; next_to / under: "what is next to / under the X?" [object]; material:
  "what is the X made of?" [object]; which_side: "where is the X?" [where, object].
"""

from __future__ import annotations

import re

from glmap_tools.sqa.question_parts import COUNT, EGO, HOUR, REL, SEE, THING, TURN, slot
from glmap_tools.sqa.question_parts import HOURS as HOURS
from glmap_tools.sqa.rewording import variants as variants

EARLY: list[tuple[str, re.Pattern[str]]] = [
    (
        "on_exists",
        re.compile(
            r"^(?:is|are) there (?:anything|something|any objects?|an object|things)"
            r"(?: (?:lying|sitting|standing|placed|resting|kept|left|put|set))? (?:on top of"
            r"|on|upon) (?:the |a |an )?(?P<base>[a-z][a-z -]*?)(?: " + EGO + r")?$"
        ),
    ),
    (
        "nearest",
        re.compile(
            r"^(?:what|which)"
            + THING
            + r"(?: is|'s) (?:the )?(?:closest|nearest)"
            + THING
            + r"(?: to me| from me)?$"
        ),
    ),
    (
        "turn_see",
        re.compile(r"^" + SEE + r" " + slot() + r" (?:if|when|after|once) " + TURN + r"\?*$"),
    ),
    (
        "turn_see",
        re.compile(r"^(?:if|when|after|once) " + TURN + r",? " + SEE + r" " + slot() + r"\?*$"),
    ),
    (
        "count_on",
        re.compile(
            r"^" + COUNT + r" " + slot() + r" (?:are |is )?(?:there )?(?:lying |sitting )?"
            r"(?:on top of|on|upon|atop) (?:the |a |an )?(?!my\b|me\b|either\b)"
            r"(?P<base>[a-z][a-z -]*?)(?: " + EGO + r")?\?*\.?$"
        ),
    ),
    (
        "divisible",
        re.compile(
            r"^(?:is|can|could) (?:the )?(?:number|amount|count) of "
            + slot()
            + r"(?: "
            + EGO
            + r")?"
            r" (?:be )?(?:evenly )?(?:divisible|divided|dividable) (?:evenly )?by (?P<k>\w+)\?*$"
        ),
    ),
    (
        "compare",
        re.compile(
            r"^(?P<which>which)(?: one| object| thing| of (?:the|them|these)(?: two)?)? (?:is )?"
            + REL
            + r"(?: away)?(?: to me| from me)?[,:]? "
            + slot("a")
            + r" or "
            + slot("b")
            + r"\?*$"
        ),
    ),
    (
        "compare",
        re.compile(
            r"^(?:is|are) "
            + slot("a")
            + r" "
            + REL
            + r"(?: away)?(?: (?:to|from) me)? than "
            + slot("b")
            + r"(?: (?:is|are))?(?: (?:to|from) me)?\?*$"
        ),
    ),
    (
        "which_side",
        re.compile(r"^(?:on )?which side (?:of me )?(?:is|are) " + slot() + r"(?: on)?\?*$"),
    ),
    (
        "up_down",
        re.compile(
            r"^(?:do|should|would|must|will) i (?:have to |need to )?look (?P<a>up|down)"
            r"(?: or (?P<b>up|down))?(?: to (?:see|find|look at|read))? " + slot() + r"\?*$"
        ),
    ),
    (
        "turn_angle",
        re.compile(
            r"^how (?:many degrees|much|far) (?:do|should|would|must|will) i (?:need to |have to )?"
            r"(?:turn|rotate)(?: myself)?(?: (?:around|left|right))?(?: to (?:face|see|look at|"
            r"get to|reach|be facing))? " + slot() + r"\?*$"
        ),
    ),
    (
        "clock",
        re.compile(
            r"(?:what|which)(?: kind of| type of| sort of| piece of)?(?: object| thing| furniture|"
            r" item)?(?: is| are| lies| stands| sits|'s| is there| are there| do i have"
            r"| (?:do|can|could|will|would) i (?:see|find|spot|notice))?(?: located| found)? "
            r"(?:at|in|on|to) (?:my |the )?" + HOUR + r" ?o'clock(?: direction| position)?\?*$"
        ),
    ),
]

# "is X A or B?": A, B one of these (or any one or two words, for either).
_OPTION = (
    r"(?:(?:on |to |at )?(?:my )?(?:left|right)(?:[- ]hand side| side)?|in front(?: of me)?|"
    r"ahead(?: of me)?|behind(?: me)?|at my back|(?:in )?(?:the )?back|(?:in )?(?:the )?front|"
    r"up|down|(?:above|below|under|over)(?: me| my (?:eyes|head))?|higher|lower|"
    r"(?:made of |of |a |an )?(?:light |dark |pale |bright |deep )?[a-z-]+(?: and [a-z-]+)?)"
)
EITHER = re.compile(
    r"^(?:is|are) "
    + slot()
    + r" (?P<a>"
    + _OPTION
    + r") or (?:is it |are they )?(?P<b>"
    + _OPTION
    + r")\?*$"
)
DIRECTION_WORDS = ("left", "right", "front", "ahead", "behind", "back")
HEIGHT_WORDS = ("up", "down", "above", "below", "under", "over", "higher", "lower")
STATE_WORDS = ("open", "opened", "closed", "shut", "on", "off")


def either_or(q: str) -> tuple[str, dict[str, str]] | None:
    """which_side / up_down / state / either for "is X A or B?", by what A and B are."""
    m = EITHER.match(q)
    if m is None:
        return None
    parts = {k: v for k, v in m.groupdict().items() if v}
    words = set(f"{parts['a']} {parts['b']}".split())
    if words & set(DIRECTION_WORDS):
        return "which_side", parts
    if words & set(HEIGHT_WORDS):
        return "up_down", parts
    if {parts["a"], parts["b"]} <= set(STATE_WORDS):
        return "state", parts
    return "either", parts


# What people want, and the object that serves it ("leave the room" -> the door).
INTENTS: tuple[tuple[str, str], ...] = (
    (r"leave|exit|go out|get out|walk out", "door"),
    (r"wash (?:my )?(?:hands|face)|brush (?:my )?teeth|wash the dishes|do the dishes", "sink"),
    (r"sleep|go to bed|lie down|take a nap|nap", "bed"),
    (r"watch (?:tv|television|a movie|the news)", "tv"),
    (r"cook|fry|boil", "stove"),
    (
        r"get (?:a |some )?(?:drink|milk|juice|food|something cold)|get something to (?:eat|drink)"
        r"|(?:grab|get|have) a snack|eat|have something to eat",
        "refrigerator",
    ),
    (r"take a shower|shower", "shower"),
    (r"take a bath|bathe", "bathtub"),
    (r"use the toilet|go to the toilet|pee", "toilet"),
    (r"read|find a book|get a book|borrow a book", "bookcase"),
    (r"throw (?:\w+ )?away|throw out|throw (?:something|this|it) out", "trash can"),
    (r"look out|see outside|open the window|look outside", "window"),
    (r"get dressed|hang (?:up )?(?:my|a) (?:coat|jacket)|change clothes", "wardrobe"),
    (r"work|study|write|use the computer|type", "desk"),
    (r"make coffee|have a coffee", "coffee machine"),
    (r"sit down|sit|take a seat|rest", "sofa|chair|armchair"),
)

_INTENT_ASK = (
    r"(?:(?:which|what) (?:way|direction|side)|where) (?:should|do|would|must|can|will) i "
    r"(?:go|turn|walk|head|move)(?: to)?"
)
LATE: list[tuple[str, re.Pattern[str]]] = [
    (
        "next_to",
        re.compile(
            r"^(?:what|which)" + THING + r"(?: is|'s| stands| sits)? (?:right |just )?(?:next to"
            r"|beside|by|near|close to|adjacent to) " + slot() + r"$"
            r"|^what (?:is|are) " + slot("object2") + r" (?:next to|beside|near|close to)$"
        ),
    ),
    (
        "between",
        re.compile(
            r"^(?:what|which)"
            + THING
            + r"(?: is|'s| stands| lies)? (?:right )?between "
            + slot("a")
            + r" and "
            + slot("b")
            + r"$"
        ),
    ),
    (
        "which_of",
        re.compile(
            r"^which(?: one| object| of (?:them|the two))? (?:is|lies|stands) "
            + EGO
            + r"[,:]? "
            + slot("a")
            + r" or "
            + slot("b")
            + r"$"
        ),
    ),
    (
        "under",
        re.compile(
            r"^(?:what|which)" + THING + r"(?: is|'s| lies| sits| stands)? (?:under|underneath|"
            r"beneath|below) " + slot() + r"$"
        ),
    ),
    (
        "material",
        re.compile(
            r"^(?:what|which) (?:material )?(?:is|are) " + slot() + r" made (?:of|from|out of)$"
            r"|^(?:what|which) material (?:is|are|does) "
            + slot("object2")
            + r"(?: made of| have)?$"
        ),
    ),
    (
        "count",
        re.compile(
            r"^how many " + slot() + r" (?:(?P<view>can i see|do i see|are visible|are in view)"
            r"(?: from here| right now)?|(?P<around>are there|is there|are here))$"
        ),
    ),
    ("which_side", re.compile(r"^(?P<where>where) (?:is|are) " + slot() + r"$")),
    ("shape", re.compile(r"^what is the (?:shape|form) of " + slot() + r"\?*$")),
    (
        "direction",
        re.compile(
            r"^(?:if|when|since) i (?:want|need|would like|wish|have) to (?P<intent>.+?),? "
            + _INTENT_ASK
            + r"\?*$"
        ),
    ),
    (
        "direction",
        re.compile(r"^i (?:want|need|would like) to (?P<intent>.+?)[;,.] " + _INTENT_ASK + r"\?*$"),
    ),
    (
        "direction",
        re.compile(
            r"^(?:where|which way|which direction) (?:do|should|would|must|can) i (?:need to |have"
            r" to )?(?:turn|go|walk|head|move)(?: to| in order to)? (?:get to|reach|find|go to|see|"
            r"face|sit on|sit in|use|open|look at) " + slot() + r"\?*$"
        ),
    ),
    (
        "direction",
        re.compile(
            r"^to (?:reach|get to|go to|find|see) " + slot() + r",? (?:should|do|must|would) i "
            r"(?:turn|go|walk) (?P<lr>left or right|right or left)\?*$"
        ),
    ),
    (
        "count",
        re.compile(
            r"^" + COUNT + r" " + slot() + r"(?: (?:are|is))?(?: there)?"
            r"(?: (?:can|do) i (?:see|have)| i can see| do you see)? " + EGO + r"\?*\.?$"
        ),
    ),
    (
        "attribute",
        re.compile(
            r"^(?:is|are) (?:the )?(?P<kind>shape|colou?r|material|size|style) of "
            + slot()
            + r" (?P<value>(?:light |dark |pale |bright )?[a-z-]+(?: and [a-z-]+)?)\?*$"
        ),
    ),
    (
        "attribute",
        re.compile(
            r"^(?:does|do) " + slot() + r" (?:have|has|come with|carry) (?:a |an |any |some )?"
            r"(?P<part>[a-z][a-z -]*?)\?*$"
        ),
    ),
    (
        "attribute",
        re.compile(
            r"^(?:is|are) (?!there\b|it\b)" + slot() + r" (?:made (?:of|from|out of) |of )?"
            r"(?:a |an )?(?P<value>(?:light |dark |pale |bright )?[a-z-]+(?: and [a-z-]+)?)\?*$"
        ),
    ),
]


def intent_object(intent: str) -> str:
    """The object an intent needs ("leave the room" -> "door"); the intent's own object
    words when it names one ("go to the sofa" -> "sofa"), else the intent."""
    named = re.search(r"\b(?:to|at|on|in|the) (?:the )?([a-z][a-z -]*)$", intent)
    for pattern, obj in INTENTS:
        if re.match(rf"(?:{pattern})\b", intent):
            return obj
    return named.group(1) if named else intent
