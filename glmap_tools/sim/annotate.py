"""Ground-truth perception: a rendered id mask plus the layout, as the core's annotation format.

The output feeds `glmap_tools.perception.annotated.semantics_from_annotation` directly:
objects with fewer than `min_pixels` pixels in the frame are dropped and their pixels set to
0 (every listed object has pixels, every non-zero pixel is a listed object); regions become
groups restricted to their visible members, and are left out when no member is visible.
A group's description names only its visible members, with the region's name and purpose
(a captioner cannot name what it has not seen).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from glmap_tools.sim.describe import count_phrase
from glmap_tools.sim.layout import Layout, Region

REFERENCE_PIXELS = 640 * 480
REFERENCE_MIN_PIXELS = 64  # at 640x480; scaled with the image area


def default_min_pixels(height: int, width: int) -> int:
    """The sliver threshold for an image size (64 pixels at 640x480, at least 4)."""
    return max(4, round(REFERENCE_MIN_PIXELS * height * width / REFERENCE_PIXELS))


def annotate_view(
    instance_mask: np.ndarray, layout: Layout, min_pixels: int | None = None
) -> tuple[np.ndarray, dict[str, Any]]:
    """Filter an id mask and describe its objects and regions.

    Args:
        instance_mask: [H, W] int layout object ids, 0 = none.
        layout: the scene the mask was rendered from.
        min_pixels: objects with fewer pixels are dropped (default: `default_min_pixels`).

    Returns:
        ([H, W] int32 mask with dropped objects zeroed, {"objects": [...], "groups": [...]}).
    """
    mask = np.asarray(instance_mask).astype(np.int32, copy=True)
    h, w = mask.shape
    threshold = default_min_pixels(h, w) if min_pixels is None else int(min_pixels)
    counts = np.bincount(mask.ravel())
    by_id = layout.objects_by_id
    keep = [i for i in np.nonzero(counts)[0] if i > 0 and counts[i] >= threshold and i in by_id]
    keep_set = {int(i) for i in keep}
    lut = np.zeros(len(counts), dtype=np.int32)
    lut[list(keep_set)] = list(keep_set)
    mask = lut[mask]
    objects = [
        {"id": int(i), "label": by_id[int(i)].category, "description": by_id[int(i)].text}
        for i in sorted(keep_set)
    ]
    groups = []
    for region in layout.regions:
        members = [m for m in region.members if m in keep_set]
        if members:
            groups.append(visible_group(region, members, [by_id[m].category for m in members]))
    return mask, {"objects": objects, "groups": groups}


def region_purpose(region: Region) -> str:
    """The purpose clause of a generated region's description ("for eating meals"), or ''."""
    at = region.description.rfind(", for ")
    return region.description[at + 2 :] if at >= 0 else ""


def visible_group(region: Region, members: list[int], labels: list[str]) -> dict[str, Any]:
    """The annotation group of `region` as seen: its visible `members` and their `labels`.

    The description is "<name>: <the visible members counted>, <purpose>", e.g. "cooking
    area: a kitchen cabinet, for preparing food" while only a cabinet is in view.
    """
    purpose = region_purpose(region)
    text = f"{region.name}: {count_phrase(labels)}" + (f", {purpose}" if purpose else "")
    return {"id": region.id, "description": text, "members": list(members)}
