"""A perception model that errs like an open-vocabulary detector and a captioning MLLM.

`detect_view` turns a rendered id mask into the annotation format of
`glmap_tools.perception.annotated`, as `annotate.annotate_view` does, but with the errors of
real models (rates in `data/detector_rates.json`, their sources in `sim/design.md`):

- misses: recall = recall_max x f(apparent size) x f(distance) x f(visible fraction);
- label confusions inside one confusion group (sofa/armchair/bed, tv/monitor/picture ...),
  more often for few pixels and at distance, and more for some objects than others (a
  per-object difficulty drawn once per scene: a real detector misreads the same armchair
  again and again);
- false positives: at a per-frame rate, the goal's category on an object of the goal's
  confusion group (a sink taken for a toilet) or on a segment of wall or floor;
- masks that bleed a few pixels across depth edges; a wrong colour in a share of
  descriptions;
- region descriptions from the perceived members only (`annotate.visible_group`).

Draws are seeded per (scene, episode, view): the same view in the same episode gives the
same detections to every agent, and a seeded episode replays identically.
"""

from __future__ import annotations

import json
import math
import os
import zlib
from dataclasses import dataclass, fields
from functools import cache
from importlib import resources
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.geometry.camera import Intrinsics
from glmap_tools.sim.annotate import REFERENCE_PIXELS, default_min_pixels, visible_group
from glmap_tools.sim.describe import object_description
from glmap_tools.sim.jsonfile import read_json
from glmap_tools.sim.layout import Layout, SceneObject
from glmap_tools.sim.palette import COLORS

PERCEPTIONS = ("gt", "detector")
RATES_FORMAT = "glmap-detector-rates"
RATES_ENV = "GLMAP_DETECTOR_RATES"  # a rates file of one's own (every server and worker)


@dataclass(frozen=True)
class DetectorRates:
    """The detector's error rates (see `data/detector_rates.json` and sim/design.md).

    Pixel counts are at the 640x480 reference image and scale with the image area.
    """

    recall_max: float
    recall_half_pixels: float
    recall_size_exponent: float
    recall_full_distance_m: float
    recall_far_distance_m: float
    recall_far_factor: float
    recall_full_visible: float
    recall_occluded_factor: float
    confusion_base: float
    confusion_small_extra: float
    confusion_far_extra: float
    object_difficulty_spread: float
    false_positive_per_frame: float
    false_positive_on_object_share: float
    false_positive_segment_pixels: float
    mask_bleed_rate: float
    mask_bleed_pixels: float
    wrong_color_rate: float
    confusion_groups: tuple[tuple[str, ...], ...]

    def group_of(self, category: str) -> tuple[str, ...]:
        """The confusion group holding `category` (empty: never confused)."""
        return _groups(self.confusion_groups).get(category, ())


@cache
def _groups(groups: tuple[tuple[str, ...], ...]) -> dict[str, tuple[str, ...]]:
    return {c: g for g in groups for c in g}


def load_rates(path: str | Path | None = None) -> DetectorRates:
    """Read the rates file: `path`, else `$GLMAP_DETECTOR_RATES`, else the bundled
    `data/detector_rates.json`.

    Raises:
        InvalidInputError: an unreadable file or not JSON, a missing or unknown key, or a rate
            outside its range.
    """
    path = path or os.environ.get(RATES_ENV) or None
    if path is None:
        where = "data/detector_rates.json"
        data = json.loads(
            (resources.files("glmap_tools") / "data" / "detector_rates.json").read_text()
        )
    else:
        where = str(path)
        bundled = f"a copy of the bundled data/detector_rates.json (or unset {RATES_ENV})"
        data = read_json(path, "detector rates file", bundled)
    if not isinstance(data, dict) or data.get("format") != RATES_FORMAT:
        raise InvalidInputError(f"{where} is not a {RATES_FORMAT} file (its 'format' key).")
    names = [f.name for f in fields(DetectorRates)]
    missing = [n for n in names if n not in data]
    unknown = sorted(set(data) - set(names) - {"format", "version", "reference_image"})
    if missing or unknown:
        raise InvalidInputError(
            f"{where}: missing keys {missing}, unknown keys {unknown}; see the bundled file."
        )
    values: dict[str, Any] = {
        "confusion_groups": _confusion_groups(data["confusion_groups"], where)
    }
    for n in names:
        if n != "confusion_groups":
            upper = 1.0 if n.endswith(("_rate", "_share", "_per_frame", "recall_max")) else math.inf
            values[n] = _rate(data[n], n, upper, where)
    return DetectorRates(**values)


