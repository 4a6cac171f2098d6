"""Goal verification over fused views: a goal candidate the map saw as something else more
often is outvoted (the glmap policies; the baselines keep VLFM's rule, `min_observations`).

A detector that takes a TV for a picture now and then leaves two units at one place: "a
picture" seen twice and "a tv" seen ten times. The map remembers both; the candidate
counts only if its views are at least as many as those of the other-labelled instances
at the same place (`same_place`: the other's box covers `COVER` of the candidate's, and the
candidate's covers `COVER_BACK` of the other's: a partial view of a cabinet taken for a TV
stand still votes with the cabinet, while a pillow on a bed, inside the bed's box but far
smaller, is not outvoted by the bed).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from glmap_tools.map.glmap import GLMap

COVER = 0.5  # share of the candidate's box inside the other's
COVER_BACK = 0.25  # share of the other's box inside the candidate's (a partial view is smaller)


def covered_share(
    lo: np.ndarray, hi: np.ndarray, other_lo: np.ndarray, other_hi: np.ndarray
) -> float:
    """Share of box (lo, hi) inside box (other_lo, other_hi); boxes [3] min / max in metres,
    each side grown to at least 5 cm (a picture's box is flat)."""
    lo, hi = _grown(lo, hi)
    other_lo, other_hi = _grown(other_lo, other_hi)
    inter = np.clip(np.minimum(hi, other_hi) - np.maximum(lo, other_lo), 0.0, None)
    return float(np.prod(inter) / np.prod(hi - lo))


def _grown(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    mid = (lo + hi) / 2
    return np.minimum(lo, mid - 0.025), np.maximum(hi, mid + 0.025)


def same_place(lo: np.ndarray, hi: np.ndarray, other_lo: np.ndarray, other_hi: np.ndarray) -> bool:
    """Whether box `other` covers `COVER` of box (lo, hi) and (lo, hi) covers `COVER_BACK`
    of `other` (boxes [3] min / max, metres)."""
    return (
        covered_share(lo, hi, other_lo, other_hi) >= COVER
        and covered_share(other_lo, other_hi, lo, hi) >= COVER_BACK
    )


def outvoted(glmap: GLMap, unit_id: int) -> bool:
    """Whether instances of other labels at the place of instance `unit_id` were observed
    more often than it."""
    unit = glmap.instances[unit_id]
    if len(unit.gaussians) == 0:
        return False
    lo, hi = unit.bounds()
    votes = 0
    for other_id, other in glmap.instances.items():
        if other_id == unit_id or other.label == unit.label or len(other.gaussians) == 0:
            continue
        other_lo, other_hi = other.bounds()
        if same_place(lo, hi, other_lo, other_hi):
            votes += other.observations
    return votes > unit.observations
