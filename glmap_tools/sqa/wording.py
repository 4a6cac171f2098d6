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

from glmap_tools.sqa.situation_words import HOUR_WORDS

HOURS = HOUR_WORDS[1:]  # one .. twelve
_HOUR = r"(?P<hour>\d{1,2}|" + "|".join(HOURS) + r")"
# An egocentric place: a side, behind, in front, around, or a clock hour.
EGO = (
    r"(?:(?:on|to|at) (?:my|the) (?P<side>left|right)(?:[- ]hand)?(?: side)?(?: of me)?"
    r"|(?P<behind>behind me|at my back)|(?P<front>in front of me|ahead of me|before me)"
    r"|(?P<around>around me|near me|nearby|close to me|in (?:this|the) room|here|in here)"
    r"|(?:at|in|on|to) (?:my |the )?" + _HOUR + r" ?o'clock(?: direction| position)?)"
)
_DET = r"(?:the |a |an |any |some |another |other |all (?:the )?)*"


def _obj(name: str = "object") -> str:
    return _DET + rf"(?P<{name}>[a-z][a-z -]*?)"


_TURN = (
    r"(?:i )?(?:turn|turning|rotate|rotating|spin|spinning)(?: myself)?(?: (?P<turn>around|back|"
    r"180 degrees|(?:90 degrees )?(?:to )?(?:my |the )?(?:left|right)))"
)
_SEE = r"(?:can|could|will|would|do) i (?:be able to )?(?:see|spot|view|notice|face)"
_REL = (
    r"(?P<rel>closer|nearer|farther|further|bigger|larger|smaller|taller|shorter|higher|"
    r"lower|wider|longer|heavier)"
)
_COUNT = r"(?:how many|what is the number of|the number of|number of|count(?: the)?)"