def _rate(value: Any, name: str, upper: float, where: str) -> float:
    """A rate file's number, finite and in [0, upper]."""
    v = math.nan
    if isinstance(value, int | float) and not isinstance(value, bool):
        try:
            v = float(value)
        except OverflowError:  # an integer past float64
            v = math.inf
    if not (math.isfinite(v) and 0.0 <= v <= upper):
        raise InvalidInputError(
            f"{where}: {name}={str(value)[:40]} must be a number in [0, {upper}]."
        )
    return v


def _confusion_groups(groups: Any, where: str) -> tuple[tuple[str, ...], ...]:
    """A rate file's confusion groups: lists of category names."""
    if not isinstance(groups, list) or not all(
        isinstance(g, list) and all(isinstance(c, str) for c in g) for g in groups
    ):
        raise InvalidInputError(
            f"{where}: confusion_groups must be lists of category names, e.g. "
            f'[["sofa", "armchair"]] (got {str(groups)[:80]}).'
        )
    return tuple(tuple(g) for g in groups)


@dataclass(frozen=True)
class ObjectView:
    """What decides how one visible object is perceived in one view.

    Attributes:
        pixels: its mask's pixel count.
        distance: metres from the camera to its nearest visible point.
        visible: the share of it in view (occlusion and image borders), in [0, 1].
    """

    pixels: int
    distance: float
    visible: float


def size_factor(pixels: float, image_pixels: int, rates: DetectorRates) -> float:
    """Recall's size term: 1/2 at `recall_half_pixels` (scaled to the image), -> 1 when large."""
    half = rates.recall_half_pixels * image_pixels / REFERENCE_PIXELS
    return 1.0 / (1.0 + (half / max(pixels, 1e-9)) ** rates.recall_size_exponent)


def far_share(distance: float, rates: DetectorRates) -> float:
    """0 up to `recall_full_distance_m`, rising linearly to 1 at `recall_far_distance_m`."""
    near, far = rates.recall_full_distance_m, rates.recall_far_distance_m
    return float(np.clip((distance - near) / max(far - near, 1e-9), 0.0, 1.0))


def recall(view: ObjectView, image_pixels: int, rates: DetectorRates) -> float:
    """Probability that a visible object is detected at all."""
    dist = 1.0 - (1.0 - rates.recall_far_factor) * far_share(view.distance, rates)
    full = rates.recall_full_visible
    vis = (
        1.0
        if view.visible >= full
        else (
            rates.recall_occluded_factor
            + (1.0 - rates.recall_occluded_factor) * view.visible / full
        )
    )
    return rates.recall_max * size_factor(view.pixels, image_pixels, rates) * dist * vis


def confusion(
    view: ObjectView, image_pixels: int, difficulty: float, rates: DetectorRates
) -> float:
    """Probability that a detected object of a confusable category gets another group label."""
    small = 1.0 - size_factor(view.pixels, image_pixels, rates)
    p = (
        rates.confusion_base
        + rates.confusion_small_extra * small
        + rates.confusion_far_extra * far_share(view.distance, rates)
    )
    return float(np.clip(p * difficulty, 0.0, 1.0))


def stable_key(text: str) -> int:
    """A seed word from a text, the same in every process (unlike `hash`)."""
    return zlib.crc32(text.encode("utf-8"))


def object_difficulty(layout: Layout, object_id: int, rates: DetectorRates) -> float:
    """A per-object factor on its confusion rate, fixed for the scene: 1 +- spread."""
    u = np.random.default_rng([stable_key(layout.name), int(object_id), 17]).random()
    return 1.0 + rates.object_difficulty_spread * (2.0 * u - 1.0)


def view_seed(layout: Layout, episode: str, pose: np.ndarray) -> list[int]:
    """The seed words of one view: scene, episode, and the camera position and heading."""
    x, y = (round(float(v) * 100) for v in pose[:2, 3])
    forward = pose[:3, 2]
    heading = round(math.degrees(math.atan2(float(forward[1]), float(forward[0])))) % 360
    return [stable_key(layout.name), stable_key(episode), x & 0xFFFFFFFF, y & 0xFFFFFFFF, heading]


