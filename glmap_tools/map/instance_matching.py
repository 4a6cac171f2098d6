"""Instances of one frame (paper §3.1): mask -> points -> Gaussians, matched to map instances.

An observation joins the best map instance whose text is similar (cosine > tau_s) and
whose Gaussians are geometrically consistent with it; otherwise it becomes a new instance.
Then fusion (`map/dedup.py`) joins the frame's instances with map instances of the same
object.
"""

from __future__ import annotations

from collections import ChainMap
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from glmap_tools.gaussians.estimator import EstimatorConfig, GaussianEstimator
from glmap_tools.gaussians.merge import any_mergeable, remerge
from glmap_tools.gaussians.types import GaussianSet
from glmap_tools.map.dedup import fuse_instances, normalised
from glmap_tools.map.frame_points import FramePoints
from glmap_tools.map.mask_edges import depth_consistent
from glmap_tools.map.matching import Matching, report_fused, text_candidates
from glmap_tools.map.report import SkippedObservation, UnitChange, UpdateReport
from glmap_tools.map.units import InstanceUnit
from glmap_tools.perception.semantics import FrameSemantics

# Geometric consistency, beyond the paper's "some Gaussian pair is mergeable": also when at
# least OVERLAP_FRACTION of the smaller set's means lie within OVERLAP_VOXELS voxels of the
# other set's means (re-observations under other exposure or from farther away).
OVERLAP_FRACTION = 0.3
OVERLAP_VOXELS = 2.5


@dataclass(frozen=True)
class ObservedInstance:
    """One object of the frame with its fitted Gaussians."""

    local_id: int
    label: str
    text: str
    gaussians: GaussianSet


def _boxes_touch(a: GaussianSet, b: GaussianSet, margin: float) -> bool:
    amin, amax = a.bounds()
    bmin, bmax = b.bounds()
    return bool(np.all(amin - margin <= bmax) and np.all(bmin - margin <= amax))


def geometrically_consistent(
    unit: GaussianSet, observed: GaussianSet, config: EstimatorConfig
) -> bool:
    """Whether an observed instance's Gaussians agree with a map instance's (paper §3.1).

    True when any Gaussian pair is mergeable (the paper's criterion), or when the two sets
    overlap: OVERLAP_FRACTION of the smaller set lies within OVERLAP_VOXELS voxels of the
    larger. The second clause catches re-observations whose colours (exposure, shading)
    or covariances (viewing distance) differ too much for a mergeable pair; measured on
    generated apartments it lifts instance precision from 0.83-0.93 to 0.95-0.97 with
    recall unchanged at 1.0 (`glmap sim map-eval`, seeds 0-3).
    """
    if any_mergeable(unit, observed, config):
        return True
    small, big = (observed, unit) if len(observed) <= len(unit) else (unit, observed)
    radius = OVERLAP_VOXELS * config.voxel_size
    dist, _ = cKDTree(big.means).query(small.means, distance_upper_bound=radius)
    return bool(np.mean(np.isfinite(dist)) >= OVERLAP_FRACTION)


def observe_instances(
    semantics: FrameSemantics,
    points: FramePoints,
    estimator: GaussianEstimator,
    depth: np.ndarray | None = None,
) -> tuple[list[ObservedInstance], list[SkippedObservation]]:
    """Fit Gaussians to each object mask's points; objects that give none are skipped.

    With the frame's [H, W] `depth`, a mask's pixels across a depth edge from the rest of
    it (a mask that bled past the outline) are left out (`mask_edges.depth_consistent`).
    """
    observed: list[ObservedInstance] = []
    skipped: list[SkippedObservation] = []
    for obj in semantics.objects:
        mask = obj.mask if depth is None else depth_consistent(obj.mask, depth)
        cloud = points.cloud(mask)
        gaussians = estimator.fit(cloud.points, cloud.colors)
        if len(gaussians) == 0:
            skipped.append(
                SkippedObservation(
                    local_id=obj.local_id,
                    kind="instance",
                    reason=f"{len(cloud)} valid depth points in the mask gave no Gaussian",
                )
            )
            continue
        observed.append(ObservedInstance(obj.local_id, obj.label, obj.text, gaussians))
    return observed, skipped


