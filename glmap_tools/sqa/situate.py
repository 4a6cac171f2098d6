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
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from glmap_tools.errors import InvalidInputError, NoMatchError
from glmap_tools.sqa.constrain import constrained_pose, reading_text, targets
from glmap_tools.sqa.phrases import core_phrase, split_situation
from glmap_tools.sqa.place import centroid, closest_pair, stand_point_near
from glmap_tools.sqa.reading import SituationReading, read_situation
from glmap_tools.sqa.relations import prefer_related, relation_phrases
from glmap_tools.sqa.situation import TIE, ScoredUnit, Situation, top_units
from glmap_tools.sqa.stand import front_stand_point

if TYPE_CHECKING:
    from glmap_tools.map.glmap import GLMap
    from glmap_tools.nav.scorers import Scorer, UnitText
    from glmap_tools.nav.value import ValueMap

# Imports inside functions stay there: language.embed, scipy, numba load on first use.

SIGMA = 0.5  # m: Eq. 7 bandwidth, the nav default (about a person's reach)
MIN_SCORE = 0.15  # best p below this on both maps: the text matches nothing
LOW_CONFIDENCE = 0.35  # best p below this: a result, marked low-confidence
MAX_TEXT = 512
REGION_MARGIN = 0.1  # a region must beat the best anchor object by this to place the agent


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
    text = _checked_text(glmap, text, reading)
    scorer, split_text, reading = _scorer_and_reading(glmap, text, scorer, split_text, reading)
    location, facing = _phrases(text, reading, split_text)
    notes: list[str] = []
    ev = _evidence(glmap, scorer, location, facing, split_text, relate, notes)
    _check_some_match(ev, text)
    h_r, h_o, peak_o = _heat_maps(glmap, ev, facing, sigma)
    anchors = top_units(ev.r_units, ev.r_scores)
    peak_r, peak_o, anchor_ids, facing_id = _anchor_and_facing(
        glmap, ev, h_r, peak_o, anchors, facing, split_text, sight, notes, text
    )
    pose = _pose(glmap, peak_r, peak_o, anchor_ids, front_side, backrest, notes)
    x, y, heading, anchor_ids, facing_id = _egocentric_pose(
        glmap, scorer, ev, reading, pose, anchor_ids, facing_id, peak_o, split_text, backrest, notes
    )
    confidence = min(ev.best_r, ev.best_o) if facing else ev.best_r
    return Situation(
        x=x,
        y=y,
        heading=heading,
        h_r=h_r,
        h_o=h_o,
        peak_r=peak_r,
        peak_o=peak_o,
        anchors=anchors,
        facing=top_units(ev.instances, ev.p_o),
        confidence=confidence,
        low_confidence=confidence < LOW_CONFIDENCE,
        location_text=location,
        facing_text=facing,
        notes=notes,
        anchor_id=anchor_ids[0] if anchor_ids else None,
        facing_id=facing_id,
        reading=reading,
    )


def _checked_text(glmap: GLMap, text: str, reading: SituationReading | None) -> str:
    """The situation text (a reading's own words when `text` is empty), checked."""
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
    return text


def _scorer_and_reading(
    glmap: GLMap,
    text: str,
    scorer: Scorer | None,
    split_text: bool | None,
    reading: SituationReading | None,
) -> tuple[Scorer, bool, SituationReading]:
    """(scorer, split_text, reading) with their defaults: the embedding scorer, splitting
    the text for it alone, and the offline reader's reading."""
    from glmap_tools.nav.scorers import EmbeddingScorer

    if scorer is None:
        scorer = EmbeddingScorer(glmap.embedder)
    if split_text is None:
        split_text = isinstance(scorer, EmbeddingScorer)
    if reading is None:
        reading = read_situation(text)
    return scorer, split_text, reading


def _phrases(text: str, reading: SituationReading, split_text: bool) -> tuple[str, str]:
    """(location, facing) phrases to score: the reading's anchor and facing object, or the
    whole text for both (a scorer that reads the whole text)."""
    if not split_text:
        return text.strip(), text.strip()
    # Scored as "the <words>", as the phrases of the earlier split were.
    location = f"the {reading.anchor}" if reading.anchor else ""
    facing = f"the {reading.facing}" if reading.facing else ""
    if not location and not facing and reading.constraints:
        location = f"the {reading.constraints[0].object}"  # "the lamp is on my left"
    if not location and not facing:
        location = core_phrase(split_situation(text)[0])
    return location, facing