def object_views(
    mask: np.ndarray,
    depth: np.ndarray,
    layout: Layout,
    intrinsics: Intrinsics,
    pose: np.ndarray,
    ids: list[int],
) -> dict[int, ObjectView]:
    """Pixels, distance and visible share of each listed object in one view.

    The visible share is the object's pixels over its pixels plus the pixels of its
    projected box that something nearer hides, times the square root of the share of the
    projected box inside the image (corners behind the camera are left out).

    Args:
        mask: [H, W] int object ids.
        depth: [H, W] metres along the optical axis (0: no hit).
        pose: [4, 4] world_from_camera (OpenCV camera).
    """
    h, w = mask.shape
    camera_from_world = np.linalg.inv(pose)
    by_id = layout.objects_by_id
    out: dict[int, ObjectView] = {}
    for i in ids:
        own = mask == i
        pixels = int(own.sum())
        d = depth[own]
        d = d[d > 0]
        distance = float(d.min()) if d.size else 0.0
        out[i] = ObjectView(
            pixels,
            distance,
            _visible_share(own, pixels, depth, by_id[i], intrinsics, camera_from_world, (h, w)),
        )
    return out


def _box_corners(obj: SceneObject) -> np.ndarray:  # [8, 3]
    foot = obj.footprint()
    z0, z1 = float(obj.position[2]), obj.top
    return np.vstack([np.c_[foot, np.full(4, z0)], np.c_[foot, np.full(4, z1)]])


def _visible_share(
    own: np.ndarray,
    pixels: int,
    depth: np.ndarray,
    obj: SceneObject,
    intrinsics: Intrinsics,
    camera_from_world: np.ndarray,
    shape: tuple[int, int],
) -> float:
    corners = _box_corners(obj) @ camera_from_world[:3, :3].T + camera_from_world[:3, 3]
    front = corners[:, 2] > 0.05
    if front.sum() < 3:
        return 0.0
    pts = corners[front]
    uv = np.c_[
        intrinsics.fx * pts[:, 0] / pts[:, 2] + intrinsics.cx,
        intrinsics.fy * pts[:, 1] / pts[:, 2] + intrinsics.cy,
    ]
    hull = cv2.convexHull(uv.astype(np.float32)).reshape(-1, 2)
    total = float(cv2.contourArea(hull))
    if total <= 0.0:
        return 1.0
    h, w = shape
    inside = np.zeros(shape, dtype=np.uint8)
    cv2.fillConvexPoly(inside, np.round(hull).astype(np.int32), 1)
    in_image = float(inside.sum())
    truncation = min(1.0, in_image / total)
    nearest = float(pts[:, 2].min())
    hidden = int(((inside > 0) & ~own & (depth > 0) & (depth < nearest - 0.05)).sum())
    # Truncated objects are found more easily than hidden ones: the in-image share counts
    # by its square root (most of a cut-off sofa still reads as a sofa).
    return math.sqrt(truncation) * pixels / max(pixels + hidden, 1)


