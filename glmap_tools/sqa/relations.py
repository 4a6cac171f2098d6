"""Relation words in a situation text: "the navy kitchen cabinet next to the white
refrigerator", "the table in the kitchen".

A sentence embedding of the whole phrase cannot tell two equally named cabinets apart by
their neighbours. So the phrase is split into the object's own words, which score the
instances, and its relations ("next to the X", "beside/near the X", "on the X", "in the
<room>"), which then decide among the equally good candidates: per relation, the best
score of what it names among the instances within NEAR of the candidate ("on" counts as
next to: a support is within reach), or of the room among the regions holding it.
"""

from __future__ import annotations

import re
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from glmap_tools.map.glmap import GLMap
    from glmap_tools.nav.scorers import Scorer, UnitText

# Imports inside functions stay there: scipy load on first use.

NEAR = 1.0  # m between two units' cells for "next to" (the generator's and InstNav's)

_RELATION = re.compile(r"\s+(next to|beside|near|on|in)\s+the\s+", re.IGNORECASE)


def relation_phrases(phrase: str) -> tuple[str, list[tuple[str, str]]]:
    """(the object phrase, [(relation, what it relates to)]) of a phrase.

    >>> relation_phrases("the white cabinet next to the fridge in the kitchen")
    ('the white cabinet', [('next to', 'fridge'), ('in', 'kitchen')])
    """
    parts = _RELATION.split(phrase.strip(" .,;"))
    rels = [(r.lower(), t.strip()) for r, t in zip(parts[1::2], parts[2::2], strict=True)]
    return parts[0].strip(), [(r, t) for r, t in rels if t]


def relation_fit(
    glmap: GLMap,
    scorer: Scorer,
    instances: list[UnitText],
    regions: list[UnitText],
    relations: list[tuple[str, str]],
    candidates: list[int],
) -> dict[int, float]:
    """How well each candidate fits the relations, in [0, 1].

    Args:
        glmap: the map (its index grid places the instances, its regions hold them).
        scorer: f(u, text) in [0, 1], as for the object's own words.
        instances, regions: the map's units as the scorer sees them.
        relations: (relation, words) pairs from `relation_phrases`.
        candidates: indices into `instances`.

    Returns:
        Candidate index -> the mean over the relations of the best score of what each names
        among the instances within NEAR of the candidate ("next to", "beside", "near",
        "on"), or among the regions holding it ("in").
    """
    from scipy.spatial import cKDTree

    s = glmap.grid.cell_size
    cells = {
        u.unit_id: np.array(sorted(glmap.grid.cells_of_unit(u.unit_id)), dtype=np.float64)
        for u in instances
    }
    fits: dict[int, list[float]] = {i: [] for i in candidates}
    for rel, words in relations:
        if rel == "in":
            p = scorer.score(f"the {words}", regions) if regions else np.zeros(0)
            for i in candidates:
                uid = instances[i].unit_id
                held = [
                    float(p[k])
                    for k, r in enumerate(regions)
                    if uid in getattr(glmap.regions[r.unit_id], "instance_ids", ())
                ]
                fits[i].append(max(held, default=0.0))
            continue
        p = scorer.score(f"the {words}", instances)
        for i in candidates:
            mine = cells[instances[i].unit_id]
            best = 0.0
            if len(mine):
                tree = cKDTree((mine + 0.5) * s)
                for k, u in enumerate(instances):
                    other = cells[u.unit_id]
                    if k == i or not len(other) or p[k] <= best:
                        continue
                    gap, _ = tree.query((other + 0.5) * s, k=1)
                    if float(gap.min()) <= NEAR + s:
                        best = float(p[k])
            fits[i].append(best)
    return {i: float(np.mean(f)) if f else 0.0 for i, f in fits.items()}


def prefer_related(
    glmap: GLMap,
    scorer: Scorer,
    instances: list[UnitText],
    regions: list[UnitText],
    scores: np.ndarray,
    relations: list[tuple[str, str]],
    tie: float,
    notes: list[str],
) -> np.ndarray:
    """`scores` [N] of `instances` with the candidates within `tie` of the best that fit the
    relations worse than another candidate by more than `tie` moved out of the tie (to the
    best minus 2 `tie`); unchanged without relations or with a single candidate. A note
    on what decided goes to `notes`."""
    if not relations or not len(scores):
        return scores
    cands = [i for i, p in enumerate(scores) if p >= float(scores.max()) - tie]
    if len(cands) < 2:
        return scores
    fit = relation_fit(glmap, scorer, instances, regions, relations, cands)
    top = max(fit.values())
    out = scores.copy()
    for i in cands:
        if fit[i] < top - tie:
            out[i] = float(scores.max()) - 2 * tie
    notes.append(
        "same-named candidates told apart by "
        + ", ".join(f"'{r} the {w}'" for r, w in relations)
        + f" (fits {', '.join(f'{fit[i]:.2f}' for i in cands)})"
    )
    return out
