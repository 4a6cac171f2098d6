"""Synthetic ray-cast scenes (boxes on a floor) with exact depth, colour and instance masks.

Used by tests and benchmarks: known geometry, known poses, no assets needed.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from glmap_tools.geometry import Intrinsics, Pose
from glmap_tools.geometry.frame import RGBDFrame
from glmap_tools.perception import FrameSemantics, GroupObservation, ObjectObservation


@dataclass(frozen=True)
class Box:
    """An axis-aligned box belonging to object `object_id` (0 = background)."""

    lo: tuple[float, float, float]
    hi: tuple[float, float, float]
    color: tuple[float, float, float]
    object_id: int


def chair(x: float, y: float, color=(0.8, 0.2, 0.2), object_id: int = 1) -> list[Box]:
    """A 0.45 m chair: seat, four legs, a backrest on the +y side."""
    s, legw, seat_h = 0.225, 0.04, 0.45
    wood = (0.45, 0.3, 0.15)
    boxes = [Box((x - s, y - s, seat_h - 0.05), (x + s, y + s, seat_h), color, object_id)]
    for dx in (-s, s - legw):
        for dy in (-s, s - legw):
            boxes.append(
                Box(
                    (x + dx, y + dy, 0.0),
                    (x + dx + legw, y + dy + legw, seat_h - 0.05),
                    wood,
                    object_id,
                )
            )
    boxes.append(
        Box((x - s, y + s - 0.05, seat_h), (x + s, y + s, seat_h + 0.45), color, object_id)
    )
    return boxes


def table(x: float, y: float, object_id: int) -> list[Box]:
    top = (0.55, 0.4, 0.25)
    boxes = [Box((x - 0.6, y - 0.4, 0.70), (x + 0.6, y + 0.4, 0.75), top, object_id)]
    for dx in (-0.55, 0.5):
        for dy in (-0.35, 0.3):
            boxes.append(
                Box((x + dx, y + dy, 0), (x + dx + 0.05, y + dy + 0.05, 0.7), top, object_id)
            )
    return boxes


def floor(half: float = 6.0) -> list[Box]:
    return [Box((-half, -half, -0.02), (half, half, 0.0), (0.6, 0.6, 0.55), 0)]


def raycast(
    boxes: list[Box], pose: Pose, intrinsics: Intrinsics
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact depth [H, W] (0 = miss), rgb [H, W, 3] uint8 and instance ids [H, W] of `boxes`."""
    h, w = intrinsics.height, intrinsics.width
    v, u = np.mgrid[0:h, 0:w]
    dirs_cam = np.stack(
        [(u - intrinsics.cx) / intrinsics.fx, (v - intrinsics.cy) / intrinsics.fy, np.ones_like(u)],
        axis=-1,
    ).reshape(-1, 3)
    dirs = dirs_cam @ pose.rotation.T
    origin = pose.translation
    best_t = np.full(len(dirs), np.inf)
    color = np.zeros((len(dirs), 3))
    ids = np.zeros(len(dirs), dtype=np.int32)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / dirs
        for box in boxes:
            t1 = (np.array(box.lo) - origin) * inv
            t2 = (np.array(box.hi) - origin) * inv
            tnear = np.nanmax(np.minimum(t1, t2), axis=1)
            tfar = np.nanmin(np.maximum(t1, t2), axis=1)
            hit = (tnear <= tfar) & (tnear > 1e-6) & (tnear < best_t)
            best_t[hit] = tnear[hit]
            color[hit] = box.color
            ids[hit] = box.object_id
    depth = np.where(np.isfinite(best_t), best_t, 0.0)  # dirs_cam has z = 1: t is depth
    return (
        depth.reshape(h, w).astype(np.float32),
        (color.reshape(h, w, 3) * 255).round().astype(np.uint8),
        ids.reshape(h, w),
    )


def view(
    boxes: list[Box],
    eye: tuple[float, float, float],
    target: tuple[float, float, float],
    width: int = 320,
    height: int = 240,
    hfov: float = 79.0,
) -> tuple[RGBDFrame, np.ndarray]:
    """Render a frame from `eye` looking at `target`; returns (frame, instance ids)."""
    intr = Intrinsics.from_fov(width, height, hfov)
    pose = Pose.looking_at(np.array(eye), np.array(target))
    depth, rgb, ids = raycast(boxes, pose, intr)
    return RGBDFrame(rgb, depth, intr, pose), ids


def semantics(
    ids: np.ndarray,
    texts: dict[int, tuple[str, str]],
    groups: Sequence[tuple[int, str, tuple[int, ...]]] = (),
) -> FrameSemantics:
    """FrameSemantics for the visible objects of `ids` with (label, description) per id."""
    objects = [
        ObjectObservation(i, texts[i][0], texts[i][1], ids == i)
        for i in sorted(texts)
        if (ids == i).any()
    ]
    visible = {o.local_id for o in objects}
    return FrameSemantics(
        objects,
        [
            GroupObservation(g, d, tuple(m for m in members if m in visible))
            for g, d, members in groups
        ],
    )


def orbit_eye(center: tuple[float, float], radius: float, angle_deg: float, height: float = 1.2):
    a = math.radians(angle_deg)
    return (center[0] + radius * math.cos(a), center[1] + radius * math.sin(a), height)
