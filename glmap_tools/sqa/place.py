"""Where one stands at an anchor: free cells, the stand point by the anchor nearest what is
faced (the fallback of `sqa.stand`), and the anchor/facing pair among equally good ones."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from glmap_tools.map.occupancy import FREE
from glmap_tools.sqa.sight import SEEN_MIN, SightCheck

if TYPE_CHECKING:
    from glmap_tools.map.glmap import GLMap
    from glmap_tools.nav.scorers import UnitText

# Imports inside functions stay there: language.embed, scipy, numba load on first use.

STAND_REACH = 0.6  # m from the anchor's cells: where one stands at it ...
STAND_RADIUS = 1.2  # ... or, when nothing is free that close, at most this far


def free_cells(glmap: GLMap, exclude: set[tuple[int, int]]) -> tuple[np.ndarray, float]:
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


def stand_point_near(
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
    free, s = free_cells(glmap, cells)
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


def centroid(glmap: GLMap, unit_id: int) -> tuple[float, float]:
    c = glmap.instances[unit_id].gaussians.means.mean(axis=0)
    return float(c[0]), float(c[1])


def closest_pair(
    glmap: GLMap,
    instances: list[UnitText],
    p_anchor: np.ndarray,
    p_face: np.ndarray | None,
    sight: bool,
    tie: float,
    min_score: float,
) -> tuple[int, int | None]:
    """(anchor id, facing id): the best-scored ones, ties (within `tie`) broken by distance
    among the pairs whose facing object is seen from the anchor's stand band; no facing id
    when the best facing score is below `min_score`."""
    ids = [u.unit_id for u in instances]
    cand_a = [i for i, p in enumerate(p_anchor) if p >= float(p_anchor.max()) - tie]
    if p_face is None or float(p_face.max()) < min_score:
        return ids[cand_a[0]], None
    cand_f = [j for j, p in enumerate(p_face) if p >= float(p_face.max()) - tie]
    pairs = [(i, j) for i in cand_a for j in cand_f if i != j]
    if sight and len(pairs) > 1:
        # One sees what one faces: drop the pairs split by a wall, unless all are.
        check = SightCheck(glmap)
        shares = [check.seen_share(ids[i], ids[j]) for i, j in pairs]
        seen = [p for p, sh in zip(pairs, shares, strict=True) if sh is None or sh >= SEEN_MIN]
        pairs = seen or pairs
    best: tuple[float, int, int] | None = None
    for i, j in pairs:
        a, f = centroid(glmap, ids[i]), centroid(glmap, ids[j])
        d = math.hypot(a[0] - f[0], a[1] - f[1])
        if best is None or d < best[0]:
            best = (d, i, j)
    if best is None:
        return ids[cand_a[0]], ids[cand_f[0]]
    return ids[best[1]], ids[best[2]]
