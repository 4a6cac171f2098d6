"""Queries over a GLMap: by text (instances, regions), by position, by id.

Text search (`find`) scores each unit against the query in a few phrasings:

- phrasings: the query itself and, when it asks for a use ("somewhere to sleep", "something
  to sit on", "where can I wash my hands"), the bare activity ("sleep"), which the
  embedder places nearer the things used for it than the filler words do;
- an instance is scored against its label (the short category) and its description
  separately, and the two cosines are averaged (`LABEL_WEIGHT`); a region, which has no
  label, against its description;
- the score is the mean over phrasings, so it stays a cosine-like number in [-1, 1].

A hit is a `match` when its score reaches the embedder's `default_tau_match`, calibrated
on a labelled query set (docs/search_quality.md); embedders without one leave it None.
For MiniLM the threshold depends on what is asked (`MATCH_RULES`): a region, an instance
by its use ("somewhere to sit": `phrasings` finds the activity) or an instance by name
("desk"). Chosen by `python tools/match_thresholds.py` on the tuning half (best top-hit
recall at precision >= 0.9 per group) and checked on the held-out half, top hit:

| rule | tuning P / R | held-out P / R |
|---|---|---|
| one threshold 0.49 (before) | 0.912 / 0.678 | 0.913 / 0.633 |
| region 0.369, instance 0.49 | 0.902 / 0.724 | 0.904 / 0.687 |
| region 0.369, use 0.485, name 0.516 (used) | 0.932 / 0.724 | 0.917 / 0.660 |

(With the "next to" relations below in the ranking; without them the held-out rows read
0.904 / 0.631, 0.895 / 0.685 and 0.908 / 0.664: three held-out queries have a relation.)

Region queries gain most (held-out recall 0.733 -> 1.0 at precision 0.957 -> 0.909): a
region's text scores lower against a query than an instance's label does. Name queries need
more than 0.49 ("desk" reached a chair at 0.497); use queries stay near 0.49: at lower
thresholds their held-out precision falls under 0.7 ("somewhere to sit" against a lounge
chair at 0.45 stays `match: false`, i.e. not sure).
"""

from __future__ import annotations

import math
import numbers
import re
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.gaussians.types import GaussianSet
from glmap_tools.map.report import UnitInfo
from glmap_tools.map.units import InstanceUnit, RegionUnit

if TYPE_CHECKING:
    from glmap_tools.map.state import MapState

MAX_K = 1000
LABEL_WEIGHT = 0.5  # share of the label cosine in an instance's score (tuned on the tuning half)

# "somewhere to X", "a place where I can X", "where do I X", "something to X", "a device for X"
_ASKS_FOR_A_PLACE = re.compile(
    r"^(?:somewhere|some ?place|a place|a spot|an area|a room|where)\s+"
    r"(?:(?:can|could|do|should|would|might|may) (?:i|we|you|one)\s+|i can\s+|to\s+|for\s+)?"
    r"(?P<activity>.+)$"
)
_ASKS_FOR_A_THING = re.compile(
    r"^(?:something|a thing|an object|a device|an appliance|anything|a piece of furniture|what)"
    r"\s+(?:(?:can|could|do|should) (?:i|we|you) (?:use )?)?(?:to|for|that|used to|used for)"
    r"\s+(?P<activity>.+)$"
)


def region_gaussians(glmap: MapState, region: RegionUnit) -> GaussianSet:
    """The union of a region's instance Gaussians."""
    return GaussianSet.concat([glmap.instances[i].gaussians for i in region.instance_ids])


def details(glmap: MapState, unit: InstanceUnit | RegionUnit) -> UnitInfo:
    """Describe one unit."""
    if isinstance(unit, InstanceUnit):
        g = unit.gaussians
        return UnitInfo(
            id=unit.id,
            kind="instance",
            label=unit.label,
            description=unit.text,
            centroid=_round(unit.centroid),
            bounds=[_round(b) for b in unit.bounds()],
            observations=unit.observations,
            num_gaussians=len(g),
            region_ids=sorted(glmap.regions_of_instance(unit.id)),
        )
    g = region_gaussians(glmap, unit)
    w = g.counts.astype(np.float64)
    centroid = (g.means.astype(np.float64) * w[:, None]).sum(0) / w.sum()
    return UnitInfo(
        id=unit.id,
        kind="region",
        description=unit.text,
        centroid=_round(centroid),
        bounds=[_round(b) for b in g.bounds()],
        observations=unit.observations,
        num_gaussians=len(g),
        instance_ids=list(unit.instance_ids),
    )


