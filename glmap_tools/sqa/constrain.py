"""Candidate poses scored against every constraint of a situation reading.

"I am at the desk, the window behind me and the bookcase at my 2 o'clock": the desk gives
where one stands, and the heading is whatever puts the window behind and the bookcase at
-60 degrees. With several same-named anchors (three chairs) each gives a stand point, and
the constraints, not the order of the units, pick among them.

A candidate pose (x, y, theta) scores, per constraint, the best over the units matching
its object (within TIE of the best embedding score, at least MIN_SCORE) of
p(unit) * exp(-(d / SPREAD)^2 / 2) * fade(distance), d the angle between the unit's
bearing from the pose and the bearing the constraint asks for (left +90, right -90,
behind 180, k o'clock -30k degrees), and fade 1 within NEAR m, falling by e per FADE m
beyond. A facing object adds the same term at bearing 0. The pose with the highest sum
wins; exact ties go to the closest anchor/facing pair (the earlier rule).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from glmap_tools.sqa.place import centroid, free_cells, stand_point_near
from glmap_tools.sqa.situation import TIE
from glmap_tools.sqa.stand import front_stand_point

if TYPE_CHECKING:
    from glmap_tools.map.glmap import GLMap
    from glmap_tools.nav.scorers import Scorer, UnitText
    from glmap_tools.sqa.reading import Constraint, SituationReading

SPREAD = {"side": 35.0, "clock": 25.0}  # deg: how far off a stated direction still fits
NEAR = 2.5  # m: what is "on my left" is this near; farther, its fit fades by e per FADE m
FADE = 1.5
MAX_CANDIDATES = 6  # matching units per constraint, best first
HEADINGS = 72  # free headings tried when nothing is faced (every 5 degrees)


@dataclass(frozen=True)
class Target:
    """The units that may be a constraint's object: centres [K, 2] (m) and scores [K]."""

    bearing: float  # deg the object should lie at (+ = left)
    spread: float  # deg
    centres: np.ndarray  # [K, 2]
    scores: np.ndarray  # [K]
    ids: tuple[int, ...]
    text: str


def targets(
    glmap: GLMap,
    scorer: Scorer,
    instances: list[UnitText],
    constraints: tuple[Constraint, ...],
    tie: float,
    min_score: float,
) -> list[Target]:
    """One `Target` per constraint whose object matches some unit (others are dropped)."""
    out = []
    for c in constraints:
        p = scorer.score(c.object, instances)
        if not len(p) or float(p.max()) < min_score:
            continue
        keep = [i for i in np.argsort(-p, kind="stable") if p[i] >= float(p.max()) - tie]
        keep = keep[:MAX_CANDIDATES]
        ids = tuple(instances[i].unit_id for i in keep)
        centres = np.array(
            [glmap.instances[u].gaussians.means[:, :2].mean(axis=0) for u in ids], np.float64
        )
        spread = SPREAD["clock"] if c.clock is not None else SPREAD["side"]
        out.append(
            Target(c.bearing_deg, spread, centres, p[keep].astype(np.float64), ids, c.object)
        )
    return out


def fit(x: float, y: float, heading: np.ndarray, target: Target) -> np.ndarray:
    """[H] how well each heading (radians) puts the target at its bearing from (x, y)."""
    d = target.centres - (x, y)
    dist = np.hypot(d[:, 0], d[:, 1])
    ang = np.degrees(np.arctan2(d[:, 1], d[:, 0]))  # [K]
    off = (ang[None, :] - np.degrees(heading)[:, None] - target.bearing + 180.0) % 360.0 - 180.0
    fade = np.where(dist <= NEAR, 1.0, np.exp(-(dist - NEAR) / FADE))
    score = target.scores[None, :] * fade[None, :] * np.exp(-0.5 * (off / target.spread) ** 2)
    score[:, dist < 0.05] = 0.0  # the unit one stands in says nothing about direction
    return np.asarray(score.max(axis=1))


def best_heading(x: float, y: float, tgts: list[Target]) -> tuple[float, float]:
    """(heading rad, summed fit) that best satisfies the targets from (x, y); candidate
    headings are every 5 degrees and those that put a target unit exactly at its bearing."""
    cands = [np.linspace(-math.pi, math.pi, HEADINGS, endpoint=False)]
    for t in tgts:
        d = t.centres - (x, y)
        cands.append(np.arctan2(d[:, 1], d[:, 0]) - math.radians(t.bearing))
    h = np.concatenate(cands)
    total = np.zeros(len(h))
    for t in tgts:
        total += fit(x, y, h, t)
    k = int(np.argmax(total))
    return float(math.remainder(h[k], math.tau)), float(total[k])


def pose_score(x: float, y: float, heading: float, tgts: list[Target]) -> float:
    """Summed fit of one pose."""
    h = np.array([heading])
    return float(sum(fit(x, y, h, t)[0] for t in tgts))


