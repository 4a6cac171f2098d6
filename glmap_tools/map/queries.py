"""Queries over a GLMap: by text (instances, regions), by position, by id."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.gaussians.types import GaussianSet
from glmap_tools.map.report import UnitInfo
from glmap_tools.map.units import InstanceUnit, RegionUnit

if TYPE_CHECKING:
    from glmap_tools.map.glmap import GLMap

MAX_K = 1000


def region_gaussians(glmap: GLMap, region: RegionUnit) -> GaussianSet:
    """The union of a region's instance Gaussians."""
    return GaussianSet.concat([glmap.instances[i].gaussians for i in region.instance_ids])


def details(glmap: GLMap, unit: InstanceUnit | RegionUnit) -> UnitInfo:
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


def find(glmap: GLMap, kind: str, text: str, k: int) -> list[UnitInfo]:
    """Top-k units of `kind` by cosine between `text` and their embedding."""
    if not isinstance(text, str) or not text.strip():
        raise InvalidInputError("query text is empty; describe what to find, e.g. 'a red chair'.")
    if not (1 <= int(k) <= MAX_K):
        raise InvalidInputError(f"k={k!r} must be in 1..{MAX_K}.")
    ids, matrix = glmap.instance_matrix() if kind == "instance" else glmap.region_matrix()
    if len(ids) == 0:
        return []
    q = glmap.embedder.embed([text])[0]
    scores = matrix @ q
    k = min(int(k), len(ids))
    top = np.argpartition(-scores, k - 1)[:k]
    top = top[np.lexsort((ids[top], -scores[top]))]
    units = glmap.instances if kind == "instance" else glmap.regions
    out = []
    for i in top:
        info = details(glmap, units[int(ids[i])])
        info.score = round(float(scores[i]), 4)
        out.append(info)
    return out


def units_at(glmap: GLMap, x: float, y: float, radius: float) -> list[UnitInfo]:
    """Units whose grid cells lie within `radius` of (x, y), nearest first."""
    if not all(np.isfinite([x, y, radius])):
        raise InvalidInputError(f"position ({x!r}, {y!r}) and radius {radius!r} must be finite.")
    if not (0 <= radius <= 20):
        raise InvalidInputError(f"radius={radius!r} must be in 0..20 metres.")
    out = []
    for uid, dist in glmap.grid.units_near(x, y, radius):
        info = details(glmap, glmap.unit(uid))
        info.distance = round(dist, 4)
        out.append(info)
    return out
