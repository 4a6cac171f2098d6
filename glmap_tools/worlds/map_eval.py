"""Does a GLMap built from a tour have one instance per visible object? Precision and recall.

A tour's frames and their ground-truth annotations are integrated into a `GLMap`; each map
instance is then matched to the layout object whose (slightly grown) box holds most of its
Gaussian mass, one to one, greedily by that share. Precision: matched instances / instances.
Recall: matched objects / objects listed in at least one frame's annotation.

Duplicates are reported per map: duplicate instances are map instances that hold most of
their mass in an object another instance was matched to (several instances for one object);
duplicate regions are regions that share a member instance and a description (one in common,
or text cosine >= the map's tau_s).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.geometry import Pose
from glmap_tools.geometry.frame import RGBDFrame
from glmap_tools.language.text_merger import split_buffer
from glmap_tools.perception.annotated import semantics_from_annotation
from glmap_tools.perception.geometric import segment_frame
from glmap_tools.perception.labelling import oracle_semantics
from glmap_tools.perception.semantics import FrameSemantics
from glmap_tools.sim.annotate import annotate_view
from glmap_tools.sim.layout import Layout, SceneObject
from glmap_tools.sim.render import CameraSpec, SceneRenderer
from glmap_tools.worlds.tour import plan_tour

if TYPE_CHECKING:
    from glmap_tools.map import GLMap

MATCH_MARGIN = 0.05  # metres the object boxes are grown by
MIN_SHARE = 0.5  # of an instance's Gaussian mass inside the object's box


@dataclass(frozen=True)
class MapEvaluation:
    """Instance-level agreement of a map with the layout."""

    precision: float
    recall: float
    instances: int
    visible_objects: int
    matched: dict[int, int]  # map instance id -> layout object id
    missed: list[int]  # visible layout objects with no instance
    spurious: list[int]  # map instances matched to no object (or a duplicate)
    # layout object id -> the other map instances that fit it (beyond the matched one)
    duplicate_instances: dict[int, list[int]] = field(default_factory=dict)
    # groups of region ids that share members and a description
    duplicate_regions: list[list[int]] = field(default_factory=list)


def tour_frames(
    layout: Layout,
    camera: CameraSpec | None = None,
    step: float = 0.4,
    spin: int = 8,
    max_frames: int | None = None,
    min_pixels: int | None = None,
) -> Iterator[tuple[RGBDFrame, FrameSemantics, set[int]]]:
    """The tour's frames with their semantics and the object ids they list."""
    camera = camera or CameraSpec()
    renderer = SceneRenderer(layout, camera)
    try:
        for stop in plan_tour(layout, step=step, spin=spin)[: max_frames or None]:
            pose = Pose.from_position_heading(stop.x, stop.y, camera.camera_height, stop.heading)
            view = renderer.render(pose)
            mask, annotation = annotate_view(view.instance_mask, layout, min_pixels)
            frame = RGBDFrame(view.rgb, view.depth, renderer.intrinsics, pose)
            listed = {o["id"] for o in annotation["objects"]}
            yield frame, semantics_from_annotation(mask, annotation), listed
    finally:
        renderer.close()


def _share_inside(means: np.ndarray, weights: np.ndarray, obj: SceneObject) -> float:
    local = (means[:, :2] - obj.position[:2]) @ obj.rotation[:2, :2]
    half = obj.size[:2] / 2 + MATCH_MARGIN
    inside = np.all(np.abs(local) <= half, axis=1)
    inside &= means[:, 2] >= obj.position[2] - MATCH_MARGIN
    inside &= means[:, 2] <= obj.top + MATCH_MARGIN
    return float(weights[inside].sum() / max(weights.sum(), 1e-12))