def detect_view(
    instance_mask: np.ndarray,
    depth: np.ndarray,
    layout: Layout,
    intrinsics: Intrinsics,
    pose: np.ndarray,
    *,
    goal_category: str,
    episode: str,
    rates: DetectorRates | None = None,
    min_pixels: int | None = None,
) -> tuple[np.ndarray, dict[str, Any]]:
    """Perceive one rendered view as a detector and a captioner would.

    Args:
        instance_mask: [H, W] int layout object ids, 0 = none.
        depth: [H, W] metres along the optical axis.
        layout: the scene.
        intrinsics: the camera's.
        pose: [4, 4] world_from_camera.
        goal_category: the category false positives are labelled with.
        episode: the episode's id (seeds the view with the scene and the pose).
        rates: the error rates (default: the bundled file).
        min_pixels: objects with fewer pixels are never detected (as `annotate_view`).

    Returns:
        ([H, W] int32 mask of the detections, {"objects": [...], "groups": [...]}).
    """
    rates = rates or load_rates()
    mask = np.asarray(instance_mask).astype(np.int32, copy=False)
    h, w = mask.shape
    threshold = default_min_pixels(h, w) if min_pixels is None else int(min_pixels)
    by_id = layout.objects_by_id
    counts = np.bincount(mask.ravel())
    ids = [int(i) for i in np.nonzero(counts)[0] if i > 0 and counts[i] >= threshold and i in by_id]
    rng = np.random.default_rng(view_seed(layout, episode, pose))
    views = object_views(mask, depth, layout, intrinsics, pose, ids)
    image_pixels = h * w

    labels: dict[int, str] = {}
    texts: dict[int, str] = {}
    for i in ids:
        obj, view = by_id[i], views[i]
        # Every draw is made for every object, so one object's outcome never shifts another's.
        seen, confused, pick, recolour, colour = rng.random(5)
        if seen >= recall(view, image_pixels, rates):
            continue
        label = obj.category
        group = [c for c in rates.group_of(label) if c != label]
        p = confusion(view, image_pixels, object_difficulty(layout, i, rates), rates)
        if group and confused < p:
            label = group[min(int(pick * len(group)), len(group) - 1)]
        attributes = dict(obj.attributes)
        if "color" in attributes and recolour < rates.wrong_color_rate:
            others = [c for c in COLORS if c != attributes["color"]]
            attributes["color"] = others[min(int(colour * len(others)), len(others) - 1)]
        labels[i] = label
        if label == obj.category and attributes == obj.attributes:
            texts[i] = obj.text
        else:
            texts[i] = object_description(label, attributes)

    lut = np.zeros(int(mask.max()) + 1, dtype=np.int32)  # detected ids kept, the rest 0
    lut[list(labels)] = list(labels)
    out = lut[mask]
    _bleed(out, list(labels), rng, rates, w)
    _false_positive(out, depth, layout, labels, texts, goal_category, rng, rates, threshold)

    present = {int(i) for i in np.unique(out) if i > 0}
    objects = [
        {"id": i, "label": labels[i], "description": texts[i]}
        for i in sorted(labels)
        if i in present
    ]
    groups = []
    for region in layout.regions:
        members = [m for m in region.members if m in present]
        if members:
            groups.append(visible_group(region, members, [labels[m] for m in members]))
    return out, {"objects": objects, "groups": groups}


def _bleed(
    out: np.ndarray, ids: list[int], rng: np.random.Generator, rates: DetectorRates, width: int
) -> None:
    """Grow some masks by a few pixels over their neighbours (a depth-edge bleed)."""
    k = max(1, round(rates.mask_bleed_pixels * width / 640))
    kernel = np.ones((2 * k + 1, 2 * k + 1), np.uint8)
    draws = rng.random(len(ids))
    for i, u in zip(ids, draws, strict=True):
        if u < rates.mask_bleed_rate:
            grown = cv2.dilate((out == i).astype(np.uint8), kernel) > 0
            out[grown] = i


def _false_positive(
    out: np.ndarray,
    depth: np.ndarray,
    layout: Layout,
    labels: dict[int, str],
    texts: dict[int, str],
    goal_category: str,
    rng: np.random.Generator,
    rates: DetectorRates,
    min_pixels: int,
) -> None:
    """At the per-frame rate, label an object that looks like the goal (its confusion
    group) or a background segment as the goal."""
    happens, on_object, pick, colour, where = rng.random(5)
    if happens >= rates.false_positive_per_frame or not goal_category:
        return
    by_id = layout.objects_by_id
    name = list(COLORS)[min(int(colour * len(COLORS)), len(COLORS) - 1)]
    # Detectors' false positives are mostly objects that look like the class (Hoiem et al.
    # 2012): a wrong object gets the goal's label only if it is of the goal's group.
    similar = sorted(
        i
        for i in labels
        if by_id[i].category != goal_category
        and labels[i] != goal_category
        and goal_category in rates.group_of(by_id[i].category)
    )
    if on_object < rates.false_positive_on_object_share:
        if not similar:
            return  # nothing in view looks like the goal
        i = similar[min(int(pick * len(similar)), len(similar) - 1)]
        labels[i] = goal_category
        attributes = dict(by_id[i].attributes)
        texts[i] = object_description(goal_category, attributes)
        return
    h, w = out.shape
    background = (out == 0) & (depth > 0)
    rows, cols = np.nonzero(background)
    if rows.size == 0:
        return
    k = min(int(where * rows.size), rows.size - 1)
    side = max(2, round(math.sqrt(rates.false_positive_segment_pixels * h * w / REFERENCE_PIXELS)))
    r0, c0 = max(0, rows[k] - side // 2), max(0, cols[k] - side // 2)
    patch = np.zeros_like(background)
    patch[r0 : r0 + side, c0 : c0 + side] = True
    patch &= background
    if patch.sum() < min_pixels:
        return
    fp_id = max(by_id) + 1
    out[patch] = fp_id
    labels[fp_id] = goal_category
    texts[fp_id] = object_description(goal_category, {"color": name})
