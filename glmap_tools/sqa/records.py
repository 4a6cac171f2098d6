"""The answerer's record types and the colour words, beneath every module that answers."""

from __future__ import annotations

from dataclasses import dataclass

COLOURS = [
    "red",
    "orange",
    "yellow",
    "green",
    "teal",
    "blue",
    "navy",
    "purple",
    "pink",
    "brown",
    "beige",
    "white",
    "grey",
    "gray",
    "black",
    "silver",
    "gold",
    "cream",
    "tan",
]


@dataclass(frozen=True)
class MapAnswer:
    """An answer from the map, or why there is none."""

    answer: str
    question_type: str
    supported: bool
    evidence: str
