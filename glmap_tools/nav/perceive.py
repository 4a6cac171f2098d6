"""What a policy step reads off the map: the occupancy window around the agent, bump marks,
reachability, frontiers, the goal match and the walls."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from glmap_tools.language.text_merger import DELIMITER
from glmap_tools.map.occupancy import OBSTACLE, DenseOccupancy
from glmap_tools.nav.config import GOAL_MAX_BOTTOM, GOAL_MIN_SIZE, SCORE_TIE, NavConfig
from glmap_tools.nav.footprint import ROOM_WALL, GoalMatch, distances_to_cells
from glmap_tools.nav.frontiers import Frontier, frontiers
from glmap_tools.nav.grid import agent_rc, known_window, reframe
from glmap_tools.nav.motion import bump_cells, clearance, contact_cell, masks
from glmap_tools.nav.planner import DistanceField, distance_field
from glmap_tools.nav.scorers import Scorer, UnitText, map_units
from glmap_tools.nav.value import unit_cell_array, unit_core_cells
from glmap_tools.nav.wall_counts import structure_walls_kept

if TYPE_CHECKING:
    from glmap_tools.language.embed import Embedder
    from glmap_tools.map.glmap import GLMap
    from glmap_tools.perception.semantics import FrameSemantics

SHORT_MOVE = 0.0125  # metres: a move_forward this much short of a full step was stopped
FORGET_NEAR = 0.5  # metres: bump marks this close are forgotten when no step is open

Cell = tuple[int, int]


def occupancy_window(
    glmap: GLMap, agent_xy: tuple[float, float], blocked: set[Cell], config: NavConfig
) -> DenseOccupancy:
    """The map's known occupancy around the agent, `blocked` cells marked as obstacles."""
    dense = glmap.occupancy.to_dense()
    margin = math.ceil(config.window_margin / dense.cell_size)
    occ = reframe(dense, known_window(dense, margin, agent_xy))
    if blocked:
        cells = np.array(sorted(blocked), dtype=np.int64)
        r, c = cells[:, 1] - occ.origin[1], cells[:, 0] - occ.origin[0]
        h, w = occ.state.shape
        keep = (r >= 0) & (r < h) & (c >= 0) & (c < w)
        occ.state[r[keep], c[keep]] = OBSTACLE
    return occ


@dataclass(frozen=True)
class Bump:
    """Where the body touched when the simulator stopped the last forward move short.

    Attributes:
        cells: the (i, j) marks `nav.motion.bump_cells` gives (empty: no stopped move).
        contact: the contact point's own cell alone (`nav.motion.contact_cell`), the mark
            kept longest; empty with `cells`.
    """

    cells: set[Cell]
    contact: set[Cell]


def bump_marks(
    glmap: GLMap,
    xy: tuple[float, float],
    last_action: str | None,
    last_xy: tuple[float, float] | None,
    last_heading: float,
    config: NavConfig,
) -> Bump:
    """The `Bump` of the last action: empty when it was no stopped forward move."""
    if last_action != "move_forward" or last_xy is None:
        return Bump(set(), set())
    if math.dist(xy, last_xy) >= config.forward_step - SHORT_MOVE:
        return Bump(set(), set())
    occ = occupancy_window(glmap, xy, set(), config)
    cells = set(bump_cells(occ, xy, last_heading, config))
    return Bump(cells, {contact_cell(xy, last_heading, config, occ.cell_size)})


@dataclass(frozen=True)
class Surroundings:
    """The occupancy window (bump marks included) around the agent and what is derived
    from it: clearance, traversable cells, (plannable, speed), distance field, frontiers."""

    occ: DenseOccupancy
    clear: np.ndarray
    trav: np.ndarray
    plannable: tuple[np.ndarray, np.ndarray]
    field: DistanceField
    fronts: list[Frontier]


