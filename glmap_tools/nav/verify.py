"""Goal verification over fused views: a goal candidate the map saw as something else more
often is outvoted (the glmap policies; the baselines keep VLFM's rule, `min_observations`);
a unit the agent looked at again without seeing it (`missed_in_view`) pulls the value map
by the share of looks that saw it (`seen_share`): a false positive on a wall, seen once,
stops drawing the agent once it has looked there again.

A detector that takes a TV for a picture now and then leaves two units at one place: "a
picture" seen twice and "a tv" seen ten times. The map remembers both; the candidate
counts only if its views are at least as many as those of the other-labelled instances
at the same place (`same_place`: the other's box covers `COVER` of the candidate's, and the
candidate's covers `COVER_BACK` of the other's: a partial view of a cabinet taken for a TV
stand still votes with the cabinet, while a pillow on a bed, inside the bed's box but far
smaller, is not outvoted by the bed) and the other's floor cells hold `COVER` of the
candidate's core cells (a box is not a place: a kitchen-cabinet unit spanning the cabinets
on both sides of a sink has a box around the sink but none of its cells; house-bench
InstNav s07-002, where the sink was outvoted for 200 steps).
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from glmap_tools.geometry.frame import RGBDFrame
    from glmap_tools.map.glmap import GLMap

from glmap_tools.nav.value import unit_cell_array, unit_core_cells

COVER = 0.5  # share of the candidate's box inside the other's
COVER_BACK = 0.25  # share of the other's box inside the candidate's (a partial view is smaller)
CORE = 0.8  # share of a unit's points its core cells hold (`NavConfig.footprint_core`)


def covered_share(
    lo: np.ndarray, hi: np.ndarray, other_lo: np.ndarray, other_hi: np.ndarray
) -> float:
    """Share of box (lo, hi) inside box (other_lo, other_hi); boxes [3] min / max in metres,
    each side grown to at least 5 cm (a picture's box is flat)."""
    return float(_covered_shares(*_grown(lo, hi), *_grown(other_lo, other_hi)))


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
    return unit_id in outvoted_units(glmap, [unit_id])


def outvoted_units(glmap: GLMap, unit_ids: Iterable[int]) -> set[int]:
    """The instances of `unit_ids` that are outvoted (`outvoted`). Every instance's box is
    read once and the place tests run against all instances at a time."""
    ids, labels, observations, lo, hi = _instance_boxes(glmap)
    row = {uid: k for k, uid in enumerate(ids.tolist())}
    out: set[int] = set()
    for unit_id in unit_ids:
        k = row.get(unit_id)
        if k is None:  # not an instance, or one without Gaussians
            continue
        places = np.flatnonzero(
            (labels != labels[k])
            & (_covered_shares(lo[k], hi[k], lo, hi) >= COVER)
            & (_covered_shares(lo, hi, lo[k], hi[k]) >= COVER_BACK)
        )
        if len(places) == 0:
            continue
        core = {(int(i), int(j)) for i, j in unit_core_cells(glmap, unit_id, CORE)}
        votes = 0
        for p in places.tolist():
            theirs = {(int(i), int(j)) for i, j in unit_cell_array(glmap.grid, int(ids[p]))}
            if core and len(core & theirs) >= COVER * len(core):
                votes += int(observations[p])
        if votes > observations[k]:
            out.add(unit_id)
    return out


def _instance_boxes(
    glmap: GLMap,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Instances with Gaussians: ids [N], labels [N] (object), observations [N] and their
    boxes grown as `covered_share` grows them ([N, 3] min, [N, 3] max)."""
    units = [(uid, u) for uid, u in glmap.instances.items() if len(u.gaussians)]
    lo, hi = np.zeros((len(units), 3)), np.zeros((len(units), 3))
    for k, (_, u) in enumerate(units):
        lo[k], hi[k] = u.bounds()
    labels = np.empty(len(units), dtype=object)
    labels[:] = [u.label for _, u in units]
    return (
        np.array([uid for uid, _ in units], dtype=np.int64),
        labels,
        np.array([u.observations for _, u in units], dtype=np.int64),
        *_grown(lo, hi),
    )


def _covered_shares(
    lo: np.ndarray, hi: np.ndarray, other_lo: np.ndarray, other_hi: np.ndarray
) -> np.ndarray:
    """`covered_share` of boxes already grown, broadcast over rows ([3] or [N, 3] each)."""
    inter = np.clip(np.minimum(hi, other_hi) - np.maximum(lo, other_lo), 0.0, None)
    return np.prod(inter, axis=-1) / np.prod(hi - lo, axis=-1)


MISS_RANGE_M = 3.0  # a unit's centre nearer than this, in view and not hidden, should be seen
MISS_MARGIN = 0.1  # share of the image width / height kept clear of the borders
HIDDEN_M = 0.3  # something this much nearer than the centre hides it


def missed_in_view(glmap: GLMap, frame: RGBDFrame) -> list[int]:
    """Instances the latest frame looked at without observing them.

    A unit counts when its centre lies in the image (away from the borders), in front of
    the camera within `MISS_RANGE_M`, and the depth there does not put something more than
    `HIDDEN_M` in front of it; the latest frame is `frame`, already integrated.
    """
    last = len(glmap.trajectory) - 1
    camera_from_world = np.linalg.inv(frame.pose.matrix)
    k = frame.intrinsics
    depth = np.asarray(frame.depth)
    h, w = depth.shape
    out = []
    for uid, unit in glmap.instances.items():
        if unit.last_frame == last or len(unit.gaussians) == 0:
            continue
        c = camera_from_world[:3, :3] @ unit.centroid + camera_from_world[:3, 3]
        z = float(c[2])
        if not 0.3 < z < MISS_RANGE_M:
            continue
        u, v = k.fx * c[0] / z + k.cx, k.fy * c[1] / z + k.cy
        if not (MISS_MARGIN * w <= u < (1 - MISS_MARGIN) * w):
            continue
        if not (MISS_MARGIN * h <= v < (1 - MISS_MARGIN) * h):
            continue
        d = float(depth[int(v), int(u)])
        if d > 0 and d >= z - HIDDEN_M:
            out.append(uid)
    return out


def note_missed(missed: dict[int, int], glmap: GLMap, frame: RGBDFrame) -> None:
    """Count one more miss in `missed` (instance id -> frames) for each unit the latest
    frame, `frame`, looked at without observing (`missed_in_view`)."""
    for uid in missed_in_view(glmap, frame):
        missed[uid] = missed.get(uid, 0) + 1


def seen_share(observations: int, missed: int) -> float:
    """The share of the looks at a unit that saw it: 1 for a unit never looked past."""
    return observations / max(observations + missed, 1)
