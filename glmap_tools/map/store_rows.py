"""Map units as rows of the store's tables (store_schema.py), in column order: all of a map,
or what one frame's plan changes, as {table: rows} in the order they are written.

The way back, rows to checked units, is `store_check.py`'s reader.
"""

from __future__ import annotations

import io
import json
from typing import TYPE_CHECKING

import numpy as np

from glmap_tools.map.structure import ChunkKey, StructureChunk
from glmap_tools.map.units import InstanceUnit, RegionUnit

if TYPE_CHECKING:
    from glmap_tools.map.fusion import FramePlan
    from glmap_tools.map.state import MapState

Row = tuple[object, ...]


def to_npy(arr: np.ndarray) -> bytes:
    """`arr` as the bytes of a .npy file (C order, no pickle)."""
    buf = io.BytesIO()
    np.save(buf, np.ascontiguousarray(arr), allow_pickle=False)
    return buf.getvalue()


def instance_row(u: InstanceUnit) -> Row:
    """A row of the `instances` table."""
    g = u.gaussians
    return (
        u.id,
        u.label,
        u.text,
        to_npy(u.embedding),
        to_npy(g.means),
        to_npy(g.covs),
        to_npy(g.colors),
        to_npy(g.opacities),
        to_npy(g.counts),
        u.observations,
        u.first_frame,
        u.last_frame,
    )


def region_row(r: RegionUnit) -> Row:
    """A row of the `regions` table (member ids as a JSON list)."""
    return (
        r.id,
        r.text,
        to_npy(r.embedding),
        json.dumps(list(r.instance_ids)),
        r.observations,
        r.first_frame,
        r.last_frame,
    )


def occupancy_rows(chunks: dict[tuple[int, int], np.ndarray]) -> list[Row]:
    """Rows of the `occupancy` table, one per chunk of counts."""
    return [(ci, cj, to_npy(c)) for (ci, cj), c in chunks.items()]


def structure_rows(chunks: dict[ChunkKey, StructureChunk]) -> list[Row]:
    """Rows of the `structure` table, one per chunk of the structure layer."""
    return [
        (
            ci,
            cj,
            to_npy(c.keys),
            to_npy(c.gaussians.means),
            to_npy(c.gaussians.covs),
            to_npy(c.gaussians.colors),
            to_npy(c.gaussians.opacities),
            to_npy(c.gaussians.counts),
        )
        for (ci, cj), c in chunks.items()
    ]


def frame_row(frame_index: int, pose: np.ndarray) -> Row:
    """A row of the `frames` table (its `seq` is SQLite's)."""
    return (frame_index, to_npy(pose))


def map_rows(glmap: MapState) -> dict[str, list[Row]]:
    """The rows of all of `glmap` (every frame of its trajectory), by table."""
    return {
        "instances": [instance_row(u) for u in glmap.instances.values()],
        "regions": [region_row(r) for r in glmap.regions.values()],
        "occupancy": occupancy_rows(glmap.occupancy.chunks),
        "structure": structure_rows(glmap.structure.chunks),
        "frames": [frame_row(i, p) for i, p in enumerate(glmap.trajectory)],
    }


def plan_rows(plan: FramePlan) -> dict[str, list[Row]]:
    """The rows one frame's plan writes (new and changed units, chunks, its pose), by table."""
    return {
        "frames": [frame_row(plan.frame_index, plan.pose)],
        "instances": [instance_row(u) for u in plan.instances.values()],
        "regions": [region_row(r) for r in plan.regions.values()],
        "occupancy": occupancy_rows(plan.occupancy),
        "structure": structure_rows(plan.structure),
    }