def surroundings_of(
    glmap: GLMap,
    xy: tuple[float, float],
    blocked: set[Cell],
    config: NavConfig,
    with_frontiers: bool = True,
) -> Surroundings:
    """The `Surroundings` of the agent at `xy` with `blocked` cells marked as obstacles."""
    occ = occupancy_window(glmap, xy, blocked, config)
    clear = clearance(occ)
    rc = agent_rc(occ, xy)
    trav, ok, speed = masks(occ, clear, rc, config)
    field = distance_field(occ, ok, rc, config.plan_stride, config.optimistic, speed)
    fronts = (
        frontiers(occ, xy, config.agent_radius, config.min_frontier_size, field.metres, trav=trav)
        if with_frontiers
        else []
    )
    return Surroundings(occ, clear, trav, (ok, speed), field, fronts)


def unfit_goals(glmap: GLMap) -> dict[int, str]:
    """Instance id -> why the agent cannot be expected to reach or recognise it as a goal.

    The rule `glmap sim episodes` refuses goals by (`GOAL_MAX_BOTTOM`, `GOAL_MIN_SIZE`), read
    on the map: the lowest Gaussian mean above the floor, the largest side of the means'
    box plus one grid cell (means sit inside an object's surface). A map without a floor
    height keeps every instance on the height rule.
    """
    out: dict[int, str] = {}
    cell = glmap.grid.cell_size
    for uid, unit in glmap.instances.items():
        if len(unit.gaussians) == 0:
            continue
        lo, hi = unit.bounds()
        if glmap.floor_z is not None and float(lo[2]) - glmap.floor_z > GOAL_MAX_BOTTOM:
            out[uid] = (
                f"its bottom is {float(lo[2]) - glmap.floor_z:.2f} m up, over {GOAL_MAX_BOTTOM} m"
            )
        elif float(np.max(hi - lo)) + cell < GOAL_MIN_SIZE:
            out[uid] = f"{float(np.max(hi - lo)) + cell:.2f} m at most, under {GOAL_MIN_SIZE} m"
    return out


def find_goal_match(
    glmap: GLMap,
    units: list[UnitText],
    scores: np.ndarray,
    rejected: set[int],
    config: NavConfig,
    scorer: Scorer | None = None,
    goal: str = "",
    prefer: int | None = None,
) -> GoalMatch | None:
    """The best-scoring instance at or above the stop threshold with enough observations.

    With `config.category_margin` set and a scorer that has `category_margins`, a candidate
    must instead score `config.category_threshold` and be closer to the goal than to any
    other label of the map by that margin (a category goal: "cabinet", not "kitchen cabinet").
    `rejected`: instances given up (no way to reach them) or unfit as goals (`unfit_goals`).
    With no candidate and no category check (InstNav), a goal of the form "the X next to /
    on the Y" is matched by category + relation on units without descriptions
    (`relation_match`).
    Ties (scores within `SCORE_TIE`, identical texts) go to `prefer` (the previous step's
    match) when it is among them, else to the lowest id: the same unit step after step.
    """
    margins = getattr(scorer, "category_margins", None)
    by_category = config.category_margin is not None and margins is not None
    threshold = config.category_threshold if by_category else config.stop_threshold
    cand = [
        (u, float(s))
        for u, s in zip(units, scores, strict=True)
        if u.kind == "instance"
        and u.unit_id not in rejected
        and s >= threshold
        and u.observations >= config.min_observations
    ]
    if cand and by_category:
        assert margins is not None and config.category_margin is not None
        vocabulary = [u.label for u in units if u.kind == "instance"]
        m = margins(goal, [u for u, _ in cand], vocabulary)
        cand = [c for c, v in zip(cand, m, strict=True) if v >= config.category_margin]
    if not cand and not by_category:
        return relation_match(glmap, units, scores, rejected, config, goal, prefer)
    if not cand:
        return None
    top = max(s for _, s in cand)
    tied = sorted((c for c in cand if c[1] >= top - SCORE_TIE), key=lambda c: c[0].unit_id)
    u, s = next((c for c in tied if c[0].unit_id == prefer), tied[0])
    cells = unit_core_cells(glmap, u.unit_id, config.footprint_core)
    return GoalMatch(u.unit_id, s, u.observations, cells)