def evaluate_instances(glmap: GLMap, layout: Layout, visible: set[int]) -> MapEvaluation:
    """Match map instances to visible layout objects (see the module docstring)."""
    objects = [layout.object(i) for i in sorted(visible)]
    pairs = []
    for inst_id, unit in glmap.instances.items():
        means = unit.gaussians.means.astype(np.float64)
        weights = unit.gaussians.counts.astype(np.float64)
        for obj in objects:
            share = _share_inside(means, weights, obj)
            if share >= MIN_SHARE:
                pairs.append((share, inst_id, obj.id))
    matched: dict[int, int] = {}
    taken: set[int] = set()
    ranked = sorted(pairs, key=lambda p: (-p[0], p[1], p[2]))
    for _, inst_id, obj_id in ranked:
        if inst_id in matched or obj_id in taken:
            continue
        matched[inst_id] = obj_id
        taken.add(obj_id)
    duplicates: dict[int, list[int]] = {}
    best_object: dict[int, int] = {}
    for _, inst_id, obj_id in ranked:  # each unmatched instance's best-fitting object
        best_object.setdefault(inst_id, obj_id)
    for inst_id, obj_id in sorted(best_object.items()):
        if inst_id not in matched and obj_id in taken:
            duplicates.setdefault(obj_id, []).append(inst_id)
    n_inst = len(glmap.instances)
    return MapEvaluation(
        precision=len(matched) / n_inst if n_inst else 0.0,
        recall=len(taken) / len(visible) if visible else 0.0,
        instances=n_inst,
        visible_objects=len(visible),
        matched=matched,
        missed=sorted(visible - taken),
        spurious=sorted(set(glmap.instances) - set(matched)),
        duplicate_instances=dict(sorted(duplicates.items())),
        duplicate_regions=duplicate_regions(glmap),
    )


def duplicate_regions(glmap: GLMap) -> list[list[int]]:
    """Groups (ids ascending) of map regions linked by shared members and a description.

    Two regions are linked when they share a member instance and a description: one in
    common, or a text cosine >= the map's tau_s. A group is a connected set of links.
    """
    regions = sorted(glmap.regions.values(), key=lambda r: r.id)
    group_of = {r.id: r.id for r in regions}

    def root(i: int) -> int:
        while group_of[i] != i:
            i = group_of[i]
        return i

    for k, a in enumerate(regions):
        for b in regions[k + 1 :]:
            if not set(a.instance_ids) & set(b.instance_ids):
                continue
            same_text = bool(set(split_buffer(a.text)) & set(split_buffer(b.text)))
            if same_text or float(a.embedding @ b.embedding) >= glmap.tau_s:
                group_of[max(root(a.id), root(b.id))] = min(root(a.id), root(b.id))
    groups: dict[int, list[int]] = {}
    for r in regions:
        groups.setdefault(root(r.id), []).append(r.id)
    return [ids for ids in groups.values() if len(ids) > 1]


def build_map_from_tour(
    layout: Layout,
    glmap: GLMap,
    camera: CameraSpec | None = None,
    step: float = 0.4,
    spin: int = 8,
    max_frames: int | None = None,
    min_pixels: int | None = None,
    perception: str = "annotated",
) -> set[int]:
    """Integrate a tour's frames into `glmap`; returns the ids of the objects seen.

    `min_pixels`: objects smaller in a frame are left out of its annotation (default: 64 at
    640x480, scaled with the image area). `perception`: "annotated" (ground-truth masks) or
    "geometric" (model-free segments named by ground truth, largest overlap).
    """
    if perception not in ("annotated", "geometric"):
        raise InvalidInputError(
            f"perception {perception!r} is unknown; use 'annotated' or 'geometric'."
        )
    seen: set[int] = set()
    for i, (frame, semantics, listed) in enumerate(
        tour_frames(layout, camera, step, spin, max_frames, min_pixels)
    ):
        if perception == "geometric":
            semantics, _ = oracle_semantics(segment_frame(frame), semantics)
        glmap.integrate(frame, semantics, frame_index=i)
        seen |= listed
    return seen
