"""What surrounds a situated pose, from the map alone: units with distance and bearing.

The text half of the SQA interface: every instance near the pose with its label,
description, distance (to its nearest grid cell), bearing (degrees, + = left) and the
direction it lies in (front, left, back, right), plus the regions with their members.
`locate_situation` returns it beside the four rendered views, and the offline answerer
reasons over it, so both see the same evidence.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from glmap_tools.sqa.sight import walls_of

if TYPE_CHECKING:
    from glmap_tools.map.glmap import GLMap

AROUND = 4.0  # m: units farther away are not "around me"
# Direction sectors (bearing ranges in degrees, + = left), as the views are labelled.
SECTORS = (("front", -45.0, 45.0), ("left", 45.0, 135.0), ("right", -135.0, -45.0))


def direction_of(bearing_deg: float) -> str:
    """front / left / right / back for a bearing in degrees (+ = left)."""
    for name, lo, hi in SECTORS:
        if lo <= bearing_deg < hi:
            return name
    return "back"


@dataclass(frozen=True)
class Nearby:
    """One instance as seen from the pose."""

    unit_id: int
    label: str
    text: str
    distance: float  # m, to the unit's nearest grid cell
    bearing: float  # degrees, + = left, to the unit's centroid
    direction: str
    z_min: float
    z_max: float
    footprint: tuple[float, float, float, float]  # x0, y0, x1, y1 (m)
    # length, width, height (m) of its Gaussians' means along their principal axes
    size: tuple[float, float, float] | None = None

    def as_row(self) -> list[Any]:
        return [
            self.unit_id,
            self.label,
            round(self.distance, 2),
            round(self.bearing),
            self.direction,
        ]


@dataclass(frozen=True)
class Surroundings:
    """The map around (x, y, heading)."""

    x: float
    y: float
    heading: float
    nearby: tuple[Nearby, ...]  # nearest first
    regions: tuple[tuple[int, str, tuple[int, ...]], ...]  # (id, text, member ids)
    labels: dict[int, str]  # every instance's label, for region member counts
    walled: frozenset[int] = frozenset()  # nearby units a wall hides (another room)

    def as_dict(self, max_units: int = 20) -> dict[str, Any]:
        """Compact JSON: [id, label, metres, bearing, direction] rows, regions and, when
        any, the ids of the rows a wall hides ("behind_walls": another room)."""
        rows = self.nearby[:max_units]
        out: dict[str, Any] = {
            "pose": [round(self.x, 2), round(self.y, 2), round(math.degrees(self.heading))],
            "nearby": [n.as_row() for n in rows],
            "regions": [[rid, text[:100], list(members)] for rid, text, members in self.regions],
        }
        hidden = sorted(n.unit_id for n in rows if n.unit_id in self.walled)
        if hidden:
            out["behind_walls"] = hidden
        return out


def gaussian_size(means: np.ndarray) -> tuple[float, float, float]:
    """(length, width, height) in metres of a unit from its Gaussians' means [N, 3]: the
    spread along the two principal horizontal axes (longer first) and in z."""
    xy = means[:, :2] - means[:, :2].mean(axis=0)
    if len(xy) < 2:
        return 0.0, 0.0, 0.0
    _, vecs = np.linalg.eigh(np.cov(xy.T))
    proj = xy @ vecs
    ext = np.sort(proj.max(axis=0) - proj.min(axis=0))[::-1]
    return float(ext[0]), float(ext[1]), float(np.ptp(means[:, 2]))


def _all_units(glmap: GLMap, x: float, y: float) -> list[tuple[int, float]]:
    """(id, distance to its nearest cell) of every instance."""
    s = glmap.grid.cell_size
    out = []
    for uid in glmap.instances:
        cells = np.array(sorted(glmap.grid.cells_of_unit(uid)), dtype=np.float64)
        if len(cells) == 0:
            continue
        gap = np.maximum(np.maximum(cells * s - (x, y), (x, y) - (cells + 1) * s), 0.0)
        out.append((uid, float(np.hypot(gap[:, 0], gap[:, 1]).min())))
    return out


def surroundings(
    glmap: GLMap,
    x: float,
    y: float,
    heading: float,
    radius: float | None = AROUND,
    walls: bool = True,
) -> Surroundings:
    """The instances within `radius` of (x, y) (None: all) with bearings from `heading`;
    with `walls`, also which of them a wall hides (`glmap_tools.sqa.sight.Walls`)."""
    s = glmap.grid.cell_size
    rows = []
    sight: dict[int, np.ndarray] = {}  # unit id -> [2, 2]: its centre and nearest cell centre
    near = glmap.grid.units_near(x, y, radius) if radius is not None else _all_units(glmap, x, y)
    for uid, dist in near:
        unit = glmap.instances.get(uid)
        if unit is None:
            continue
        means = unit.gaussians.means
        c = means.mean(axis=0)
        b = math.degrees(math.remainder(math.atan2(c[1] - y, c[0] - x) - heading, math.tau))
        cells = np.array(sorted(glmap.grid.cells_of_unit(uid)), dtype=np.float64)
        lo = cells.min(axis=0) * s if len(cells) else c[:2]
        hi = (cells.max(axis=0) + 1) * s if len(cells) else c[:2]
        centres = (cells + 0.5) * s if len(cells) else c[None, :2]
        nearest = centres[int(np.argmin(np.hypot(centres[:, 0] - x, centres[:, 1] - y)))]
        sight[uid] = np.array([c[:2], nearest], dtype=np.float64)
        rows.append(
            Nearby(
                uid,
                unit.label or unit.text.split(",")[0],
                unit.text,
                float(dist),
                b,
                direction_of(b),
                float(means[:, 2].min()),
                float(means[:, 2].max()),
                (float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])),
                gaussian_size(means),
            )
        )
    rows.sort(key=lambda n: (n.distance, n.unit_id))
    regions = tuple(
        (r.id, r.text, tuple(r.instance_ids))
        for r in sorted(glmap.regions.values(), key=lambda r: r.id)
    )
    labels = {uid: u.label for uid, u in glmap.instances.items()}
    walled: frozenset[int] = frozenset()
    if walls and rows:
        # Hidden: a wall lies before both the unit's centre and its nearest cell.
        ids = [n.unit_id for n in rows]
        ends = np.concatenate([sight[i] for i in ids])
        hidden = walls_of(glmap).blocked((x, y), ends).reshape(len(ids), 2).all(axis=1)
        walled = frozenset(ids[k] for k in np.flatnonzero(hidden))
    return Surroundings(x, y, heading, tuple(rows), regions, labels, walled)
