"""Locate a situation described in text (paper §3.2, SQA): p_r, p_o -> H_r, H_o -> pose.

For a situation text T_l ("sitting on the edge of the bed, facing the couch") every region
gets p_r = f(r, T_l) (is the agent in or near it) and every instance p_o = f(o, T_l) (is
the agent facing it). Both are placed on the index grid and smoothed by Eq. 7 into H_r and
H_o; l_a = argmax H_r snapped to seen-free space, l_o = argmax H_o, and
theta = atan2(l_o - l_a).

Two scorers fit:
- an LLM (`LLMScorer(mode="sqa")`, the paper's f_LLM): it reads the whole text and tells
  "where I am" from "what I face" itself;
- the offline default, embedding cosine: a sentence embedding cannot tell the two roles
  apart, so the text is split at its facing clause ("facing X", "looking at X", "X in
  front of me") into a location phrase and a facing phrase; H_r then also counts the
  instances that match the location phrase (the anchor the agent stands at), since regions
  alone place the agent somewhere in a room, not at the bed.

Relation words (`glmap_tools.sqa.relations`): offline, each phrase is split into the
object's own words ("the navy kitchen cabinet"), which score the instances, and relations
("next to the white refrigerator", "on the X", "in the kitchen"), which decide among the
candidates within TIE of the best: per relation, the best score of what it names among the
instances within 1 m of the candidate, or of the room among the regions holding it. A
whole-phrase embedding cannot tell two equally named cabinets apart by their neighbours.

l_a, when an object anchors the text: a seen-free cell on the object's accessible (front)
side, read from the map (`glmap_tools.sqa.stand`: the face whose back is blocked by a wall
or furniture is the back; the cell covering most of the 0.3-1.0 m band in front). The
earlier rule, kept as the fallback (a region anchor, too few Gaussians, no free band cell)
and for `front_side=False`: the free cell within reach (0.6 m) of the anchor closest to l_o;
it put the agent at the anchor's end nearest what is faced, often beside or behind it
(tune: 50% of situations within 1 m and 45 degrees, 69% with the front side).

Same-named objects (three kitchen cabinets, two dining tables): the paper takes l_a =
argmax H_r and l_o = argmax H_o separately, which with several equal peaks can pair an
anchor and a facing object on opposite sides of a wall. Here the pair is chosen: among
the anchor and facing candidates within TIE of the best scores, the pairs whose facing
object is in no line of sight from the anchor's stand band are dropped
(`glmap_tools.sqa.sight`; unless all are), then the closest pair is taken. Tried on tune
and not kept (docs/evaluation.md): weighting every pair by how much of the band sees the
facing object and standing at the cell of highest expected success over all pairs (0.63
vs 0.66: within a room the candidates are equally likely, and furniture hides objects on
the 2D occupancy as walls do), and favouring the face that looks towards the facing object.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from glmap_tools.errors import InvalidInputError, NoMatchError
from glmap_tools.map.occupancy import FREE
from glmap_tools.sqa.constrain import constrained_pose, reading_text, targets
from glmap_tools.sqa.reading import SituationReading, read_situation
from glmap_tools.sqa.relations import prefer_related, relation_phrases
from glmap_tools.sqa.sight import SEEN_MIN, SightCheck
from glmap_tools.sqa.stand import front_stand_point

if TYPE_CHECKING:
    from glmap_tools.map.glmap import GLMap
    from glmap_tools.nav.scorers import Scorer, UnitText
    from glmap_tools.nav.value import ValueMap

SIGMA = 0.5  # m: Eq. 7 bandwidth, the nav default (about a person's reach)
MIN_SCORE = 0.15  # best p below this on both maps: the text matches nothing
LOW_CONFIDENCE = 0.35  # best p below this: a result, marked low-confidence
STAND_REACH = 0.6  # m from the anchor's cells: where one stands at it ...
STAND_RADIUS = 1.2  # ... or, when nothing is free that close, at most this far
MAX_TEXT = 512
TIE = 0.05  # scores this close to the best count as equally good
REGION_MARGIN = 0.1  # a region must beat the best anchor object by this to place the agent

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


def _top(units: list[UnitText], scores: np.ndarray, k: int = 3) -> tuple[ScoredUnit, ...]:
    order = np.argsort(-scores, kind="stable")[:k]
    return tuple(
        ScoredUnit(units[i].unit_id, units[i].kind, float(scores[i]), units[i].text)
        for i in order
        if scores[i] > 0
    )


def _free_cells(glmap: GLMap, exclude: set[tuple[int, int]]) -> tuple[np.ndarray, float]:
    """[N, 2] world centres of cells where an agent can stand, and the cell size.

    Seen-free cells clear of obstacles by the agent radius, outside the `exclude` cells
    (the anchor's own footprint: one stands by the bed, the camera is not in it).
    """
    from glmap_tools.nav import NavConfig, traversable

    occ = glmap.occupancy.to_dense()
    ok = traversable(occ, NavConfig().agent_radius)
    if exclude:
        cells = np.array(sorted(exclude), dtype=np.int64)
        r, c = cells[:, 1] - occ.origin[1], cells[:, 0] - occ.origin[0]
        inside = (r >= 0) & (r < ok.shape[0]) & (c >= 0) & (c < ok.shape[1])
        ok[r[inside], c[inside]] = False
    if not ok.any():
        ok = occ.state == FREE
    rows, cols = np.nonzero(ok)
    s = occ.cell_size
    xy = np.stack(
        [(cols + occ.origin[0] + 0.5) * s, (rows + occ.origin[1] + 0.5) * s], axis=1
    ).astype(np.float64)
    return xy, s


def _stand_point(
    glmap: GLMap,
    peak: tuple[float, float],
    anchor_ids: list[int],
    toward: tuple[float, float] | None,
    notes: list[str],
) -> tuple[float, float]:
    """l_a: a seen-free cell near the anchor units (or the peak), closest to `toward`."""
    cells: set[tuple[int, int]] = set()
    for uid in anchor_ids:
        unit = glmap.unit(uid)
        members = getattr(unit, "instance_ids", None) or [uid]
        for m in members:
            cells |= set(glmap.grid.cells_of_unit(int(m)))
    free, s = _free_cells(glmap, cells)
    if len(free) == 0:
        notes.append("no seen-free cell in the map: l_a is the H_r peak itself")
        return peak
    if cells:
        anchor_xy = (np.array(sorted(cells), dtype=np.float64) + 0.5) * s
        # Distance from every free cell to the anchor's nearest cell.
        from scipy.spatial import cKDTree

        d, _ = cKDTree(anchor_xy).query(free)
    else:
        d = np.hypot(free[:, 0] - peak[0], free[:, 1] - peak[1])
    near = free[d <= STAND_REACH]
    if len(near) == 0:
        near = free[d <= STAND_RADIUS]
    if len(near) == 0:
        k = int(np.argmin(d))
        notes.append(f"no free cell within {STAND_RADIUS} m of the anchor; nearest is {d[k]:.2f} m")
        return float(free[k, 0]), float(free[k, 1])
    if toward is not None:
        k = int(np.argmin(np.hypot(near[:, 0] - toward[0], near[:, 1] - toward[1])))
        notes.append("l_a: the free cell by the anchor closest to what is faced")
    else:
        k = int(np.argmin(np.hypot(near[:, 0] - peak[0], near[:, 1] - peak[1])))
        notes.append("l_a: the free cell nearest the H_r peak (nothing faced is named)")
    return float(near[k, 0]), float(near[k, 1])


def _centroid(glmap: GLMap, unit_id: int) -> tuple[float, float]:
    c = glmap.instances[unit_id].gaussians.means.mean(axis=0)
    return float(c[0]), float(c[1])


def _closest_pair(
    glmap: GLMap,
    instances: list[UnitText],
    p_anchor: np.ndarray,
    p_face: np.ndarray | None,
    sight: bool = True,
) -> tuple[int, int | None]:
    """(anchor id, facing id): the best-scored ones, ties (within TIE) broken by distance
    among the pairs whose facing object is seen from the anchor's stand band."""
    ids = [u.unit_id for u in instances]
    cand_a = [i for i, p in enumerate(p_anchor) if p >= float(p_anchor.max()) - TIE]
    if p_face is None or float(p_face.max()) < MIN_SCORE:
        return ids[cand_a[0]], None
    cand_f = [j for j, p in enumerate(p_face) if p >= float(p_face.max()) - TIE]
    pairs = [(i, j) for i in cand_a for j in cand_f if i != j]
    if sight and len(pairs) > 1:
        # One sees what one faces: drop the pairs split by a wall, unless all are.
        check = SightCheck(glmap)
        shares = [check.seen_share(ids[i], ids[j]) for i, j in pairs]
        seen = [p for p, sh in zip(pairs, shares, strict=True) if sh is None or sh >= SEEN_MIN]
        pairs = seen or pairs
    best: tuple[float, int, int] | None = None
    for i, j in pairs:
        a, f = _centroid(glmap, ids[i]), _centroid(glmap, ids[j])
        d = math.hypot(a[0] - f[0], a[1] - f[1])
        if best is None or d < best[0]:
            best = (d, i, j)
    if best is None:
        return ids[cand_a[0]], ids[cand_f[0]]
    return ids[best[1]], ids[best[2]]


def situate(
    glmap: GLMap,
    text: str,
    scorer: Scorer | None = None,
    *,
    split_text: bool | None = None,
    sigma: float = SIGMA,
    front_side: bool = True,
    sight: bool = True,
    relate: bool = True,
    backrest: bool = True,
    reading: SituationReading | None = None,
) -> Situation:
    """Locate the situation `text` in `glmap`.

    Args:
        glmap: the map (instances, regions, occupancy).
        text: the situation description T_l.
        scorer: f(u, T_l) in [0, 1]; default `EmbeddingScorer(glmap.embedder)`.
        split_text: score the location and facing phrases separately; default True for
            the embedding scorer and False for any other (an LLM reads the whole text).
        sigma: Eq. 7 bandwidth (m).
        front_side: stand on the anchor object's accessible side (`glmap_tools.sqa.stand`);
            False: the free cell by the anchor nearest what is faced (the earlier rule).
        sight: among equally good anchor/facing pairs, keep those whose facing object is
            in line of sight from the anchor's stand band (`glmap_tools.sqa.sight`)
            before taking the closest; False: the closest pair (the earlier rule).
        relate: offline, score an object by its own words and let the relations after
            them ("next to the X", "on the X", "in the <room>") decide among equally good
            candidates (`glmap_tools.sqa.relations`); False: score the whole phrase (the
            earlier rule).
        backrest: let a rising edge (backrest, headboard) mark the anchor's back
            (`glmap_tools.sqa.stand`); False: the floor around it alone (the earlier rule).
        reading: the text already read (`glmap_tools.sqa.reading`; an LLM's or a
            caller's); default: the offline reader's. Its anchor and facing are the
            phrases scored, and its egocentric constraints score the candidate poses
            (`glmap_tools.sqa.constrain`). With a reading, `text` may be empty.

    Raises:
        InvalidInputError: empty or overlong text, or an empty map.
        NoMatchError: nothing in the map matches the text (the best candidates and their
            scores are in the message; no pose is invented).
    """
    from glmap_tools.nav.scorers import EmbeddingScorer, map_units
    from glmap_tools.nav.value import TRUNCATE, map_window, value_map_from_scores

    if reading is not None and (not isinstance(text, str) or not text.strip()):
        text = reading_text(reading)
    if not isinstance(text, str) or not text.strip():
        raise InvalidInputError(
            "the situation text is empty; describe where you are, e.g. 'sitting on the "
            "bed, facing the window'."
        )
    if len(text) > MAX_TEXT:
        raise InvalidInputError(f"the situation text has {len(text)} characters; max {MAX_TEXT}.")
    if not glmap.instances:
        raise InvalidInputError(
            "the map is empty: build it first (observe_frame, sim_step or glmap build)."
        )
    if scorer is None:
        scorer = EmbeddingScorer(glmap.embedder)
    if split_text is None:
        split_text = isinstance(scorer, EmbeddingScorer)
    if reading is None:
        reading = read_situation(text)
    if split_text:
        # Scored as "the <words>", as the phrases of the earlier split were.
        location = f"the {reading.anchor}" if reading.anchor else ""
        facing = f"the {reading.facing}" if reading.facing else ""
        if not location and not facing and reading.constraints:
            location = f"the {reading.constraints[0].object}"  # "the lamp is on my left"
        if not location and not facing:
            location = core_phrase(split_situation(text)[0])
    else:
        location = facing = text.strip()
    instances, regions = map_units(glmap, "instances"), map_units(glmap, "regions")
    notes: list[str] = []
    # Offline: an object is scored by its own words; the relations ("next to the fridge",
    # "in the kitchen") then tell same-named candidates apart by what is around them.
    parse = relate and split_text
    loc_head, loc_rels = relation_phrases(location) if parse else (location, [])
    face_head, face_rels = relation_phrases(facing) if parse and facing else (facing, [])
    p_o = scorer.score(face_head or facing, instances) if facing else np.zeros(len(instances))
    p_r = scorer.score(location, regions) if regions and location else np.zeros(len(regions))
    # Offline: the anchor object the location phrase names joins the regions in H_r.
    p_anchor = (
        scorer.score(loc_head or location, instances)
        if split_text and location
        else np.zeros(len(instances))
    )
    if parse:
        p_anchor = prefer_related(glmap, scorer, instances, regions, p_anchor, loc_rels, TIE, notes)
        if facing:
            p_o = prefer_related(glmap, scorer, instances, regions, p_o, face_rels, TIE, notes)

    r_units = list(regions) + (list(instances) if split_text else [])
    r_scores = np.concatenate([p_r, p_anchor]) if split_text else p_r
    best_r = float(r_scores.max()) if len(r_scores) else 0.0
    best_o = float(p_o.max()) if len(p_o) else 0.0
    if best_r < MIN_SCORE and best_o < MIN_SCORE:
        cands = _top(r_units + list(instances), np.concatenate([r_scores, p_o]), 5)
        shown = ", ".join(f"{u.kind} {u.unit_id} {u.text[:40]!r} ({u.score:.2f})" for u in cands)
        raise NoMatchError(
            f"nothing in the map matches the situation {text!r} (best scores below "
            f"{MIN_SCORE}): {shown or 'no candidates'}. Describe it with objects the map "
            "holds (find_instance / map_summary list them)."
        )
    window = map_window(glmap, TRUNCATE * sigma)
    h_r = value_map_from_scores(
        {u.unit_id: float(s) for u, s in zip(r_units, r_scores, strict=True)},
        glmap.grid,
        window,
        sigma,
        unit_mass="cells",  # as tuned for localisation (session 4); the nav default is 'unit'
    )
    h_o = None
    peak_o = None
    if facing and best_o >= MIN_SCORE:
        h_o = value_map_from_scores(
            {u.unit_id: float(s) for u, s in zip(instances, p_o, strict=True)},
            glmap.grid,
            window,
            sigma,
            unit_mass="cells",
        )
        peak_o = h_o.argmax_xy()
    anchors = _top(r_units, r_scores)
    facing_id = _top(instances, p_o, 1)[0].unit_id if peak_o is not None else None
    if h_r.empty or best_r < MIN_SCORE:
        if peak_o is None:
            raise NoMatchError(f"nothing in the map tells where {text!r} is.")
        notes.append("no unit matches the location: l_a from what is faced")
        peak_r = peak_o
        anchor_ids = [u.unit_id for u in _top(instances, p_o, 1)]
    else:
        peak_r = h_r.argmax_xy() or (0.0, 0.0)
        # The units whose cells carry the peak decide where one stands.
        anchor_ids = [
            u.unit_id
            for u in anchors
            if glmap.grid.cell_of(*peak_r) in glmap.grid.cells_of_unit(u.unit_id)
            or u.score >= 0.9 * anchors[0].score
        ][:1] or [anchors[0].unit_id]
    stand: tuple[float, float] | None = None
    if split_text and len(instances):
        best_a = float(p_anchor.max())
        best_region = float(p_r.max()) if len(p_r) else 0.0
        if best_a >= MIN_SCORE and best_a + REGION_MARGIN >= best_region:
            # An object names where one stands: Eq. 7 sums a unit's score over all its
            # cells, so a large region outweighs a small anchor at the peak; take the
            # anchor object itself, and among equally good anchors and facing objects
            # the pair closest together (one faces something in the same room).
            pair = _closest_pair(glmap, instances, p_anchor, p_o if facing else None, sight)
            anchor_ids = [pair[0]]
            peak_r = _centroid(glmap, pair[0])
            if pair[1] is not None:
                peak_o = _centroid(glmap, pair[1])
                facing_id = pair[1]
            notes.append(
                "pose from the best anchor/facing pair (on ties: "
                + ("the facing object in line of sight from the anchor, then " if sight else "")
                + "the closest pair)"
            )
    if stand is None and front_side and anchor_ids and anchor_ids[0] in glmap.instances:
        stand = front_stand_point(glmap, anchor_ids[:1], notes, backrest=backrest)
    x, y = stand or _stand_point(glmap, peak_r, anchor_ids, peak_o, notes)
    if peak_o is not None and math.hypot(peak_o[0] - x, peak_o[1] - y) > 1e-6:
        heading = math.atan2(peak_o[1] - y, peak_o[0] - x)
    else:
        heading = math.atan2(peak_r[1] - y, peak_r[0] - x) if (x, y) != peak_r else 0.0
        notes.append("no facing target: heading towards the anchor")
    tgts = targets(glmap, scorer, instances, reading.constraints, TIE, MIN_SCORE)
    if tgts:
        x, y, heading, a_id, f_id = constrained_pose(
            glmap,
            instances,
            tgts,
            (x, y, heading),
            anchor_ids[0] if anchor_ids else None,
            p_anchor if split_text and float(p_anchor.max(initial=0.0)) >= MIN_SCORE else None,
            p_o if peak_o is not None else None,
            facing_id,
            anchor_from_facing=best_r < MIN_SCORE,
            backrest=backrest,
            notes=notes,
        )
        anchor_ids = [a_id] if a_id is not None else anchor_ids
        facing_id = f_id
    confidence = min(best_r, best_o) if facing else best_r
    return Situation(
        x=x,
        y=y,
        heading=heading,
        h_r=h_r,
        h_o=h_o,
        peak_r=peak_r,
        peak_o=peak_o,
        anchors=anchors,
        facing=_top(instances, p_o),
        confidence=confidence,
        low_confidence=confidence < LOW_CONFIDENCE,
        location_text=location,
        facing_text=facing,
        notes=notes,
        anchor_id=anchor_ids[0] if anchor_ids else None,
        facing_id=facing_id,
        reading=reading,
    )