def reading_text(reading: SituationReading) -> str:
    """A situation text that says what `reading` says (for messages and scorers)."""
    parts = []
    if reading.anchor:
        parts.append(
            f"I am {reading.posture or 'standing'} {reading.relation or 'at'} the {reading.anchor}"
        )
    if reading.facing:
        parts.append(f"facing the {reading.facing}")
    for c in reading.constraints:
        where = (
            f"at my {c.clock} o'clock"
            if c.clock
            else ("behind me" if c.side == "behind" else f"on my {c.side}")
        )
        parts.append(f"the {c.object} is {where}")
    return ", ".join(parts) + "." if parts else ""


def constrained_pose(
    glmap: GLMap,
    instances: list[UnitText],
    tgts: list[Target],
    default: tuple[float, float, float],
    default_anchor: int | None,
    p_anchor: np.ndarray | None,
    p_face: np.ndarray | None,
    default_facing: int | None,
    *,
    anchor_from_facing: bool,
    backrest: bool,
    notes: list[str],
) -> tuple[float, float, float, int | None, int | None]:
    """(x, y, heading, anchor id, facing id): the candidate pose that best fits every
    constraint (`glmap_tools.sqa.constrain`). Candidates: a stand point at each anchor
    within TIE of the best (or, with no anchor, around each facing candidate), headed at
    each facing candidate, or, with nothing faced, at the heading that fits best. The
    pose the earlier rules chose wins exact ties (a bonus of TIE / 10)."""
    ids = [u.unit_id for u in instances]
    faces = _near_best(p_face) if p_face is not None else []
    stands = _stand_candidates(glmap, ids, p_anchor, faces, anchor_from_facing, backrest)
    if not stands:
        stands = [(default[0], default[1], default_anchor)]
    best: tuple[float, float, float, float, int | None, int | None] | None = None
    for x, y, a in stands:
        bonus = (
            TIE / 10
            if (a == default_anchor and a is not None)
            or (a is None and math.hypot(x - default[0], y - default[1]) < 1e-6)
            else 0.0
        )
        if faces:
            for j in faces:
                f = ids[j]
                if f == a:
                    continue
                c = centroid(glmap, f)
                h = math.atan2(c[1] - y, c[0] - x)
                score = float(p_face[j]) + pose_score(x, y, h, tgts)  # type: ignore[index]
                score += bonus if f == default_facing else 0.0
                if best is None or score > best[0]:
                    best = (score, x, y, h, a, f)
        else:
            h, score = best_heading(x, y, tgts)
            if best is None or score + bonus > best[0]:
                best = (score + bonus, x, y, h, a, None)
    if best is None:
        return (*default, default_anchor, default_facing)
    notes.append(
        f"pose from {len(stands)} stand point(s) scored against "
        + ", ".join(f"'{t.text}' at {t.bearing:.0f} deg" for t in tgts)
        + (" and what is faced" if faces else "")
        + f" (fit {best[0]:.2f})"
    )
    return best[1], best[2], best[3], best[4] if best[4] is not None else default_anchor, best[5]


def _near_best(p: np.ndarray) -> list[int]:
    """Indices of the scores within TIE of the best, best first (at most MAX_CANDIDATES)."""
    order = np.argsort(-p, kind="stable")
    return [int(i) for i in order if p[i] >= float(p.max()) - TIE][:MAX_CANDIDATES]


def _stand_candidates(
    glmap: GLMap,
    ids: list[int],
    p_anchor: np.ndarray | None,
    faces: list[int],
    anchor_from_facing: bool,
    backrest: bool,
) -> list[tuple[float, float, int | None]]:
    """(x, y, anchor id) stand points: one at each anchor within TIE of the best, or with
    no anchor, the front of each facing candidate and a ring of free cells around it."""
    stands: list[tuple[float, float, int | None]] = []
    if p_anchor is not None and not anchor_from_facing:
        for i in _near_best(p_anchor):
            uid = ids[i]
            pt = front_stand_point(glmap, [uid], [], backrest=backrest)
            pt = pt or stand_point_near(glmap, centroid(glmap, uid), [uid], None, [])
            stands.append((pt[0], pt[1], uid))
    elif faces:
        free, _ = free_cells(glmap, set())
        for j in faces:
            centre = np.array(centroid(glmap, ids[j]))
            pt = front_stand_point(glmap, [ids[j]], [], backrest=backrest)
            if pt is not None:
                stands.append((pt[0], pt[1], None))
            if len(free):
                d = np.hypot(*(free - centre).T)
                ring = free[(d >= 0.8) & (d <= 2.5)]
                step = max(1, len(ring) // 48)
                stands += [(float(q[0]), float(q[1]), None) for q in ring[::step]]
    return stands