# "the table next to the chair", "the lamp on the nightstand" (sim.instnav's InstNav goals;
# a trailing "in the bedroom" is read past), "the wardrobe in the bedroom": the head phrase,
# the relation, the anchor phrase (a room's name for "in").
_RELATION = re.compile(
    r"^(?:the|a|an)\s+(?P<head>.+?)\s+(?P<rel>next to|on)\s+(?:the|a|an)\s+"
    r"(?P<anchor>.+?)(?:\s+in\s+the\s+.+)?\.?$"
)
_IN_ROOM = re.compile(
    r"^(?:the|a|an)\s+(?P<head>.+?)\s+(?P<rel>in)\s+(?:the|a|an)\s+(?P<anchor>.+?)\.?$"
)
NEXT_TO = 1.0  # metres between footprints for "next to" (sim.instnav.NEAR; a test holds it)
ON_GAP = 0.1  # metres: "on" asks the two footprints to overlap, up to map rounding


@dataclass(frozen=True)
class RelationalGoal:
    """An InstNav goal read as category + relation: `head` `relation` the `anchor`."""

    head: str
    relation: str
    anchor: str


def relational_goal(goal: str) -> RelationalGoal | None:
    """ "the table next to the chair" -> ('table', 'next to', 'chair'); None for a goal of
    another form."""
    text = " ".join(goal.lower().split())
    m = _RELATION.match(text) or _IN_ROOM.match(text)
    if m is None:
        return None
    return RelationalGoal(m["head"], m["rel"], m["anchor"])


def _bare(unit: UnitText) -> bool:
    """The unit has no description beyond its label (a scan's objects: a category only)."""
    label = unit.label.strip().lower()
    parts = {p.strip().lower() for p in unit.text.split(DELIMITER.strip())} - {""}
    return bool(label) and parts <= {label}


def _named(phrase: str, labels: set[str]) -> str | None:
    """The longest label that ends `phrase` at a word boundary ('side table' before
    'table' for "the white side table"), or None."""
    fits = [lb for lb in labels if phrase == lb or phrase.endswith(" " + lb)]
    return max(fits, key=len) if fits else None


def relation_match(
    glmap: GLMap,
    units: list[UnitText],
    scores: np.ndarray,
    rejected: set[int],
    config: NavConfig,
    goal: str,
    prefer: int | None = None,
) -> GoalMatch | None:
    """The goal matched by category + relation when the map's units carry no descriptions.

    A scan's objects are their categories: "the table next to the chair" scores a unit
    "table" 0.59, under InstNav's 0.75, so the goal is never recognised. Read as category +
    relation, it matches an instance labelled with the goal's head category (the longest
    label of the map ending the head phrase), seen in `min_observations` frames, with no
    description beyond its label, that has an instance of the anchor's category within
    `NEXT_TO` ("next to") or `ON_GAP` ("on") of its cells; "in the <room>" only when the
    map holds a single instance of the category. Ties go to `prefer`, else to the best
    score, else to the lowest id.
    """
    rel = relational_goal(goal)
    if rel is None:
        return None
    instances = [u for u in units if u.kind == "instance"]
    labels = {u.label.strip().lower() for u in instances if u.label.strip()}
    head, anchor = _named(rel.head, labels), _named(rel.anchor, labels)
    if head is None or (rel.relation != "in" and (anchor is None or head == anchor)):
        return None
    score = {u.unit_id: float(v) for u, v in zip(units, scores, strict=True)}
    heads = [
        u
        for u in instances
        if u.label.strip().lower() == head
        and u.unit_id not in rejected
        and u.observations >= config.min_observations
        and _bare(u)
    ]
    if rel.relation == "in":
        # The map keeps no rooms of a scan: "in the <room>" singles out the head only when
        # the map holds one instance of its category.
        same = [u for u in instances if u.label.strip().lower() == head]
        if len(same) != 1 or not heads:
            return None
        u = heads[0]
        cells = unit_core_cells(glmap, u.unit_id, config.footprint_core)
        return GoalMatch(u.unit_id, score[u.unit_id], u.observations, cells)
    anchors = [u for u in instances if u.label.strip().lower() == anchor]
    if not heads or not anchors:
        return None
    s = glmap.grid.cell_size
    reach = NEXT_TO if rel.relation == "next to" else ON_GAP
    anchor_cells = [unit_cell_array(glmap.grid, a.unit_id) for a in anchors]
    found = []
    for u in heads:
        cells = unit_cell_array(glmap.grid, u.unit_id)
        if len(cells) == 0:
            continue
        centres = (cells + 0.5) * s
        # Cell centre to the anchor's cells, less half a cell: footprint to footprint.
        gaps = [distances_to_cells(a, centres, s).min() - s / 2 for a in anchor_cells if len(a)]
        if gaps and min(gaps) <= reach:
            found.append((u, cells))
    if not found:
        return None
    u, cells = min(
        found, key=lambda f: (f[0].unit_id != prefer, -score[f[0].unit_id], f[0].unit_id)
    )
    core = unit_core_cells(glmap, u.unit_id, config.footprint_core)
    return GoalMatch(u.unit_id, score[u.unit_id], u.observations, core)


