"""A situation text's phrases: where one is, and what one faces (the offline split)."""

from __future__ import annotations

import re

_FACING = re.compile(
    r"\b(?:facing|face|looking (?:at|towards?)|look(?:ing)? towards?|turned towards?|"
    r"with my (?:face|eyes) (?:to|towards?)|staring at)\s+(?P<target>.+)$"
    r"|\b(?:with\s+)?(?P<target2>(?:the|a|an|my)\s+(?:(?!\bwith\b)[^,.;])+?)\s+(?:is\s+)?"
    r"(?:right\s+)?in front of me\b",
    re.IGNORECASE,
)


def split_situation(text: str) -> tuple[str, str]:
    """(location phrase, facing phrase) of a situation text; facing '' when none is given.

    >>> split_situation("I am sitting on the bed, facing the couch.")
    ('I am sitting on the bed', 'the couch')
    """
    t = " ".join(text.split()).strip()
    m = _FACING.search(t)
    if not m:
        return t.rstrip(" .,;"), ""
    target = (m.group("target") or m.group("target2") or "").strip(" .,;")
    location = (t[: m.start()] + " " + t[m.end() :]).strip(" .,;")
    location = re.sub(r"\s*(?:,|\band\b|\bwhile\b|\bwith\b)\s*$", "", location).strip(" .,;")
    return location or t, target


_FILLER = re.compile(
    r"^(?:(?:i am|i'm|i|am|we are|currently|right now|now|standing|stand|sitting|sit|lying|lie|"
    r"leaning|waiting|at|by|on|in|near|next to|beside|close to|in front of|the edge of|"
    r"edge of|the side of|side of|of|while|and|with)\b\s*)+",
    re.IGNORECASE,
)


def core_phrase(phrase: str) -> str:
    """The phrase without its leading pose and preposition words ('I am sitting on the')."""
    out = _FILLER.sub("", phrase.strip()).strip(" .,;")
    return out or phrase.strip()
