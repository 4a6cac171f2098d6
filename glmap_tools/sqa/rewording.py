"""Other wordings of the same questions (`glmap_tools.sqa.wording`), tried in turn when a
question as written falls to no family (`answer.question_type`): contractions, polite
wrappers and embedded questions, synonyms, and fronted phrases moved to the end.
`plain_question` first takes off what would mislead the families as written: a time tail
("right now"), "in between", "my eye level", an odd-or-even count asked as "are there",
a yes/no side asked of "the X", and a turn asked after its question."""

from __future__ import annotations

import re
from collections.abc import Callable

from glmap_tools.sqa.question_parts import REL

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
# How one feels, before asking where to go: "i am thirsty; which way should i go?"
FEELINGS = {
    "hungry": "get something to eat",
    "thirsty": "get a drink",
    "tired": "sleep",
    "sleepy": "sleep",
}
_FEELING = (
    r"^i am (?:so |very |really |quite |a bit |a little |getting )?(?P<feeling>"
    + "|".join(FEELINGS)
    + r")(?: now)?[;,.:!] "
)
_SYNONYMS: tuple[tuple[str, str | Callable[[re.Match[str]], str]], ...] = (
    (
        _FEELING + r"(?:where|which way|which direction) (?:should|do|can|would|must) i "
        r"(?:go|head|walk|turn)$",
        lambda m: f"if i want to {FEELINGS[m.group('feeling')]}, which way should i go",
    ),
    (_FEELING, ""),  # the question after it says what for
    # "could I touch the lamp without getting up?"
    (r"^(?:could|would) i (?=(?:touch|reach|grab|pick up|put my hand on|get to)\b)", "can i "),
    (r"^what is the material of ", "what material is "),
    (
        r"^what is the (?:object|thing|item|furniture)"
        r" (?=(?:at|on|in|to) (?:my |the )?\S+ ?o'clock)",
        "what is ",
    ),
    (
        r"^(?:which|what) (?:way|direction) (?:to|towards?) (?:the )?",
        "which way should i go to get to the ",
    ),
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
    # "do I go left or right to reach the sink?"
    (
        r"^(?:do|would|must|shall|can) i (?:need to |have to )?(?:(go|walk)|head|move|(turn))"
        r" (left or right|right or left)\b",
        lambda m: f"should i {m.group(2) or 'go'} {m.group(3)}",
    ),
    (r"^what(?: one| object| thing)? is (" + REL[len("(?P<rel>") : -1] + r")\b", r"which is \1"),
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


# Said of the question, not of what it asks: "is the window open right now?"
_TIME_TAIL = re.compile(r",? (?:right now|at the moment|at present|currently|just now)(?=[?.!]*$)")
_NORMAL: tuple[tuple[str, str | Callable[[re.Match[str]], str]], ...] = (
    (r" (?:in total|altogether|in all)(?=[?.!]*$)", ""),  # "how many ... in total"
    (r"\bin between\b", "between"),
    (
        r"\bto where (?:i am|i'm|i stand|i sit|i)(?: standing| sitting| seated)?(?=[?.!]*$)",
        "to me",
    ),
    (r"\b(if|when|once) i (?:turned|were to turn|was to turn)\b", r"\1 i turn"),
    # "is the picture above me?": whether to look up
    (
        r"^(?:is|are) (?:the )?((?:(?!\bor\b)[a-z -])+?) (above|over|below|under|beneath) me"
        r"(?=[?.!]*$)",
        lambda m: (
            f"should i look {'up' if m.group(2) in ('above', 'over') else 'down'} to see "
            f"the {m.group(1)}"
        ),
    ),
    (r"\b(above|below|under|over) (?:my )?eye[- ]?(?:level|line)\b", r"\1 my eyes"),
    # "is the clock above my eye level or below it?": the options together, as they are read
    (
        r"^(is|are) (the (?:(?!\bor\b)[a-z -])+?) (above|below|over|under) my eyes or"
        r" (above|below|over|under)(?: it| them| my eyes)?(?=[?.!]*$)",
        r"\1 \2 \3 or \4 my eyes",
    ),
    # "what's sitting off to my right?", "what is placed on the shelf?"
    (
        r"^(what(?: object| thing)?(?: is|'s)) (?:(?:sitting|standing|lying|located|placed|kept"
        r"|hanging|resting) )?(?:(?:way )?(?:off|over) )?(?=(?:on|to|at|in|behind|next to|by) )",
        r"\1 ",
    ),
    (r"\bbehind my back\b", "behind me"),
    (r"\bcan i (?:spot|notice|make out|glimpse)\b", "can i see"),
    # "what object is at 3 o'clock from me?"
    (
        r"\b(o'? ?clock)(?: (?:from|relative to|in relation to) (?:me|here|where i(?:'m| am)?"
        r"(?: standing| sitting)?))(?=[?.!]*$)",
        r"\1",
    ),
    (
        r"^(is|are) (anything|something) (?:(?:sitting|lying|placed|kept|resting|standing) )?"
        r"(?=(?:on|in|under|inside) )",
        r"\1 there \2 ",
    ),
    # "are the curtains drawn?", "is the lamp lit?"
    (
        r"^(is|are) (the (?:curtains?|blinds?|drapes?|shades?)) (?:drawn|pulled)(?: shut| closed)?"
        r"(?=[?.!]*$)",
        r"\1 \2 closed",
    ),
    (r"^(is|are) (the (?:(?!\bor\b)[a-z -])+?) (?:lit|lit up)(?=[?.!]*$)", r"\1 \2 on"),
    # "are there an odd or even number of lamps?"
    (
        r"^(?:are|is) there an? (?:odd|even) or (?:an? )?(?:even|odd) number of (.+?)(?=[?.!]*$)",
        r"is the number of \1 odd or even",
    ),
    # "is the bookshelf to my left?": whether one is there
    (
        r"^(is|are) (the (?:(?!\bor\b)[a-z -])+?) ((?:on|to|at) my (?:left|right)"
        r"(?:[- ]hand)?(?: side)?|behind me|in front of me)(?=[?.!]*$)",
        r"\1 there \2 \3",
    ),
    # "what will I see if I turn around?": the turn first, as the turn family reads it
    (
        r"^((?:what|which)(?: object| thing)? (?:will|would|do|can|could|might|is|'s)\b[^?]*?)"
        r",? (if|when|once|after) i (turn(?:ed)?|rotate|spin) ([^?]+?)(?=[?.!]*$)",
        r"\2 i \3 \4, \1",
    ),
)


def plain_question(q: str) -> str:
    """A lower-cased question without what would mislead the families as written."""
    q = _TIME_TAIL.sub("", q)
    for pattern, repl in _NORMAL:
        q = re.sub(pattern, repl, q)
    return q


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
    for pattern, rewrite in _SYNONYMS:
        q = re.sub(pattern, rewrite, q)
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