def _round(v: np.ndarray) -> list[float]:
    return [round(float(x), 4) for x in v]


def phrasings(text: str) -> list[str]:
    """The query and, when it asks for a place or thing to do something, that activity.

    >>> phrasings("Somewhere to sleep?")
    ['Somewhere to sleep?', 'sleep']
    >>> phrasings("the red chair")
    ['the red chair']
    """
    plain = " ".join(text.lower().split()).rstrip("?!. ")
    found = _ASKS_FOR_A_PLACE.match(plain) or _ASKS_FOR_A_THING.match(plain)
    return [text, found.group("activity")] if found else [text]


def label_matrix(glmap: MapState) -> tuple[np.ndarray, np.ndarray]:
    """(embeddings [L, D] of the distinct labels, [N] row of each instance's label or -1).

    Instances in `instance_matrix` order; -1 marks an instance without a (meaningful) label.
    Few labels are distinct, so scoring them costs an [L, D] product and an [N] gather
    instead of a second [N, D] product. Cached with the map's other matrices (cleared on
    every update).
    """
    cache = glmap._matrix_cache
    cached = cache.get("instance-label")
    if cached is None:
        ids, _ = glmap.instance_matrix()
        labels = [glmap.instances[int(i)].label.strip() for i in ids]
        distinct = sorted(set(labels) - {""})
        vectors = (
            glmap.embedder.embed(distinct).astype(np.float32)
            if distinct
            else np.zeros((0, glmap.embedder.dim), np.float32)
        )  # [L, D]
        meaningful = {lab for lab, v in zip(distinct, vectors, strict=True) if np.any(v)}
        row_of = {lab: j for j, lab in enumerate(distinct)}
        index = np.array([row_of[lab] if lab in meaningful else -1 for lab in labels], np.int64)
        cached = cache["instance-label"] = (vectors, index)
    return cached


def text_scores(glmap: MapState, kind: str, text: str) -> tuple[np.ndarray, np.ndarray]:
    """(unit ids [N], scores [N]) of every unit of `kind` for the query `text`."""
    ids, matrix = glmap.instance_matrix() if kind == "instance" else glmap.region_matrix()
    if len(ids) == 0:
        return ids, np.zeros(0, np.float32)
    # Cosines are linear in the query vector, so the mean over phrasings is one product.
    q = glmap.embedder.embed(phrasings(text)).mean(axis=0)  # [D]
    scores = matrix @ q  # [N]
    if kind == "instance":
        vectors, index = label_matrix(glmap)
        if len(vectors):
            label_scores = (vectors @ q)[np.maximum(index, 0)]  # [N]
            mixed = LABEL_WEIGHT * label_scores + (1.0 - LABEL_WEIGHT) * scores
            scores = np.where(index >= 0, mixed, scores)
    return ids, scores


def reference_text_scores(glmap: MapState, kind: str, text: str) -> tuple[np.ndarray, np.ndarray]:
    """Slow reference of `text_scores`: every phrasing against every unit's fields, one by one."""
    units = glmap.instances if kind == "instance" else glmap.regions
    ids = np.array(sorted(units), dtype=np.int64)
    variants = glmap.embedder.embed(phrasings(text))  # [P, D]
    scores = np.zeros(len(ids), np.float64)
    for row, uid in enumerate(ids):
        unit = units[int(uid)]
        label = getattr(unit, "label", "").strip()
        label_vec = glmap.embedder.embed([label])[0] if label else None
        per_phrasing = []
        for v in variants:
            s_desc = float(np.dot(v, unit.embedding))
            if label_vec is not None and np.any(label_vec):
                s_label = float(np.dot(v, label_vec))
                per_phrasing.append(LABEL_WEIGHT * s_label + (1 - LABEL_WEIGHT) * s_desc)
            else:
                per_phrasing.append(s_desc)
        scores[row] = np.mean(per_phrasing)
    return ids, scores


# Match thresholds by what a query asks for, per embedder (see the module docstring);
# embedders not listed use their `default_tau_match` for every query.
MATCH_RULES: dict[str, dict[str, float]] = {
    "all-MiniLM-L6-v2": {"region": 0.369, "use": 0.485, "name": 0.516},
}


