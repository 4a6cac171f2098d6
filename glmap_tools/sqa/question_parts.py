"""The pieces the question patterns (`glmap_tools.sqa.wording`) are built of: clock hours,
an egocentric place, an object slot, a turn, seeing, a comparative, counting."""

from __future__ import annotations

from glmap_tools.sqa.situation_words import HOUR_WORDS

HOURS = HOUR_WORDS[1:]  # one .. twelve
HOUR = r"(?P<hour>\d{1,2}|" + "|".join(HOURS) + r")"
# An egocentric place: a side, behind, in front, around, or a clock hour.
EGO = (
    r"(?:(?:on|to|at) (?:my|the) (?P<side>left|right)(?:[- ]hand)?(?: side)?(?: of me)?"
    r"|(?P<behind>behind me|at my back)|(?P<front>in front of me|ahead of me|before me)"
    r"|(?P<around>around me|near me|nearby|close to me|in (?:this|the) room|here|in here)"
    r"|(?:at|in|on|to) (?:my |the )?" + HOUR + r" ?o'clock(?: direction| position)?)"
)
DET = r"(?:the |a |an |any |some |another |other |all (?:the )?)*"


def slot(name: str = "object") -> str:
    """The group `name` for an object's words, after any determiners ("the", "all the")."""
    return DET + rf"(?P<{name}>[a-z][a-z -]*?)"


TURN = (
    r"(?:i )?(?:turn|turning|rotate|rotating|spin|spinning)(?: myself)?(?: (?P<turn>around|back|"
    r"180 degrees|(?:90 degrees )?(?:to )?(?:my |the )?(?:left|right)))"
)
SEE = r"(?:can|could|will|would|do) i (?:be able to )?(?:see|spot|view|notice|face)"
REL = (
    r"(?P<rel>closer|nearer|farther|further|bigger|larger|smaller|taller|shorter|higher|"
    r"lower|wider|longer|heavier)"
)
COUNT = r"(?:how many|what is the number of|the number of|number of|count(?: the)?)"

THING = r"(?: object| thing| item| piece of furniture| furniture)?"
