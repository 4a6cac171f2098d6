"""Incremental update (paper §3.1): plan a frame's changes without touching the map.

`plan_frame` turns one frame + its semantics into a `FramePlan`: new or replaced units,
their grid cells, updated occupancy and structure chunks and the report. `GLMap.integrate`
commits the plan to the store (one transaction) and only then swaps it into memory, so a
failure at any step leaves the map and the file as they were.

The frame is back-projected once (`map/frame_points.py`); the steps read its points:

1. layers (`map/frame_layers.py`): floor height, occupancy, structure background;
2. instances (`map/instance_matching.py`): mask -> points -> Gaussians, matched by text
   and geometry, then fused with map instances of the same object;
3. regions (`map/region_matching.py`): groups matched by member set, or by text and a
   shared instance, then fused; their cells are their instances' cells.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import partial
from typing import TYPE_CHECKING

import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.geometry.frame import RGBDFrame
from glmap_tools.map.frame_layers import needed_pixels, plan_occupancy, plan_structure
from glmap_tools.map.frame_points import FramePoints, frame_points
from glmap_tools.map.grid import Cell, unit_cells
from glmap_tools.map.instance_matching import (
    fuse_frame_instances,
    match_instances,
    observe_instances,
)
from glmap_tools.map.matching import Matching, buffered_text
from glmap_tools.map.region_matching import fuse_frame_regions, match_regions, region_cells
from glmap_tools.map.report import UpdateReport
from glmap_tools.map.structure import ChunkKey, StructureChunk
from glmap_tools.map.units import InstanceUnit, RegionUnit
from glmap_tools.perception.semantics import FrameSemantics

if TYPE_CHECKING:
    from glmap_tools.map.config import MapConfig
    from glmap_tools.map.state import MapState


@dataclass
class FramePlan:
    """Everything one frame changes, computed before anything is changed."""

    frame_index: int
    pose: np.ndarray  # [4, 4]
    instances: dict[int, InstanceUnit] = field(default_factory=dict)
    regions: dict[int, RegionUnit] = field(default_factory=dict)
    cells: dict[int, frozenset[Cell]] = field(default_factory=dict)
    occupancy: dict[tuple[int, int], np.ndarray] = field(default_factory=dict)
    structure: dict[ChunkKey, StructureChunk] = field(default_factory=dict)
    removed: set[int] = field(default_factory=set)  # units fused into an older one
    next_id: int = 1
    floor_z: float | None = None
    report: UpdateReport | None = None


def checked_points(frame: RGBDFrame, semantics: FrameSemantics, config: MapConfig) -> FramePoints:
    """The frame's points, after checking the semantics fit it and some depth is valid.

    Raises:
        InvalidInputError: semantics that do not fit the frame, or no valid depth at all.
    """
    shape = frame.depth.shape
    if not isinstance(semantics, FrameSemantics):
        raise InvalidInputError(
            f"semantics is {type(semantics).__name__}, not FrameSemantics; build it from the "
            "frame's ObjectObservation and GroupObservation lists."
        )
    semantics.validate(*shape)
    points = frame_points(frame, config.max_range, needed_pixels(config, semantics, shape))
    if not points.valid.any():
        raise InvalidInputError(
            f"depth has no valid pixel (all are 0, NaN, inf or beyond max_range="
            f"{config.max_range} m); check the depth scale (1000 for mm, 5000 for TUM) and units."
        )
    return points


def plan_frame(
    glmap: MapState, frame: RGBDFrame, semantics: FrameSemantics, frame_index: int
) -> FramePlan:
    """Compute the changes one frame makes to `glmap` (which is not modified).

    Raises:
        InvalidInputError: semantics that do not fit the frame, or no valid depth at all.
    """
    cfg = glmap.config
    points = checked_points(frame, semantics, cfg)
    plan = FramePlan(frame_index, frame.pose.matrix.copy(), next_id=glmap.next_id)
    report = plan.report = UpdateReport(frame_index=frame_index)

    plan.floor_z, plan.occupancy = plan_occupancy(
        glmap.occupancy, frame.pose.translation[:2], points, cfg, glmap.floor_z
    )
    plan.structure, report.structure_gaussians = plan_structure(
        glmap.structure, glmap.structure_estimator, points, semantics, cfg
    )

    observed, report.skipped = observe_instances(
        semantics, points, glmap.estimator, np.asarray(frame.depth)
    )
    texts = [o.text for o in observed] + [g.description.strip() for g in semantics.groups]
    embeddings = glmap.embedder.embed(texts) if texts else np.zeros((0, 1), np.float32)
    merge_text = partial(buffered_text, glmap.text_merger, cfg.max_text_words)
    ctx = Matching(frame_index, glmap.tau_s, merge_text)
    estimator = glmap.estimator.config
    staged, plan.next_id = match_instances(
        observed,
        embeddings[: len(observed)],
        glmap.instances,
        glmap.instance_matrix(),
        estimator,
        ctx,
        plan.next_id,
        report,
    )
    plan.instances, removed = fuse_frame_instances(glmap.instances, staged, estimator, ctx, report)
    plan.cells = {uid: unit_cells(u.gaussians, cfg.cell_size) for uid, u in plan.instances.items()}

    staged_regions, seen, plan.next_id = match_regions(
        semantics.groups,
        embeddings[len(observed) :],
        glmap.regions,
        glmap.region_matrix(),
        ctx,
        plan.next_id,
        report,
    )
    plan.regions, removed_regions = fuse_frame_regions(
        glmap.regions, staged_regions, seen, ctx, report
    )
    plan.removed = removed | removed_regions
    plan.cells |= region_cells(
        glmap.regions,
        plan.regions,
        plan.instances,
        plan.cells,
        glmap.regions_of_instance,
        glmap.grid,
        plan.removed,
    )

    report.num_instances = len((glmap.instances.keys() | plan.instances.keys()) - plan.removed)
    report.num_regions = len((glmap.regions.keys() | plan.regions.keys()) - plan.removed)
    return plan