def _matched_unit(
    obs: ObservedInstance,
    candidates: list[tuple[float, int]],
    units: Mapping[int, InstanceUnit],
    config: EstimatorConfig,
) -> tuple[float, InstanceUnit] | None:
    """The first text candidate whose Gaussians are consistent with the observation's."""
    for sim, uid in candidates:
        unit = units[uid]
        if _boxes_touch(unit.gaussians, obs.gaussians, config.voxel_size) and (
            geometrically_consistent(unit.gaussians, obs.gaussians, config)
        ):
            return sim, unit
    return None


def match_instances(
    observed: list[ObservedInstance],
    embeddings: np.ndarray,
    instances: dict[int, InstanceUnit],
    matrix: tuple[np.ndarray, np.ndarray],
    estimator: EstimatorConfig,
    ctx: Matching,
    next_id: int,
    report: UpdateReport,
) -> tuple[dict[int, InstanceUnit], int]:
    """Match each observation to a map instance or make it a new one.

    Args:
        observed: the frame's objects with Gaussians.
        embeddings: [len(observed), D] their descriptions' embeddings.
        instances: the map's instances before the frame.
        matrix: (ids [N], embeddings [N, D]) of those instances.
        estimator: the Gaussian estimator's settings (mergeability).
        ctx: the frame's matching settings.
        next_id: the first free unit id.
        report: gains the added and merged changes and the local -> global ids.

    Returns:
        (the new or updated instances by id, the next free id).
    """
    ids, mat = matrix
    frame = ctx.frame_index
    staged: dict[int, InstanceUnit] = {}
    known = ChainMap(staged, instances)  # this frame's version first
    for obs, e in zip(observed, embeddings, strict=True):
        candidates = text_candidates(ids, mat, e, ctx.tau_s)
        target = _matched_unit(obs, candidates, known, estimator)
        if target is None:
            uid, next_id = next_id, next_id + 1
            staged[uid] = InstanceUnit(
                uid, obs.label, obs.text, normalised(e), obs.gaussians, 1, frame, frame
            )
            report.instances_added.append(
                UnitChange(local_id=obs.local_id, global_id=uid, text=obs.text)
            )
        else:
            sim, unit = target
            uid, n = unit.id, unit.observations
            seen_now = unit.last_frame == frame and uid in staged
            staged[uid] = InstanceUnit(
                uid,
                obs.label or unit.label,
                ctx.merge_text(unit.text, obs.text),
                normalised(unit.embedding * n + e),
                remerge(GaussianSet.concat([unit.gaussians, obs.gaussians]), estimator),
                n if seen_now else n + 1,
                unit.first_frame,
                frame,
            )
            report.instances_merged.append(
                UnitChange(local_id=obs.local_id, global_id=uid, text=obs.text, similarity=sim)
            )
        report.local_to_global[obs.local_id] = uid
        report.gaussians_added += len(obs.gaussians)
    return staged, next_id


def fuse_frame_instances(
    instances: Mapping[int, InstanceUnit],
    staged: dict[int, InstanceUnit],
    estimator: EstimatorConfig,
    ctx: Matching,
    report: UpdateReport,
) -> tuple[dict[int, InstanceUnit], set[int]]:
    """Fuse the frame's instances with map instances of the same object (map/dedup.py).

    Returns:
        (the frame's instances after fusion, the map instances fused away).
    """
    fused, absorbed = fuse_instances(
        {**instances, **staged},
        staged,
        set(report.local_to_global.values()),
        ctx.tau_s,
        estimator,
        ctx.merge_text,
    )
    staged = {i: u for i, u in staged.items() if i not in absorbed} | fused
    removed = absorbed.keys() & instances.keys()
    report.local_to_global = {k: absorbed.get(v, v) for k, v in report.local_to_global.items()}
    report_fused(report.instances_added, report.instances_merged, absorbed, removed, report)
    return staged, removed
