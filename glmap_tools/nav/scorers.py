"""Similarity functions f_S(u, T_g) behind one Protocol, and the unit texts they score."""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol

import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.map.queries import parse_relation, relation_evidence

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


# Cosine at which the embedder reads a map label as the goal's own name, not another
# category. MiniLM: television / tv 0.977, fridge / refrigerator 0.968, while the closest
# other categories reach 0.893 (kitchen cabinet / cabinet) and 0.853 (couch / sofa).
# House-tune s01-008: a fourth view named the refrigerator unit "a black fridge", the map's
# label "fridge" then beat the goal "refrigerator" by 0.009 and the match dropped for 300
# steps.
SYNONYM_COS = 0.95


def names_a_kind_of(phrase: str, goal_phrase: str) -> bool:
    """Whether a label phrase names a kind of the goal: its words end with the goal's, the
    article aside ('a potted plant' of 'a plant', 'a table lamp' of 'a lamp')."""
    words, goal = phrase.lower().split(), goal_phrase.lower().split()
    words = words[1:] if words and words[0] in DETERMINERS else words
    goal = goal[1:] if goal and goal[0] in DETERMINERS else goal
    return 0 < len(goal) < len(words) and words[-len(goal) :] == goal


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
        competing label every margin is +inf. A label the embedder reads as the goal itself
        (cosine >= `SYNONYM_COS`: "fridge" for "refrigerator", "television" for "tv") is no
        other category. A unit the detector itself names as the goal does not lose it to a
        narrower name of the goal (`names_a_kind_of`): the detector calls some plants
        "potted plant", and a plant's own text ("a large potted plant in a black pot")
        is closer to that label than to "plant", so after one such view the map's plants
        never matched the goal "plant" (house-tune s01-006: 16 plant units over 500
        steps). A unit named by the narrower label keeps it as its competitor: a kitchen
        cabinet is no "cabinet" goal.
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
        q = self.goal_embedding(goal)
        synonym = SYNONYM_COS * max(float(np.linalg.norm(q)), 1e-12)
        phrases = [p for p in phrases if float(self._label_cache[p] @ q) < synonym]
        if not phrases:
            return np.full(len(units), np.inf)
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
        sims = rows @ vocab.T  # [N, L]
        narrower = np.array([names_a_kind_of(p, own) for p in phrases])
        if narrower.any():
            named = np.array([self._names_goal(u.label, own, q, synonym) for u in units])
            sims[np.ix_(named, narrower)] = -np.inf
        other = sims.max(axis=1)
        return (cos - other).astype(np.float64)

    def _names_goal(self, label: str, own: str, q: np.ndarray, synonym: float) -> bool:
        """Whether a unit's own label is the goal's name or a synonym of it."""
        if not label.strip():
            return False
        phrase = self.goal_phrase(label).lower()
        vec = self._label_cache.get(phrase)
        return phrase == own or (vec is not None and float(vec @ q) >= synonym)

    def score(self, goal: str, units: Sequence[UnitText]) -> np.ndarray:
        """[N] scores in [0, 1] (see the class docstring)."""
        cos = self.cosines(goal, units)
        return np.clip((cos - self.floor) / (1.0 - self.floor), 0.0, 1.0).astype(np.float64)


# ---------------------------------------------------------------------- the client's f_S

SOURCES = ("client", "prior", "scorer")  # where a unit's score came from


def same_goal(a: str, b: str) -> bool:
    """Whether two goal texts name the same goal (case and spacing aside)."""
    return " ".join(a.lower().split()) == " ".join(b.lower().split())


def check_unit_score(score: object, what: str) -> float:
    """`score` as a float in [0, 1], or raise InvalidInputError naming `what` and the fix."""
    value = float(score) if isinstance(score, int | float) and not isinstance(score, bool) else None
    if value is None or not math.isfinite(value) or not 0.0 <= value <= 1.0:
        raise InvalidInputError(
            f"score {score!r} for {what} is not in [0, 1]; give how likely it is to be or "
            "hold the goal, 0 (surely not) to 1 (surely)."
        )
    return value


MAX_PRIORS = 64  # region kinds a client's priors hold at once (each is matched every step)
MAX_KIND_CHARS = 60


def kind_pattern(kind: str) -> re.Pattern[str]:
    """Whole words of `kind` ('kitchen', 'sleeping area') inside a unit's text."""
    words = kind.lower().split()
    if not words:
        raise InvalidInputError(
            f"prior kind {kind!r} is empty; name a kind of room or region, e.g. 'kitchen'."
        )
    return re.compile(r"\b" + r"\s+".join(re.escape(w) for w in words) + r"s?\b")


