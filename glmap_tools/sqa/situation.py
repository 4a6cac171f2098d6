"""What `situate` (`glmap_tools.sqa.situate`) returns: where a situation text puts the
agent (`Situation`) and the units that decided it (`ScoredUnit`); and `TIE`, how close to
the best a score counts as equally good, for situate and its constraints
(`glmap_tools.sqa.constrain`) alike."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from glmap_tools.sqa.reading import SituationReading

if TYPE_CHECKING:
    from glmap_tools.nav.scorers import UnitText
    from glmap_tools.nav.value import ValueMap

TIE = 0.05  # scores this close to the best count as equally good


@dataclass(frozen=True)
class ScoredUnit:
    """A unit that decided a heat map, with its probability."""

    unit_id: int
    kind: str
    score: float
    text: str


@dataclass(frozen=True)
class Situation:
    """Where the text puts the agent.

    Attributes:
        x, y: l_a, metres (seen-free space).
        heading: theta, radians counter-clockwise from +x.
        h_r: H_r, the location heat map.
        h_o: H_o, the facing heat map (None when the text names nothing faced).
        peak_r: argmax H_r before snapping; peak_o: l_o (None without a facing target).
        anchors: the units behind H_r's peak, best first.
        facing: the units behind H_o's peak, best first.
        confidence: min of the best p_r and, when there is one, the best p_o.
        low_confidence: True when the best evidence is weak (still a result).
        location_text, facing_text: the phrases scored (the whole text for an LLM scorer).
        notes: how the pose was chosen.
        anchor_id: the unit l_a was placed at; facing_id: the unit l_o is on (or None).
    """

    x: float
    y: float
    heading: float
    h_r: ValueMap
    h_o: ValueMap | None
    peak_r: tuple[float, float]
    peak_o: tuple[float, float] | None
    anchors: tuple[ScoredUnit, ...]
    facing: tuple[ScoredUnit, ...]
    confidence: float
    low_confidence: bool
    location_text: str
    facing_text: str
    notes: list[str] = field(default_factory=list)
    anchor_id: int | None = None
    facing_id: int | None = None
    reading: SituationReading | None = None

    def as_dict(self) -> dict[str, Any]:
        """A compact JSON-ready summary (no heat maps)."""
        return {
            "x": round(self.x, 2),
            "y": round(self.y, 2),
            "heading_deg": round(math.degrees(self.heading), 1),
            "confidence": round(self.confidence, 3),
            "low_confidence": self.low_confidence,
            "location_text": self.location_text,
            "facing_text": self.facing_text,
            "anchors": [[u.unit_id, u.kind, round(u.score, 3), u.text[:80]] for u in self.anchors],
            "facing": [[u.unit_id, u.kind, round(u.score, 3), u.text[:80]] for u in self.facing],
            "notes": self.notes,
            "reading": self.reading.as_dict() if self.reading is not None else None,
        }


def top_units(units: list[UnitText], scores: np.ndarray, k: int = 3) -> tuple[ScoredUnit, ...]:
    """The `k` best-scoring units (`scores`: [len(units)]), best first, those above 0."""
    order = np.argsort(-scores, kind="stable")[:k]
    return tuple(
        ScoredUnit(units[i].unit_id, units[i].kind, float(scores[i]), units[i].text)
        for i in order
        if scores[i] > 0
    )
