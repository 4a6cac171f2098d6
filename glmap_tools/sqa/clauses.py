"""A situation text cut into clauses (`glmap_tools.sqa.reading`): lower-cased, asides
normalised ("by my left foot" -> "on my left"), split at punctuation and at the
conjunctions that start another clause; a relative clause that names a side joins the
clause before it."""

from __future__ import annotations

import re

from glmap_tools.sqa import asides

# Where an unpunctuated text starts another clause: "the fridge is on my right" after a word
# that does not relate it to the place before ("the cabinet next to the fridge is ...").
_RUN_ON = re.compile(
    r"(?<!\bto)(?<!\bby)(?<!\bof)(?<!\bnear)(?<!\bbeside)(?<!\bfrom)(?<!\bat)(?<!\bon)(?<!\bin)"
    r"(?<!\band)(?<!\bwith)(?<!\bbehind)(?<!\bunder)(?<!\bwhile)\s+(?=(?:the|a|an) "
    r"(?:(?!(?:the|a|an|and|with|that|which|who)\b)[\w-]+ ){1,3}(?:is|are) (?:on|to|at|in|behind)"
    r" (?:my|me)\b)"
)


def split_clauses(text: str) -> list[str]:
    """The clauses of a situation text, lower-cased, in order."""
    t = " " + " ".join(text.lower().replace("’", "'").replace("`", "'").split()) + " "
    t = re.sub(r"\bi'm\b", "i am", t)
    t = re.sub(r"\bthere's\b", "there is", t)
    # "while the kettle boils, ...": a leading clause about something else sets the scene
    t = re.sub(r"^\s*(?:while|whilst|as|when|since|because|once)\s+(?!i\b)[^,;.]*,", " ", t)
    # "when i wake up, i sit on the bed": a time of mine before where I am
    t = re.sub(
        r"^\s*(?:when|whenever|after|before|once|as soon as)\s+i\s[^,;.]*,(?=\s*i\b)", " ", t
    )
    # "i was sitting on the bed and the window was on my left": told in the past, read now
    t = re.sub(r"\bi was\b", "i am", t)
    t = re.sub(r"\bwas\b", "is", t)
    t = re.sub(r"\bwere\b", "are", t)
    # "at the counter with a cup in my hand": what I hold is no place
    t = re.sub(
        r"\s+with (?:a|an|the|my|some) [\w -]+? in my (?:hands?|lap|arms)\b(?= *[,;.!?]| *$)",
        "",
        t,
    )
    # "at the window with the radiator under it": what stands by the place is no part of it
    t = re.sub(
        r"\s+with (?:the|a|an|some) [\w -]+? (?:under|below|beneath|above|over|beside|next to|by"
        r"|near|around|behind|in front of|on top of|on|in) (?:it|them)\b(?= *[,;.!?]| *$)",
        "",
        t,
    )
    # "the fridge is over to my left", "the toaster way off to my right"
    t = re.sub(r"\s(?:way\s)?(?:over|off)\s(?=(?:to|on)\s(?:my|the)\s(?:left|right)\b)", " ", t)
    # "the lamp's on my right"
    t = re.sub(
        r"\b([a-z]+)'s (?=(?:on|to|at|in|behind|right|just|directly|straight)\b)", r"\1 is ", t
    )
    t = re.sub(r"\bi(?:'ve| have) got\b|\bi've\b", "i have", t)
    t = re.sub(r"\bo ?clock\b|\bo' clock\b", "o'clock", t)
    if not re.search(r"[,;:.!?]", t.strip(" .!?")):  # a run-on sentence: "at the stove
        t = _RUN_ON.sub(", ", t)  # cooking pasta the fridge is on my right"
    t = asides.hands_to_sides(t)
    t = asides.side_words(t)
    t = asides.ACROSS.sub("in front of me", t)
    # "between the X and the Y" keeps its "and" (marked) through the clause split.
    t = re.sub(r"\bbetween ((?:the |a |an )?[\w -]+?) and ", r"between \1 & ", t)
    parts = re.split(
        r"[.;!?]+\s*|,\s*(?:and |while |with |but |so |whereas )?|"
        r"\s+(?:and|while|whilst|but|whereas|as|because|since|when)\s+"
        r"(?=(?:i|i am|my|the|a|an|there|to|on|in|at|"
        r"behind|facing|looking|standing|sitting|seated|lying|leaning|crouching|kneeling)\b)"
        # "with" starts a clause only before an egocentric one ("with the lamp on my left"),
        # not inside a description ("the floor lamp with a green shade").
        r"|\s+with\s+(?=my\b|(?:the|a|an)\s(?:(?!\b(?:and|is|are)\b)[\w\s-])+?\s"
        r"(?:on|to|at|in front of|behind)\s(?:my|me)\b"
        r"|(?:the|a|an)\s[\w\s-]+?\son (?:either|both|each) sides? of me\b"
        r"|(?:the|a|an)\s[\w\s-]+?\s(?:straight |right |directly )?ahead\b)",
        t,
    )
    out: list[str] = []
    for p in (p.strip() for p in parts if p and p.strip()):
        ego = asides.relative_ego(p)
        if ego and out:  # "by the dishwasher, which is to my left": the dishwasher's side
            out[-1] = f"{out[-1]} {ego}"
        elif not asides.RELATIVE.match(p):  # any other ", which ..." names no place
            out.append(p)
    return out