@dataclass
class ClientScores:
    """The client's f_S for one goal: scores per unit id and priors per region kind.

    A unit score overrides every other score of that unit; a prior scores each region whose
    text holds the kind's words (the best prior when several match); the rest keep the
    configured scorer's score. Fused ids are followed to the unit they became.

    Attributes:
        goal: the goal text the scores are for.
        units: unit id -> s_u in [0, 1].
        priors: kind ('kitchen', 'sleeping area') -> s_u in [0, 1] of regions of that kind.
    """

    goal: str
    units: dict[int, float] = field(default_factory=dict)
    priors: dict[str, float] = field(default_factory=dict)

    @property
    def empty(self) -> bool:
        return not self.units and not self.priors

    def follow(self, fused_into: Mapping[int, int]) -> dict[int, int]:
        """Move scores of fused ids onto the unit they became (the higher score wins when two
        meet); return {fused id: surviving id} of the ids moved."""
        moved: dict[int, int] = {}
        for uid in [u for u in self.units if u in fused_into]:
            live = uid
            while live in fused_into:
                live = fused_into[live]
            score = self.units.pop(uid)
            self.units[live] = max(score, self.units.get(live, 0.0))
            moved[uid] = live
        return moved

    def prior_of(self, text: str) -> float | None:
        """The best prior whose kind the text names, or None."""
        hits = [s for k, s in self.priors.items() if kind_pattern(k).search(text.lower())]
        return max(hits) if hits else None

    def source(self, unit: UnitText) -> str:
        """'client' (a unit score), 'prior' (a region of a scored kind) or 'scorer'."""
        if unit.unit_id in self.units:
            return "client"
        if unit.kind == "region" and self.prior_of(unit.text) is not None:
            return "prior"
        return "scorer"


class ClientScorer:
    """f_S with the client's judgement first: `ClientScores` where they say something, the
    configured scorer elsewhere (and for any other goal).

    The goal match reads `category_margins` when the base scorer has one: a unit the client
    scored then matches when its score reaches `match_at` (the task's stop threshold),
    whatever the map's vocabulary says; the others keep the base scorer's margin.

    Args:
        base: the configured scorer (embedding, LLM).
        client: the client's scores.
        match_at: the score at which a client-scored instance counts as the goal.
    """

    def __init__(self, base: Scorer, client: ClientScores, match_at: float) -> None:
        self.base = base
        self.client = client
        self.match_at = float(match_at)
        margins = getattr(base, "category_margins", None)
        # find_goal_match looks the attribute up: None means "no margin check".
        self.category_margins: Callable[..., np.ndarray] | None = (
            self._margins if margins is not None else None
        )

    def applies(self, goal: str) -> bool:
        return same_goal(goal, self.client.goal)

    def sources(self, goal: str, units: Sequence[UnitText]) -> list[str]:
        """[N] where each unit's score comes from (`SOURCES`)."""
        if not self.applies(goal):
            return ["scorer"] * len(units)
        return [self.client.source(u) for u in units]

    def score(self, goal: str, units: Sequence[UnitText]) -> np.ndarray:
        """[N] scores in [0, 1]: the client's where given, else the base scorer's."""
        out = np.asarray(self.base.score(goal, units), dtype=np.float64).copy()
        if not self.applies(goal):
            return out
        for k, u in enumerate(units):
            if u.unit_id in self.client.units:
                out[k] = self.client.units[u.unit_id]
            elif u.kind == "region":
                prior = self.client.prior_of(u.text)
                if prior is not None:
                    out[k] = prior
        return out

    def _margins(
        self, goal: str, units: Sequence[UnitText], labels: Sequence[str] | None = None
    ) -> np.ndarray:
        base = getattr(self.base, "category_margins")  # noqa: B009 (checked in __init__)
        out = np.asarray(base(goal, units, labels), dtype=np.float64).copy()
        if not self.applies(goal):
            return out
        for k, u in enumerate(units):
            if u.unit_id in self.client.units:
                out[k] = np.inf if self.client.units[u.unit_id] >= self.match_at else -np.inf
        return out


# Share of an InstNav instance's score its "next to" relation decides: a look-alike with no
# anchor beside it (0.95 for its target phrase) falls under the 0.75 stop threshold.
RELATION_SHARE = 0.3


class RelationScorer:
    """f_S for goals with a "next to" relation (InstNav: "the navy kitchen cabinet next to
    the white refrigerator"): each instance scored for the goal's target phrase ("the navy
    kitchen cabinet"), of which the relation decides `RELATION_SHARE` by what stands next to
    the instance in the map (`map.queries.relation_evidence`). Regions, and goals without a
    relation, keep the base scores of the whole goal.

    Args:
        base: the configured scorer.
        glmap_of: the map the units belong to (the session's current map).
        anchor_min_observations: frames an anchor must be seen in to count, as a goal match
            must (`NavConfig.min_observations`): a one-glimpse "box" beside a toilet made
            the wrong toilet the match for one step, and the agent stopped there
            (house-bench InstNav s06-001).
    """

    def __init__(
        self, base: Scorer, glmap_of: Callable[[], GLMap], anchor_min_observations: int = 2
    ) -> None:
        self.base = base
        self.glmap_of = glmap_of
        self.anchor_min_observations = anchor_min_observations
        margins = getattr(base, "category_margins", None)
        self.category_margins: Callable[..., np.ndarray] | None = margins

    def score(self, goal: str, units: Sequence[UnitText]) -> np.ndarray:
        """[N] scores in [0, 1]: the base scores, instances by target and relation."""

        out = np.asarray(self.base.score(goal, units), dtype=np.float64).copy()
        relation = parse_relation(goal)
        if relation is None:
            return out
        glmap = self.glmap_of()
        rows = [
            k for k, u in enumerate(units) if u.kind == "instance" and u.unit_id in glmap.instances
        ]
        if rows:
            ids = np.array([units[k].unit_id for k in rows], dtype=np.int64)
            target = np.asarray(
                self.base.score(relation.target, [units[k] for k in rows]), dtype=np.float64
            )
            evidence = relation_evidence(
                glmap, ids, relation, min_observations=self.anchor_min_observations
            )
            out[rows] = target * (1.0 - RELATION_SHARE + RELATION_SHARE * evidence)
        return out