_THING = r"(?: object| thing| item| piece of furniture| furniture)?"
EARLY: list[tuple[str, re.Pattern[str]]] = [
    (
        "on_exists",
        re.compile(
            r"^(?:is|are) there (?:anything|something|any objects?|an object|things) (?:on top of"
            r"|on|upon) (?:the |a |an )?(?P<base>[a-z][a-z -]*?)(?: " + EGO + r")?$"
        ),
    ),
    (
        "nearest",
        re.compile(
            r"^(?:what|which)"
            + _THING
            + r"(?: is|'s) (?:the )?(?:closest|nearest)"
            + _THING
            + r"(?: to me| from me)?$"
        ),
    ),
    (
        "turn_see",
        re.compile(r"^" + _SEE + r" " + _obj() + r" (?:if|when|after|once) " + _TURN + r"\?*$"),
    ),
    (
        "turn_see",
        re.compile(r"^(?:if|when|after|once) " + _TURN + r",? " + _SEE + r" " + _obj() + r"\?*$"),
    ),
    (
        "count_on",
        re.compile(
            r"^" + _COUNT + r" " + _obj() + r" (?:are |is )?(?:there )?(?:lying |sitting )?"
            r"(?:on top of|on|upon|atop) (?:the |a |an )?(?!my\b|me\b|either\b)"
            r"(?P<base>[a-z][a-z -]*?)(?: " + EGO + r")?\?*\.?$"
        ),
    ),
    (
        "divisible",
        re.compile(
            r"^(?:is|can|could) (?:the )?(?:number|amount|count) of "
            + _obj()
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
            + _REL
            + r"(?: away)?(?: to me| from me)?[,:]? "
            + _obj("a")
            + r" or "
            + _obj("b")
            + r"\?*$"
        ),
    ),
    (
        "compare",
        re.compile(
            r"^(?:is|are) "
            + _obj("a")
            + r" "
            + _REL
            + r"(?: away)?(?: (?:to|from) me)? than "
            + _obj("b")
            + r"(?: (?:is|are))?(?: (?:to|from) me)?\?*$"
        ),
    ),
    (
        "which_side",
        re.compile(r"^(?:on )?which side (?:of me )?(?:is|are) " + _obj() + r"(?: on)?\?*$"),
    ),
    (
        "up_down",
        re.compile(
            r"^(?:do|should|would|must|will) i (?:have to |need to )?look (?P<a>up|down)"
            r"(?: or (?P<b>up|down))?(?: to (?:see|find|look at|read))? " + _obj() + r"\?*$"
        ),
    ),
    (
        "turn_angle",
        re.compile(
            r"^how (?:many degrees|much|far) (?:do|should|would|must|will) i (?:need to |have to )?"
            r"(?:turn|rotate)(?: myself)?(?: (?:around|left|right))?(?: to (?:face|see|look at|"
            r"get to|reach|be facing))? " + _obj() + r"\?*$"
        ),
    ),
    (
        "clock",
        re.compile(
            r"(?:what|which)(?: kind of| type of| sort of| piece of)?(?: object| thing| furniture|"
            r" item)?(?: is| are| lies| stands| sits|'s| is there| are there| do i have"
            r"| (?:do|can|could|will|would) i (?:see|find|spot|notice))?(?: located| found)? "
            r"(?:at|in|on|to) (?:my |the )?" + _HOUR + r" ?o'clock(?: direction| position)?\?*$"
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
    + _obj()
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
    (r"get (?:a |some )?(?:drink|milk|juice|food|something cold)|grab a snack", "refrigerator"),
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
    r"(?:which|what) (?:way|direction|side) (?:should|do|would|must|can|will) i (?:go|turn|walk"
    r"|head|move)(?: to)?"
)
LATE: list[tuple[str, re.Pattern[str]]] = [
    (
        "next_to",
        re.compile(
            r"^(?:what|which)" + _THING + r"(?: is|'s| stands| sits)? (?:right |just )?(?:next to"
            r"|beside|by|near|close to|adjacent to) " + _obj() + r"$"
            r"|^what (?:is|are) " + _obj("object2") + r" (?:next to|beside|near|close to)$"
        ),
    ),
    (
        "between",
        re.compile(
            r"^(?:what|which)"
            + _THING
            + r"(?: is|'s| stands| lies)? (?:right )?between "
            + _obj("a")
            + r" and "
            + _obj("b")
            + r"$"
        ),
    ),
    (
        "which_of",
        re.compile(
            r"^which(?: one| object| of (?:them|the two))? (?:is|lies|stands) "
            + EGO
            + r"[,:]? "
            + _obj("a")
            + r" or "
            + _obj("b")
            + r"$"
        ),
    ),
    (
        "under",
        re.compile(
            r"^(?:what|which)" + _THING + r"(?: is|'s| lies| sits| stands)? (?:under|underneath|"
            r"beneath|below) " + _obj() + r"$"
        ),
    ),
    (
        "material",
        re.compile(
            r"^(?:what|which) (?:material )?(?:is|are) " + _obj() + r" made (?:of|from|out of)$"
            r"|^(?:what|which) material (?:is|are|does) "
            + _obj("object2")
            + r"(?: made of| have)?$"
        ),
    ),
    (
        "count",
        re.compile(
            r"^how many " + _obj() + r" (?:(?P<view>can i see|do i see|are visible|are in view)"
            r"(?: from here| right now)?|(?P<around>are there|is there|are here))$"
        ),
    ),
    ("which_side", re.compile(r"^(?P<where>where) (?:is|are) " + _obj() + r"$")),
    ("shape", re.compile(r"^what is the (?:shape|form) of " + _obj() + r"\?*$")),
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
            r"face|sit on|sit in|use|open|look at) " + _obj() + r"\?*$"
        ),
    ),
    (
        "direction",
        re.compile(
            r"^to (?:reach|get to|go to|find|see) " + _obj() + r",? (?:should|do|must|would) i "
            r"(?:turn|go|walk) (?P<lr>left or right|right or left)\?*$"
        ),
    ),
    (
        "count",
        re.compile(
            r"^" + _COUNT + r" " + _obj() + r"(?: (?:are|is))?(?: there)?"
            r"(?: (?:can|do) i (?:see|have)| i can see| do you see)? " + EGO + r"\?*\.?$"
        ),
    ),
    (
        "attribute",
        re.compile(
            r"^(?:is|are) (?:the )?(?P<kind>shape|colou?r|material|size|style) of "
            + _obj()
            + r" (?P<value>(?:light |dark |pale |bright )?[a-z-]+(?: and [a-z-]+)?)\?*$"
        ),
    ),
    (
        "attribute",
        re.compile(
            r"^(?:does|do) " + _obj() + r" (?:have|has|come with|carry) (?:a |an |any |some )?"
            r"(?P<part>[a-z][a-z -]*?)\?*$"
        ),
    ),
    (
        "attribute",
        re.compile(
            r"^(?:is|are) (?!there\b|it\b)" + _obj() + r" (?:made (?:of|from|out of) |of )?"
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


# Other wordings of the same questions, tried in turn when a question as written falls to
# no family (`answer.question_type`): contractions, polite wrappers and embedded questions,
# synonyms, and fronted phrases moved to the end.
_CONTRACTIONS = (
    (r"\bwhat's\b", "what is"),
    (r"\bwhere's\b", "where is"),
    (r"\bwhich's\b", "which is"),
    (r"\bthere's\b", "there is"),
    (r"\bit's\b", "it is"),
    (r"\bthat's\b", "that is"),
    (r"\bi'm\b", "i am"),
    (r"\bi've\b", "i have"),
    (r"\bi'd\b", "i would"),
    (r"\bcan't\b", "cannot"),
)
_WRAPPER = re.compile(
    r"^(?:please,? )?(?:(?:can|could|would|will) you (?:please )?(?:tell me|let me know|say|check"
    r"|see)|(?:please )?(?:tell me|let me know)|(?:do|would) you (?:happen to )?know"
    r"|i (?:want|would like|need) to know|i wonder)(?: please)?[,:]? "
)
_QWORD = r"(?:what|which|where|how|is|are|can|could|do|does|should|would|will|am|shall|must)\b"
_BE = r"(?:is|are)"
_SYNONYMS = (
    # "can you count the pillows around me", "please count how many chairs there are"
    (r"^(?:please,? )?(?:(?:can|could|would|will) you (?:please )?)?count (?=how many\b)", ""),
    (r"^(?:please,? )?(?:(?:can|could|would|will) you (?:please )?)?(?=count\b)", ""),
    (r"^(how many [a-z][a-z -]*?) there (is|are)$", r"\1 \2 there"),
    (
        r"\b(?:am i able to|is it possible (?:for me )?to|would i be able to|will i be able to"
        r"|could i be able to)\b",
        "can i",
    ),
    (
        r"^(?:would|will|could|is|are) (?:the |a |an )?([a-z][a-z -]*?) (?:be )?(?:visible|in view)"
        r" (if|when|after|once) ",
        r"can i see the \1 \2 ",
    ),
    (r"\b(?:if|when|once) i (?:turned|were to turn|was to turn)\b", "if i turn"),
    (
        r"^(if|when|since) i (?:wanted|wished|needed|would want|would like|had) to\b",
        r"\1 i want to",
    ),
    (r"^in (which|what) (direction|way)\b", r"\1 \2"),
    (r"^by how (many degrees|much|far)\b", r"how \1"),
    (
        r"\bfrom where i(?: am)?(?: standing| sitting| seated| lying| stand| sit| lie)?$",
        "from here",
    ),
    (
        r"^(?:does|do) (?:the |a |an )?([a-z][a-z -]*?) (?:look|seem|appear)(?: to be)? ",
        r"is the \1 ",
    ),
    (r"^how (?:do|can|should|would) i (?:get|go|walk) to ", "which way should i go to get to "),
    (
        r"^(?:where|which way|which direction) (?:should|do|can|would|must) i (?:go|turn|walk|head)"
        r"(?: to| in order to) (?!(?:the|a|an|get to|reach|find|see|face)\b)(.+)$",
        r"if i want to \1, which way should i go",
    ),
    (r" (?:in total|altogether|in all|overall)$", ""),
    (
        r"^how many ([a-z][a-z -]*?) (?:does|do) (?:this|the) room (?:have|contain|hold)$",
        r"how many \1 are there",
    ),
    (
        r"^(how many [a-z][a-z -]*?) (?:(?:are|is) )?(?:hanging|standing|sitting|lying|placed"
        r"|located|kept|set|positioned|resting|lie|sit|stand|rest|hang)"
        r" (on|upon|atop|on top of|to|at|in|behind|around|near) ",
        r"\1 are \2 ",
    ),
    (r"^(?:which|what)(?: one| object| thing)? (?:would|will|could|might) be ", "which is "),
    (r"^what(?: one| object| thing)? is (" + _REL[len("(?P<rel>") : -1] + r")\b", r"which is \1"),
)
# "among / out of / of / between the X and the Y, which ...?": the options go to the end.
_OPTIONS_FIRST = re.compile(
    r"^(?:among|amongst|out of|of|between|from|comparing) (?:the two,? )?"
    r"((?:the |a |an )?[a-z][a-z -]*?) and ((?:the |a |an )?[a-z][a-z -]*?),? ((?:which|what)\b.+)$"
)
# "which is closer to me between / among / out of the X and the Y?"
_OPTIONS_LAST = re.compile(
    r"^((?:which|what)\b.+?),? (?:between|among|amongst|out of|of) (?:the two,? )?"
    r"((?:the |a |an )?[a-z][a-z -]*?) and ((?:the |a |an )?[a-z][a-z -]*?)$"
)
_WHICH_OF = re.compile(
    r"^which of ((?:the |a |an )?[a-z][a-z -]*?) and ((?:the |a |an )?[a-z][a-z -]*?) (is|are"
    r"|lies|stands) (.+)$"
)
# A place or purpose before the question: "on my left, what is there?", "to see the clock,
# should I look up or down?".
_FRONTED = re.compile(
    r"^((?:on|to|at) (?:my|the) (?:left|right)(?:[- ]hand side| side)?|behind me|at my back"
    r"|in front of me|ahead of me|straight ahead|(?:at|in|on) (?:my |the )?[a-z0-9]+ ?o'clock"
    r"(?: position| direction)?),? (" + _QWORD + r".+)$"
    r"|^([^,]+), (" + _QWORD + r".+)$"
)


def _unwrap(q: str) -> str:
    """A polite wrapper off, an embedded question put back in question order."""
    bare = _WRAPPER.sub("", q)
    if bare == q:
        return q
    m = re.match(
        r"^(?:(?:whether|if|that) (.+?)|((?:the|a|an|this|that|my) .+?)) (" + _BE + r") (.+)$", bare
    )
    if m:  # "whether the door is closed", "(would you say) the sofa is blue" -> "is the ..."
        return f"{m.group(3)} {m.group(1) or m.group(2)} {m.group(4)}"
    m = re.match(
        r"^((?:what|which)(?: kind of| type of| sort of)?(?: [a-z]+)?) (the .+) (" + _BE + r")$",
        bare,
    )
    if m:  # "what colour the sofa is" -> "what colour is the sofa"
        return f"{m.group(1)} {m.group(3)} {m.group(2)}"
    return bare


def variants(q: str) -> list[str]:
    """Other wordings of a lower-cased question, each ending in '?', most literal first."""
    q = q.strip(" ?.!")
    for pattern, repl in _CONTRACTIONS:
        q = re.sub(pattern, repl, q)
    q = re.sub(r"\s*,?\s*please$", "", _unwrap(q))
    q = re.sub(r",? or (?=(?:is it|are they|is that|are these) )|, or ", " or ", q)
    for pattern, repl in _SYNONYMS:
        q = re.sub(pattern, repl, q)
    out = [q]
    m = _OPTIONS_FIRST.match(q)
    if m:
        out.append(f"{m.group(3)}, {m.group(1)} or {m.group(2)}")
    m = _OPTIONS_LAST.match(q)
    if m:
        out.append(f"{m.group(1)}, {m.group(2)} or {m.group(3)}")
    m = _WHICH_OF.match(q)
    if m:  # "which of the X and the Y is closer" -> "which is closer, the X or the Y"
        out.append(f"which {m.group(3)} {m.group(4)}, {m.group(1)} or {m.group(2)}")
    m = _FRONTED.match(q)
    if m:
        front, rest = (m.group(1), m.group(2)) if m.group(1) else (m.group(3), m.group(4))
        out.append(f"{rest} {front}")
    return [v + "?" for v in out]