@dataclass(frozen=True)
class _Evidence:
    """The units scored against the phrases.

    Attributes:
        instances, regions: the map's units.
        p_o: [len(instances)] facing scores; p_r: [len(regions)] location scores.
        p_anchor: [len(instances)] anchor-object scores (zeros unless the text is split).
        r_units, r_scores: what H_r is made of (regions, and instances when split).
        best_r, best_o: the best location and facing scores.
    """

    instances: list[UnitText]
    regions: list[UnitText]
    p_o: np.ndarray
    p_r: np.ndarray
    p_anchor: np.ndarray
    r_units: list[UnitText]
    r_scores: np.ndarray
    best_r: float
    best_o: float


def _evidence(
    glmap: GLMap,
    scorer: Scorer,
    location: str,
    facing: str,
    split_text: bool,
    relate: bool,
    notes: list[str],
) -> _Evidence:
    """p_o, p_r and the anchor scores p_anchor of the map's units."""
    from glmap_tools.nav.scorers import map_units

    instances, regions = map_units(glmap, "instances"), map_units(glmap, "regions")
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
    return _Evidence(instances, regions, p_o, p_r, p_anchor, r_units, r_scores, best_r, best_o)


def _check_some_match(ev: _Evidence, text: str) -> None:
    """Raise NoMatchError, naming the best candidates, when nothing scores MIN_SCORE."""
    if ev.best_r >= MIN_SCORE or ev.best_o >= MIN_SCORE:
        return
    cands = top_units(ev.r_units + list(ev.instances), np.concatenate([ev.r_scores, ev.p_o]), 5)
    shown = ", ".join(f"{u.kind} {u.unit_id} {u.text[:40]!r} ({u.score:.2f})" for u in cands)
    raise NoMatchError(
        f"nothing in the map matches the situation {text!r} (best scores below "
        f"{MIN_SCORE}): {shown or 'no candidates'}. Describe it with objects the map "
        "holds (find_instance / map_summary list them)."
    )


def _heat_maps(
    glmap: GLMap, ev: _Evidence, facing: str, sigma: float
) -> tuple[ValueMap, ValueMap | None, tuple[float, float] | None]:
    """(H_r, H_o, l_o = argmax H_o): H_o only when something faced scores MIN_SCORE."""
    from glmap_tools.nav.value import TRUNCATE, map_window, value_map_from_scores

    window = map_window(glmap, TRUNCATE * sigma)
    h_r = value_map_from_scores(
        {u.unit_id: float(s) for u, s in zip(ev.r_units, ev.r_scores, strict=True)},
        glmap.grid,
        window,
        sigma,
        unit_mass="cells",  # as tuned for localisation; the nav default is 'unit'
    )
    if not (facing and ev.best_o >= MIN_SCORE):
        return h_r, None, None
    h_o = value_map_from_scores(
        {u.unit_id: float(s) for u, s in zip(ev.instances, ev.p_o, strict=True)},
        glmap.grid,
        window,
        sigma,
        unit_mass="cells",
    )
    return h_r, h_o, h_o.argmax_xy()


def _anchor_and_facing(
    glmap: GLMap,
    ev: _Evidence,
    h_r: ValueMap,
    peak_o: tuple[float, float] | None,
    anchors: tuple[ScoredUnit, ...],
    facing: str,
    split_text: bool,
    sight: bool,
    notes: list[str],
    text: str,
) -> tuple[tuple[float, float], tuple[float, float] | None, list[int], int | None]:
    """(argmax H_r, l_o, the units l_a is placed at, the unit l_o is on): from the heat
    maps, or the best anchor/facing object pair when an object names where one stands."""
    facing_id = top_units(ev.instances, ev.p_o, 1)[0].unit_id if peak_o is not None else None
    peak_r, anchor_ids = _anchor(glmap, ev, h_r, peak_o, anchors, notes, text)
    pair = _object_pair(glmap, ev, facing, split_text, sight, notes)
    if pair is not None:
        anchor_ids = [pair[0]]
        peak_r = centroid(glmap, pair[0])
        if pair[1] is not None:
            peak_o = centroid(glmap, pair[1])
            facing_id = pair[1]
    return peak_r, peak_o, anchor_ids, facing_id


