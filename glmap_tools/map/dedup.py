"""Unit fusion: one instance unit per object and one region unit per region.

The paper matches each observation to at most one existing unit. An object first seen in
parts that do not overlap becomes several units, which later views grow into each other;
the matches never join them. After a frame's matches are planned, fusion joins them:

- instances: the same label (case and spacing ignored), similar text (cosine >= tau_s) and
  Gaussians that touch: CONTACT_GAUSSIANS means of one within TOUCH_VOXELS voxels of the
  other's;
- regions: similar text (cosine >= tau_s) and a shared member instance (the paper's region
  match, applied between units), or the same member set.

Units the frame observed as distinct objects (or groups) are never joined: perception told
them apart. The oldest (smallest) id survives; the others' ids are not reused.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence

import numpy as np
from scipy.spatial import cKDTree

from glmap_tools.gaussians.estimator import EstimatorConfig
from glmap_tools.gaussians.merge import remerge
from glmap_tools.gaussians.types import GaussianSet
from glmap_tools.language.text_merger import split_buffer
from glmap_tools.map.units import InstanceUnit, RegionUnit

# Means this many voxels apart touch. Across a mask edge that cuts one surface the nearest
# means of the two parts lie 1.5-3 voxels apart (edge voxels with too few points emit no
# Gaussian); two objects 9 cm apart (4.5 voxels) do not touch. Gaussian supports are no
# better a measure: remerged Gaussians on flat parts reach 2 sigma = 5-7 cm.
TOUCH_VOXELS = 3.5
# Means of the smaller unit that must touch the other unit (all of them for a smaller
# unit): one stray Gaussian does not join two objects.
CONTACT_GAUSSIANS = 3

TextMerge = Callable[[str, str], str]  # (buffer, description) -> buffer


def normalised(v: np.ndarray) -> np.ndarray:
    """[D] float32 unit vector along `v` (`v` itself when it is zero)."""
    n = float(np.linalg.norm(v))
    return (v / n).astype(np.float32) if n > 0 else v.astype(np.float32)


def same_label(a: str, b: str) -> bool:
    """Whether two short category labels name the same category (case, spacing ignored)."""
    return " ".join(a.casefold().split()) == " ".join(b.casefold().split())


def gaussians_touch(a: GaussianSet, b: GaussianSet, touch: float) -> bool:
    """Whether CONTACT_GAUSSIANS means of the smaller set lie within `touch` m of the other's."""
    if len(a) == 0 or len(b) == 0:
        return False
    small, big = (a, b) if len(a) <= len(b) else (b, a)
    (smin, smax), (bmin, bmax) = small.bounds(), big.bounds()
    if np.any(smin - touch > bmax) or np.any(bmin - touch > smax):
        return False
    dist, _ = cKDTree(big.means).query(small.means, distance_upper_bound=touch)
    return int(np.isfinite(dist).sum()) >= min(CONTACT_GAUSSIANS, len(small))


class _Components:
    """Union-find over unit ids; a component holds at most one unit the frame observed."""

    def __init__(self, observed: set[int]) -> None:
        self.parent: dict[int, int] = {}
        self.observed = observed

    def find(self, a: int) -> int:
        while self.parent.get(a, a) != a:
            a = self.parent[a]
        return a

    def join(self, a: int, b: int) -> None:
        ra, rb = self.find(a), self.find(b)
        if ra == rb or (ra in self.observed and rb in self.observed):
            return
        keep, gone = min(ra, rb), max(ra, rb)
        self.parent[gone] = keep
        if gone in self.observed:
            self.observed = self.observed | {keep}

    def groups(self, ids: Iterable[int]) -> list[list[int]]:
        by_root: dict[int, list[int]] = {}
        for i in sorted(ids):
            by_root.setdefault(self.find(i), []).append(i)
        return [g for g in by_root.values() if len(g) > 1]


def _joined_text(units: list[InstanceUnit] | list[RegionUnit], merge_text: TextMerge) -> str:
    text = units[0].text
    for unit in units[1:]:
        for part in split_buffer(unit.text):
            text = merge_text(text, part)
    return text


def _fixed_point(
    units: dict[int, InstanceUnit] | dict[int, RegionUnit],
    seeds: set[int],
    joins: Callable[[int, int], bool],
    observed: set[int],
    fuse: Callable[[list[int]], None],
) -> dict[int, int]:
    """Join seeds to the units `joins` accepts, fuse each group, repeat with the survivors."""
    absorbed: dict[int, int] = {}
    while seeds:
        comps = _Components(observed)
        for a in sorted(seeds):
            for b in sorted(units):
                if b != a and comps.find(a) != comps.find(b) and joins(a, b):
                    comps.join(a, b)
        groups = comps.groups(set(units))
        for group in groups:
            fuse(group)
            for gone in group[1:]:
                absorbed[gone] = group[0]
        observed = comps.observed
        seeds = {g[0] for g in groups}
    for gone, keep in absorbed.items():  # a survivor may itself have been absorbed later
        while keep in absorbed:
            keep = absorbed[keep]
        absorbed[gone] = keep
    return absorbed


