"""Regions of one frame (paper §3.1): groups of the frame's instances matched to map regions.

A group whose global member set equals a region's is that region. Otherwise it joins the
best region with similar text (cosine > tau_s) that shares an instance with it (the
paper), and never so that a region's members become another region's: the union then
goes to that other region. Regions that held a fused instance hold its survivor instead.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np

from glmap_tools.map.dedup import fuse_regions, normalised, with_members_renamed
from glmap_tools.map.grid import Cell, IndexGrid
from glmap_tools.map.matching import Matching, report_fused, text_candidates
from glmap_tools.map.report import SkippedObservation, UnitChange, UpdateReport
from glmap_tools.map.units import InstanceUnit, RegionUnit
from glmap_tools.perception.semantics import GroupObservation


def members_index(regions: Mapping[int, RegionUnit]) -> dict[frozenset[int], int]:
    """Member set -> region id of these regions (the highest id if several share one)."""
    return {frozenset(r.instance_ids): rid for rid, r in sorted(regions.items())}


def _target_region(
    members: set[int],
    embedding: np.ndarray,
    known: Callable[[int], RegionUnit],
    by_members: dict[frozenset[int], int],
    matrix: tuple[np.ndarray, np.ndarray],
    tau: float,
) -> tuple[float, RegionUnit] | None:
    """(similarity, region) the group with these global members joins, or None."""
    same = by_members.get(frozenset(members))
    if same is not None:
        region = known(same)
        return float(region.embedding @ embedding), region
    for sim, rid in text_candidates(*matrix, embedding, tau):
        region = known(rid)
        if members & set(region.instance_ids):
            twin = by_members.get(frozenset(members | set(region.instance_ids)), rid)
            if twin != rid:  # the union is another region's member set: merge there
                region = known(twin)
                sim = float(region.embedding @ embedding)
            return sim, region
    return None


def match_regions(
    groups: list[GroupObservation],
    embeddings: np.ndarray,
    regions: dict[int, RegionUnit],
    matrix: tuple[np.ndarray, np.ndarray],
    ctx: Matching,
    next_id: int,
    report: UpdateReport,
) -> tuple[dict[int, RegionUnit], set[int], int]:
    """Match each group to a map region or make it a new one.

    Args:
        groups: the frame's groups (`FrameSemantics.groups`).
        embeddings: [len(groups), D] their descriptions' embeddings.
        regions: the map's regions before the frame.
        matrix: (ids [M], embeddings [M, D]) of those regions.
        ctx: the frame's matching settings.
        next_id: the first free unit id.
        report: its `local_to_global` and `fused` (instances) are read; gains the added
            and merged region changes and the skipped groups.

    Returns:
        (the new or updated regions by id, the ids observed this frame, the next free id).
    """
    frame = ctx.frame_index
    staged = with_members_renamed(regions, report.fused)
    by_members = members_index({**regions, **staged})
    observed: set[int] = set()

    def known(rid: int) -> RegionUnit:
        return staged.get(rid) or regions[rid]

    for group, e in zip(groups, embeddings, strict=True):
        members = {report.local_to_global[m] for m in group.members if m in report.local_to_global}
        if not members:
            report.skipped.append(
                SkippedObservation(
                    local_id=group.local_id,
                    kind="region",
                    reason="none of its member instances made it into the map",
                )
            )
            continue
        text = group.description.strip()
        target = _target_region(members, e, known, by_members, matrix, ctx.tau_s)
        if target is None:
            rid, next_id = next_id, next_id + 1
            staged[rid] = RegionUnit(
                rid, text, normalised(e), tuple(sorted(members)), 1, frame, frame
            )
            by_members[frozenset(members)] = rid
            observed.add(rid)
            report.regions_added.append(
                UnitChange(local_id=group.local_id, global_id=rid, text=text)
            )
            continue
        sim, region = target
        n = region.observations
        seen_now = region.last_frame == frame and region.id in staged
        union = tuple(sorted(members | set(region.instance_ids)))
        staged[region.id] = RegionUnit(
            region.id,
            ctx.merge_text(region.text, text),
            normalised(region.embedding * n + e),
            union,
            n if seen_now else n + 1,
            region.first_frame,
            frame,
        )
        if by_members.get(frozenset(region.instance_ids)) == region.id:
            del by_members[frozenset(region.instance_ids)]
        by_members[frozenset(union)] = region.id
        observed.add(region.id)
        report.regions_merged.append(
            UnitChange(local_id=group.local_id, global_id=region.id, text=text, similarity=sim)
        )
    return staged, observed, next_id


def fuse_frame_regions(
    regions: Mapping[int, RegionUnit],
    staged: dict[int, RegionUnit],
    observed: set[int],
    ctx: Matching,
    report: UpdateReport,
) -> tuple[dict[int, RegionUnit], set[int]]:
    """Fuse the frame's regions with map regions that are the same region (map/dedup.py).

    Returns:
        (the frame's regions after fusion, the map regions fused away).
    """
    fused, absorbed = fuse_regions(
        {**regions, **staged}, staged, observed, ctx.tau_s, ctx.merge_text
    )
    staged = {i: r for i, r in staged.items() if i not in absorbed} | fused
    removed = absorbed.keys() & regions.keys()
    report_fused(report.regions_added, report.regions_merged, absorbed, removed, report)
    return staged, removed


def region_cells(
    regions: Mapping[int, RegionUnit],
    staged: Mapping[int, RegionUnit],
    instances: Mapping[int, InstanceUnit],
    instance_cells: Mapping[int, frozenset[Cell]],
    regions_of_instance: Callable[[int], set[int]],
    grid: IndexGrid,
    removed: set[int],
) -> dict[int, frozenset[Cell]]:
    """Grid cells of every region the frame touched: the union of its instances' cells.

    Args:
        regions: the map's regions before the frame.
        staged: the frame's new or updated regions.
        instances: the frame's new or updated instances (their regions are touched too).
        instance_cells: the cells of those instances.
        regions_of_instance: the map's regions holding an instance.
        grid: the map's index grid (cells of instances the frame did not change).
        removed: units fused away this frame.
    """
    touched = set(staged)
    for uid in instances:
        touched |= regions_of_instance(uid)
    out: dict[int, frozenset[Cell]] = {}
    for rid in touched - removed:
        region = staged.get(rid) or regions[rid]
        cells: set[Cell] = set()
        for iid in region.instance_ids:
            cells |= instance_cells.get(iid) or grid.cells_of_unit(iid)
        out[rid] = frozenset(cells)
    return out