def _anchor(
    glmap: GLMap,
    ev: _Evidence,
    h_r: ValueMap,
    peak_o: tuple[float, float] | None,
    anchors: tuple[ScoredUnit, ...],
    notes: list[str],
    text: str,
) -> tuple[tuple[float, float], list[int]]:
    """(argmax H_r, the units l_a is placed at): the units whose cells carry the peak, or,
    when nothing matches the location, the best faced object."""
    if h_r.empty or ev.best_r < MIN_SCORE:
        if peak_o is None:
            raise NoMatchError(f"nothing in the map tells where {text!r} is.")
        notes.append("no unit matches the location: l_a from what is faced")
        return peak_o, [u.unit_id for u in top_units(ev.instances, ev.p_o, 1)]
    peak_r = h_r.argmax_xy() or (0.0, 0.0)
    anchor_ids = [
        u.unit_id
        for u in anchors
        if glmap.grid.cell_of(*peak_r) in glmap.grid.cells_of_unit(u.unit_id)
        or u.score >= 0.9 * anchors[0].score
    ][:1] or [anchors[0].unit_id]
    return peak_r, anchor_ids


def _object_pair(
    glmap: GLMap,
    ev: _Evidence,
    facing: str,
    split_text: bool,
    sight: bool,
    notes: list[str],
) -> tuple[int, int | None] | None:
    """(anchor id, facing id) when an object names where one stands, else None.

    Eq. 7 sums a unit's score over all its cells, so a large region outweighs a small
    anchor at the peak; the anchor object itself is taken when it scores MIN_SCORE and a
    region beats it by less than REGION_MARGIN, and among equally good anchors and facing
    objects the pair closest together (one faces something in the same room).
    """
    if not (split_text and len(ev.instances)):
        return None
    best_a = float(ev.p_anchor.max())
    best_region = float(ev.p_r.max()) if len(ev.p_r) else 0.0
    if not (best_a >= MIN_SCORE and best_a + REGION_MARGIN >= best_region):
        return None
    p_face = ev.p_o if facing else None
    pair = closest_pair(glmap, ev.instances, ev.p_anchor, p_face, sight, TIE, MIN_SCORE)
    notes.append(
        "pose from the best anchor/facing pair (on ties: "
        + ("the facing object in line of sight from the anchor, then " if sight else "")
        + "the closest pair)"
    )
    return pair


def _pose(
    glmap: GLMap,
    peak_r: tuple[float, float],
    peak_o: tuple[float, float] | None,
    anchor_ids: list[int],
    front_side: bool,
    backrest: bool,
    notes: list[str],
) -> tuple[float, float, float]:
    """(x, y, theta): l_a on the anchor's front side (or by it, nearest l_o), facing l_o
    (or the anchor when nothing is faced)."""
    stand: tuple[float, float] | None = None
    if front_side and anchor_ids and anchor_ids[0] in glmap.instances:
        stand = front_stand_point(glmap, anchor_ids[:1], notes, backrest=backrest)
    x, y = stand or stand_point_near(glmap, peak_r, anchor_ids, peak_o, notes)
    if peak_o is not None and math.hypot(peak_o[0] - x, peak_o[1] - y) > 1e-6:
        heading = math.atan2(peak_o[1] - y, peak_o[0] - x)
    else:
        heading = math.atan2(peak_r[1] - y, peak_r[0] - x) if (x, y) != peak_r else 0.0
        notes.append("no facing target: heading towards the anchor")
    return x, y, heading


def _egocentric_pose(
    glmap: GLMap,
    scorer: Scorer,
    ev: _Evidence,
    reading: SituationReading,
    pose: tuple[float, float, float],
    anchor_ids: list[int],
    facing_id: int | None,
    peak_o: tuple[float, float] | None,
    split_text: bool,
    backrest: bool,
    notes: list[str],
) -> tuple[float, float, float, list[int], int | None]:
    """(x, y, theta, anchor ids, facing id) as the reading's egocentric constraints choose
    them (`glmap_tools.sqa.constrain`); `pose` and the ids as given when none names
    anything in the map. With l_o (`peak_o`), the facing scores weigh the candidates."""
    tgts = targets(glmap, scorer, ev.instances, reading.constraints, TIE, MIN_SCORE)
    if not tgts:
        return (*pose, anchor_ids, facing_id)
    x, y, heading, a_id, f_id = constrained_pose(
        glmap,
        ev.instances,
        tgts,
        pose,
        anchor_ids[0] if anchor_ids else None,
        ev.p_anchor if split_text and float(ev.p_anchor.max(initial=0.0)) >= MIN_SCORE else None,
        ev.p_o if peak_o is not None else None,
        facing_id,
        anchor_from_facing=ev.best_r < MIN_SCORE,
        backrest=backrest,
        notes=notes,
    )
    return x, y, heading, ([a_id] if a_id is not None else anchor_ids), f_id