def fuse_instances(
    units: Mapping[int, InstanceUnit],
    changed: Iterable[int],
    observed: set[int],
    tau: float,
    estimator: EstimatorConfig,
    merge_text: TextMerge,
) -> tuple[dict[int, InstanceUnit], dict[int, int]]:
    """Fuse the instances a frame changed with the instances that are the same object.

    Args:
        units: every instance of the map as the frame leaves it, by id.
        changed: ids of the instances the frame added or updated.
        observed: ids the frame matched an observation to (never fused with each other).
        tau: text-similarity threshold tau_s (cosine of the units' embeddings).
        estimator: config of the remerge of the fused Gaussians.
        merge_text: appends one description to a text buffer (and shortens it).

    Returns:
        (the fused units by surviving id, absorbed id -> surviving id).
    """
    current = dict(units)
    fused: dict[int, InstanceUnit] = {}
    touch = TOUCH_VOXELS * estimator.voxel_size

    def joins(a: int, b: int) -> bool:
        ua, ub = current[a], current[b]
        return (
            same_label(ua.label, ub.label)
            and float(ua.embedding @ ub.embedding) >= tau
            and gaussians_touch(ua.gaussians, ub.gaussians, touch)
        )

    def fuse(group: list[int]) -> None:
        parts = [current.pop(i) for i in group]
        latest = max(parts, key=lambda u: (u.last_frame, -u.id))
        embedding, observations, first, last = _pooled(parts)
        unit = InstanceUnit(
            group[0],
            latest.label,
            _joined_text(parts, merge_text),
            embedding,
            remerge(GaussianSet.concat([u.gaussians for u in parts]), estimator),
            observations,
            first,
            last,
        )
        current[group[0]] = fused[group[0]] = unit
        for gone in group[1:]:
            fused.pop(gone, None)

    absorbed = _fixed_point(current, set(changed), joins, observed, fuse)
    return fused, absorbed


def _pooled(
    parts: Sequence[InstanceUnit] | Sequence[RegionUnit],
) -> tuple[np.ndarray, int, int, int]:
    """What fused units share: (observation-weighted embedding, observations, first frame,
    last frame)."""
    embedding = normalised(np.sum([u.embedding * u.observations for u in parts], axis=0))
    return (
        embedding,
        sum(u.observations for u in parts),
        min(u.first_frame for u in parts),
        max(u.last_frame for u in parts),
    )


def with_members_renamed(
    regions: Mapping[int, RegionUnit], absorbed: Mapping[int, int]
) -> dict[int, RegionUnit]:
    """The regions holding an absorbed instance, with its surviving id in its place."""
    renamed = {}
    for rid, region in regions.items():
        if any(i in absorbed for i in region.instance_ids):
            members = tuple(sorted({absorbed.get(i, i) for i in region.instance_ids}))
            renamed[rid] = RegionUnit(
                rid,
                region.text,
                region.embedding,
                members,
                region.observations,
                region.first_frame,
                region.last_frame,
            )
    return renamed


def fuse_regions(
    regions: Mapping[int, RegionUnit],
    changed: Iterable[int],
    observed: set[int],
    tau: float,
    merge_text: TextMerge,
) -> tuple[dict[int, RegionUnit], dict[int, int]]:
    """Fuse the regions a frame changed with the regions that are the same region.

    Args:
        regions: every region of the map as the frame leaves it, by id.
        changed: ids of the regions the frame added, updated or renamed members of.
        observed: ids the frame matched a group to (never fused with each other).
        tau: text-similarity threshold tau_s.
        merge_text: appends one description to a text buffer (and shortens it).

    Returns:
        (the fused regions by surviving id, absorbed id -> surviving id).
    """
    current = dict(regions)
    fused: dict[int, RegionUnit] = {}

    def joins(a: int, b: int) -> bool:
        ra, rb = current[a], current[b]
        if ra.instance_ids == rb.instance_ids:
            return True
        shared = set(ra.instance_ids) & set(rb.instance_ids)
        return bool(shared) and float(ra.embedding @ rb.embedding) >= tau

    def fuse(group: list[int]) -> None:
        parts = [current.pop(i) for i in group]
        embedding, observations, first, last = _pooled(parts)
        region = RegionUnit(
            group[0],
            _joined_text(parts, merge_text),
            embedding,
            tuple(sorted({i for r in parts for i in r.instance_ids})),
            observations,
            first,
            last,
        )
        current[group[0]] = fused[group[0]] = region
        for gone in group[1:]:
            fused.pop(gone, None)

    absorbed = _fixed_point(current, set(changed), joins, observed, fuse)
    return fused, absorbed
