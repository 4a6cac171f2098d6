"""Similarity functions f_S(u, T_g) behind one Protocol, and the unit texts they score."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numpy as np

from glmap_tools.errors import InvalidInputError

if TYPE_CHECKING:
    from glmap_tools.language.embed import Embedder
    from glmap_tools.map.glmap import GLMap

DETERMINERS = {"a", "an", "the", "this", "that", "these", "those", "my", "some", "any", "one"}
UNIT_KINDS = {"both": ("instance", "region"), "instances": ("instance",), "regions": ("region",)}


@dataclass(frozen=True)
class UnitText:
    """What a scorer sees of one semantic unit.

    Attributes:
        unit_id: the unit's id in the map.
        kind: 'instance' | 'region'.
        text: the unit's description buffer T_o / T_r.
        embedding: [D] unit vector of the text, or None (the scorer embeds `text`).
        observations: frames that observed the unit.
        label: the unit's short category label (instances; '' when unknown).
    """

    unit_id: int
    kind: str
    text: str
    embedding: np.ndarray | None = None  # [D]
    observations: int = 1
    label: str = ""


class Scorer(Protocol):
    """f_S: how well each unit matches a goal description, in [0, 1]."""

    def score(self, goal: str, units: Sequence[UnitText]) -> np.ndarray:
        """[N] scores in [0, 1] of `units` for the goal text (1 = certainly the goal)."""
        ...


def check_goal(goal: str) -> str:
    """Return the stripped goal text or raise InvalidInputError."""
    if not isinstance(goal, str) or not goal.strip():
        raise InvalidInputError(
            f"goal {goal!r} is empty; describe what to find, e.g. 'a bed' or "
            "'the blue metal chair next to the table'."
        )
    return goal.strip()


def map_units(glmap: GLMap, units: str = "both") -> list[UnitText]:
    """The map's instances and/or regions as `UnitText`s, with their stored embeddings.

    Args:
        units: 'both' | 'instances' | 'regions'.
    """
    kinds = UNIT_KINDS.get(units)
    if kinds is None:
        raise InvalidInputError(f"units={units!r} must be one of {sorted(UNIT_KINDS)}.")
    out: list[UnitText] = []
    if "instance" in kinds:
        ids, matrix = glmap.instance_matrix()
        for k, uid in enumerate(ids.tolist()):
            u = glmap.instances[uid]
            out.append(UnitText(uid, "instance", u.text, matrix[k], u.observations, u.label))
    if "region" in kinds:
        ids, matrix = glmap.region_matrix()
        for k, uid in enumerate(ids.tolist()):
            r = glmap.regions[uid]
            out.append(UnitText(uid, "region", r.text, matrix[k], r.observations))
    return out


class EmbeddingScorer:
    """Cosine of the goal embedding against each unit's text embedding, mapped to [0, 1].

    s = clip((cos - floor) / (1 - floor), 0, 1): cosines at or below `floor` (what unrelated
    texts reach with this embedder) count as no evidence, 1 stays 1. A bare category goal
    ("picture") is embedded as a noun phrase ("a picture"), like the unit descriptions it is
    compared with: sentence embedders place a lone word poorly (MiniLM: "picture" vs "a
    framed picture in purple tones" 0.34, "a picture" 0.52).

    Args:
        embedder: the map's text embedder phi (`glmap.embedder`), so unit embeddings and the
            goal live in one space.
        floor: cosine mapped to 0; default: the embedder's `nav_floor` attribute if it has
            one, else DEFAULT_FLOOR.
    """

    DEFAULT_FLOOR = 0.2

    def __init__(self, embedder: Embedder, floor: float | None = None) -> None:
        self.embedder = embedder
        self.floor = float(
            getattr(embedder, "nav_floor", self.DEFAULT_FLOOR) if floor is None else floor
        )
        if not -1.0 <= self.floor < 1.0:
            raise InvalidInputError(f"floor={self.floor!r} must be a cosine in [-1, 1).")
        self._goal_cache: dict[str, np.ndarray] = {}
        self._label_cache: dict[str, np.ndarray] = {}

    @staticmethod
    def goal_phrase(goal: str) -> str:
        """The text embedded for a goal: 'a <goal>' unless it starts with a determiner."""
        goal = check_goal(goal)
        first = goal.split()[0].lower()
        return goal if first in DETERMINERS else f"a {goal}"

    def goal_embedding(self, goal: str) -> np.ndarray:
        """[D] embedding of the goal text (cached: a goal stays fixed over an episode)."""
        goal = check_goal(goal)
        vec = self._goal_cache.get(goal)
        if vec is None:
            vec = np.asarray(self.embedder.embed([self.goal_phrase(goal)])[0], dtype=np.float32)
            if len(self._goal_cache) > 256:
                self._goal_cache.clear()
            self._goal_cache[goal] = vec
        return vec

    def cosines(self, goal: str, units: Sequence[UnitText]) -> np.ndarray:
        """[N] raw cosines of the goal against the units."""
        q = self.goal_embedding(goal)
        if not units:
            return np.zeros(0)
        missing = [k for k, u in enumerate(units) if u.embedding is None]
        if missing:
            embedded = self.embedder.embed([units[k].text for k in missing])
        rows = []
        j = 0
        for u in units:
            if u.embedding is None:
                rows.append(np.asarray(embedded[j], dtype=np.float32))
                j += 1
            else:
                rows.append(np.asarray(u.embedding, dtype=np.float32))
        matrix = np.stack(rows)
        norms = np.linalg.norm(matrix, axis=1) * max(float(np.linalg.norm(q)), 1e-12)
        return (matrix @ q) / np.maximum(norms, 1e-12)

    def category_margins(
        self, goal: str, units: Sequence[UnitText], labels: Sequence[str] | None = None
    ) -> np.ndarray:
        """[N] cosine of each unit with the goal minus its best cosine with another category.

        The other categories are `labels` (default: the labels of `units`; pass every label
        of the map: its own vocabulary), embedded as noun phrases like the goal. A unit whose
        text is closer to some other label than to the goal ("a kitchen cabinet ..." for the
        goal "cabinet") gets a negative margin, whatever its absolute cosine; with no
        competing label every margin is +inf.
        """
        if not units:
            return np.zeros(0)
        own = self.goal_phrase(goal).lower()
        names = [u.label for u in units] if labels is None else list(labels)
        phrases = sorted({self.goal_phrase(n).lower() for n in names if n.strip()})
        phrases = [p for p in phrases if p != own]
        cos = self.cosines(goal, units)
        if not phrases:
            return np.full(len(units), np.inf)
        missing = [p for p in phrases if p not in self._label_cache]
        if missing:
            for p, v in zip(missing, self.embedder.embed(missing), strict=True):
                v = np.asarray(v, dtype=np.float32)
                self._label_cache[p] = v / max(float(np.linalg.norm(v)), 1e-12)
        vocab = np.stack([self._label_cache[p] for p in phrases])  # [L, D]
        missing_units = [u.text for u in units if u.embedding is None]
        embedded = iter(self.embedder.embed(missing_units) if missing_units else [])
        rows = np.stack(
            [
                np.asarray(u.embedding if u.embedding is not None else next(embedded), np.float32)
                for u in units
            ]
        )
        rows /= np.maximum(np.linalg.norm(rows, axis=1, keepdims=True), 1e-12)
        other = (rows @ vocab.T).max(axis=1)
        return (cos - other).astype(np.float64)

    def score(self, goal: str, units: Sequence[UnitText]) -> np.ndarray:
        """[N] scores in [0, 1] (see the class docstring)."""
        cos = self.cosines(goal, units)
        return np.clip((cos - self.floor) / (1.0 - self.floor), 0.0, 1.0).astype(np.float64)