class TextVectors:
    """Text embeddings kept over an episode: the same objects are seen frame after frame.

    Args:
        embedder: the map's text embedder phi.
    """

    def __init__(self, embedder: Embedder) -> None:
        self.embedder = embedder
        self.vectors: dict[str, np.ndarray] = {}

    def units(self, texts: list[str]) -> list[UnitText]:
        """`texts` as instance `UnitText`s with their embeddings (new ones embedded at once)."""
        todo = [t for t in dict.fromkeys(texts) if t not in self.vectors]
        if todo:
            for t, v in zip(todo, np.asarray(self.embedder.embed(todo)), strict=True):
                self.vectors[t] = v
        return [UnitText(-1, "instance", t, self.vectors[t]) for t in texts]


def frame_score(
    glmap: GLMap,
    goal: str,
    scorer: Scorer,
    semantics: FrameSemantics | None,
    texts: TextVectors | None = None,
) -> float:
    """What the current frame shows, scored against the goal: the best of its objects/groups
    (the egocentric baseline's per-frame score).

    Args:
        semantics: the frame's semantics; None: the instances the map's latest frame observed.
        texts: embeddings kept over the episode (None: the scorer embeds the texts).
    """
    if semantics is not None:
        words = [o.description or o.label for o in semantics.objects]
        words += [g.description for g in semantics.groups]
        words = [t for t in words if t.strip()]
        units = (
            texts.units(words)
            if texts is not None
            else [UnitText(-1, "instance", t) for t in words]
        )
    else:
        last = len(glmap.trajectory) - 1
        units = [
            u
            for u in map_units(glmap, "instances")
            if glmap.instances[u.unit_id].last_frame == last
        ]
    if not units:
        return 0.0
    return float(np.max(scorer.score(goal, units)))


# Structure this high above the floor is a room's wall, not furniture a detector missed
# (whose pixels join the structure too): above nearly all furniture, below door lintels.
ROOM_WALL_BAND = (1.55, 1.95)


def walls_of(glmap: GLMap, occ: DenseOccupancy) -> np.ndarray | None:
    """[H, W] int8 over `occ`: `nav.footprint.WALL` on structure obstacle cells
    (`nav.grid.structure_walls` in the obstacle band), `ROOM_WALL` where structure also
    stands in `ROOM_WALL_BAND`, else 0. None: the map keeps no structure, so every obstacle
    cell counts as a wall. The counts behind them are kept with the layer
    (`nav.wall_counts`)."""
    if len(glmap.structure) == 0 or glmap.floor_z is None:
        return None
    bands = [glmap.config.obstacle_band, ROOM_WALL_BAND]
    walls, room_walls = structure_walls_kept(glmap.structure, glmap.floor_z, bands, occ)
    levels = walls.astype(np.int8)
    levels[room_walls] = ROOM_WALL
    return levels