def query_kind(kind: str, text: str) -> str:
    """'region', 'use' (an instance by its use: "somewhere to sit") or 'name' ("desk")."""
    if kind == "region":
        return "region"
    return "use" if len(phrasings(text)) > 1 else "name"


def match_threshold(glmap: MapState, kind: str = "instance", text: str = "") -> float | None:
    """The embedder's calibrated match threshold for a query (None: it declares none).

    Args:
        kind: 'instance' | 'region', what the query searches.
        text: the query (a use or a name, see `query_kind`).
    """
    tau = getattr(glmap.embedder, "default_tau_match", None)
    if tau is None:
        return None
    rules = MATCH_RULES.get(str(getattr(glmap.embedder, "name", "")))
    return float(rules[query_kind(kind, text)]) if rules else float(tau)


def find(glmap: MapState, kind: str, text: str, k: int) -> list[UnitInfo]:
    """Top-k units of `kind` for the query `text`, best first (scoring: module docstring).

    Raises:
        InvalidInputError: empty text, or k outside 1..MAX_K.
    """
    if not isinstance(text, str) or not text.strip():
        raise InvalidInputError("query text is empty; describe what to find, e.g. 'a red chair'.")
    whole = isinstance(k, numbers.Integral) and not isinstance(k, bool | np.bool_)
    if not (whole and 1 <= int(k) <= MAX_K):
        raise InvalidInputError(f"k={k!r} must be a whole number in 1..{MAX_K}.")
    ids, scores = text_scores(glmap, kind, text)
    if len(ids) == 0:
        return []
    if kind == "instance":  # "the navy cabinet next to the fridge": the relation decides
        scores = with_relation(glmap, ids, scores, text)
    tau = match_threshold(glmap, kind, text)
    k = min(int(k), len(ids))
    top = np.argpartition(-scores, k - 1)[:k]
    top = top[np.lexsort((ids[top], -scores[top]))]
    units = glmap.instances if kind == "instance" else glmap.regions
    out = []
    for i in top:
        info = details(glmap, units[int(ids[i])])
        info.score = round(float(scores[i]), 4)
        info.match = None if tau is None else bool(scores[i] >= tau)
        out.append(info)
    return out


# ---------------------------------------------------------------------- relations

NEAR_M = 1.0  # metres between footprints for "next to" (as the InstNav goals: sim.instnav)
RELATION_WEIGHT = 0.1  # share of an instance's score that its relation decides
RELATION_CANDIDATES = 50  # instances (best scores first) whose neighbours are looked at
ANCHOR_FLOOR = 0.2  # anchor scores at or below this are no evidence (as EmbeddingScorer)
_RELATION = re.compile(
    r"^(?P<target>.+?)\s+(?:next to|near|beside|close to|by)\s+(?P<anchor>.+)$", re.IGNORECASE
)
_UNIT_ANCHOR = re.compile(r"^(?:the\s+)?(?:unit|instance|id)\s+#?(?P<id>\d+)$", re.IGNORECASE)
_ROOM_TAIL = re.compile(r"\s+in the\s+[\w ]+$", re.IGNORECASE)


@dataclass(frozen=True)
class Relation:
    """ "<target> next to <anchor>": the anchor as a text, or as a unit id ("unit 12")."""

    target: str
    anchor: str
    anchor_id: int | None = None


def parse_relation(text: str) -> Relation | None:
    """The "next to" relation of a query or goal, or None.

    >>> parse_relation("the navy kitchen cabinet next to the white refrigerator")
    Relation(target='the navy kitchen cabinet', anchor='the white refrigerator', anchor_id=None)
    >>> parse_relation("a chair near unit 12").anchor_id
    12
    """
    plain = " ".join(text.split()).rstrip("?!. ")
    found = _RELATION.match(plain)
    if found is None:
        return None
    anchor = _ROOM_TAIL.sub("", found.group("anchor")).strip()
    unit = _UNIT_ANCHOR.match(anchor)
    return Relation(found.group("target"), anchor, int(unit.group("id")) if unit else None)


def _boxes(glmap: MapState, ids: np.ndarray) -> np.ndarray:
    """[N, 4] (i0, j0, i1, j1) cell box of each unit (NaN for a unit without cells)."""
    out = np.full((len(ids), 4), np.nan)
    for k, uid in enumerate(ids.tolist()):
        cells = glmap.grid.cells_of_unit(int(uid))
        if cells:
            arr = np.array(list(cells), dtype=np.float64)
            out[k] = (*arr.min(axis=0), *arr.max(axis=0))
    return out


def relation_evidence(
    glmap: MapState,
    ids: np.ndarray,
    relation: Relation,
    radius: float = NEAR_M,
    min_observations: int = 1,
) -> np.ndarray:
    """[N] how well each instance of `ids` stands next to the relation's anchor, in [0, 1].

    The best anchor score among the other instances whose footprint (cell box) lies within
    `radius` metres of its own: 1 for the anchor unit when the relation names an id, else
    the instance's score for the anchor text, mapped `clip((s - 0.2) / 0.8, 0, 1)`.
    Instances seen in fewer than `min_observations` frames are no anchor.
    """
    all_ids, _ = glmap.instance_matrix()
    if len(ids) == 0 or len(all_ids) == 0:
        return np.zeros(len(ids))
    if relation.anchor_id is not None:
        anchor = (all_ids == relation.anchor_id).astype(np.float64)
    else:
        _, a = text_scores(glmap, "instance", relation.anchor)
        anchor = np.clip((np.asarray(a, np.float64) - ANCHOR_FLOOR) / (1 - ANCHOR_FLOOR), 0, 1)
    if min_observations > 1:
        seen = np.array([glmap.instances[int(i)].observations for i in all_ids.tolist()])
        anchor = np.where(seen >= min_observations, anchor, 0.0)
    theirs = _boxes(glmap, all_ids)
    row = {u: k for k, u in enumerate(all_ids.tolist())}
    mine = theirs[[row[u] for u in np.asarray(ids).tolist()]]  # `ids` are instances of the map
    cell = glmap.grid.cell_size
    # Gap between boxes, in cells (0 when they touch or overlap), per pair [N, M].
    dx = np.maximum(theirs[None, :, 0] - mine[:, None, 2], mine[:, None, 0] - theirs[None, :, 2])
    dy = np.maximum(theirs[None, :, 1] - mine[:, None, 3], mine[:, None, 1] - theirs[None, :, 3])
    gap = np.hypot(np.maximum(dx - 1, 0), np.maximum(dy - 1, 0)) * cell
    near = (gap <= radius) & (np.asarray(ids)[:, None] != all_ids[None, :])
    return np.where(near, anchor[None, :], 0.0).max(axis=1)


def with_relation(glmap: MapState, ids: np.ndarray, scores: np.ndarray, text: str) -> np.ndarray:
    """[N] instance scores with the query's "next to" relation deciding RELATION_WEIGHT of
    each: s * (1 - w + w * evidence). Two instances that read alike ("a navy kitchen
    cabinet") are told apart by what stands next to them; a score never rises, so a
    threshold keeps meaning what it was calibrated for. Unchanged without a relation."""
    relation = parse_relation(text)
    if relation is None or len(ids) == 0:
        return scores
    top = np.argsort(-scores, kind="stable")[:RELATION_CANDIDATES]
    evidence = np.zeros(len(ids))
    evidence[top] = relation_evidence(glmap, ids[top], relation)
    return scores * (1.0 - RELATION_WEIGHT + RELATION_WEIGHT * evidence)


MAX_COORDINATE = 1e6  # metres: a position beyond is no place on a map


def _finite(value: float) -> bool:
    try:
        return math.isfinite(value)
    except OverflowError:  # an integer past float64
        return False


def units_at(glmap: MapState, x: float, y: float, radius: float) -> list[UnitInfo]:
    """Units whose grid cells lie within `radius` of (x, y), nearest first."""
    for name, value in (("x", x), ("y", y), ("radius", radius)):
        if not isinstance(value, numbers.Real) or isinstance(value, bool | np.bool_):
            raise InvalidInputError(f"{name}={value!r} is not a number; give metres.")
    if not all(_finite(v) for v in (x, y, radius)):
        raise InvalidInputError(f"position ({x!r}, {y!r}) and radius {radius!r} must be finite.")
    if not (0 <= radius <= 20):
        raise InvalidInputError(f"radius={radius!r} must be in 0..20 metres.")
    if max(abs(x), abs(y)) > MAX_COORDINATE:
        raise InvalidInputError(
            f"position ({x!r}, {y!r}) lies more than {MAX_COORDINATE:g} m from the map's "
            "origin; give map coordinates in metres."
        )
    out = []
    for uid, dist in glmap.grid.units_near(x, y, radius):
        info = details(glmap, glmap.unit(uid))
        info.distance = round(dist, 4)
        out.append(info)
    return out
