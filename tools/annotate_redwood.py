"""Regenerate the instance annotations of the bundled Redwood living-room frames.

Usage::

    python tools/annotate_redwood.py                  # write annotations/, print the check
    python tools/annotate_redwood.py --check-only     # only print the centroid spread
    python tools/annotate_redwood.py --overlay /tmp/redwood_overlay.png

Each object has a hand-chosen polygon per frame (pixel coordinates, read off frames 0 and 4
drawn with a 20 px grid; frames 1-3 placed between them, following the image motion of
about 2.5 px per frame measured by projecting fixed world points) and a hand-chosen world
box (metres, z-up world of `open_sequence`, read off a top-down view of the back-projected
frames). A pixel belongs to
the object when it lies inside the polygon, has valid depth, back-projects into the box, and
is not next to a depth discontinuity (flying pixels); small specks are removed and the mask
is eroded by one pixel. The check back-projects each mask with the frame's pose and prints
how far each frame's object centroid lies from the mean over frames.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from glmap_tools.geometry import backproject
from glmap_tools.ingest import open_sequence, write_annotation
from glmap_tools.ingest.datasets import RGBDSequence

BUNDLED = Path(__file__).resolve().parents[1] / "glmap_tools/data/redwood_livingroom1_5frames"
FLOOR_Z = 0.132  # measured: median world z of the floor pixels
EDGE_JUMP = 0.05  # metres, plus EDGE_JUMP_PER_M2 * depth^2: a depth jump within 2 px
EDGE_JUMP_PER_M2 = 0.03  # grows with depth like the sensor's noise and grazing-angle slope
MIN_SPECK = 150  # connected pieces smaller than this many pixels are dropped

Polygon = list[tuple[int, int]]


@dataclass(frozen=True)
class ObjectSpec:
    """One annotated object: its id, words, world box and a polygon per frame."""

    id: int
    label: str
    description: str
    box_min: tuple[float, float, float]
    box_max: tuple[float, float, float]
    polygons: dict[int, Polygon]


OBJECTS = [
    ObjectSpec(
        id=1,
        label="lounge chair",
        description=(
            "a white upholstered lounge chair with a curved seat on a shiny chrome tubular "
            "frame that rests on two sled runners"
        ),
        box_min=(-2.36, -2.88, FLOOR_Z + 0.012),
        box_max=(-1.40, -1.55, 1.40),
        polygons={
            0: [(330, 98), (500, 98), (505, 182), (608, 182), (608, 398), (330, 398)],
            1: [(327, 98), (497, 98), (502, 182), (605, 182), (605, 402), (327, 402)],
            2: [(324, 98), (494, 98), (499, 182), (602, 182), (602, 406), (324, 406)],
            3: [(321, 98), (491, 98), (496, 182), (599, 182), (599, 410), (321, 410)],
            4: [(318, 98), (488, 98), (493, 182), (596, 182), (596, 414), (318, 414)],
        },
    ),
    ObjectSpec(
        id=2,
        label="curtain",
        description="a long white sheer curtain hanging in soft vertical folds by the glass door",
        box_min=(-2.40, -3.06, FLOOR_Z + 0.015),
        box_max=(-1.70, -2.85, 3.00),
        polygons={
            0: [(166, 0), (276, 0), (276, 368), (166, 368)],
            1: [(163, 0), (274, 0), (274, 369), (163, 369)],
            2: [(161, 0), (271, 0), (271, 370), (161, 370)],
            3: [(158, 0), (269, 0), (269, 371), (158, 371)],
            4: [(156, 0), (266, 0), (266, 372), (156, 372)],
        },
    ),
    ObjectSpec(
        id=3,
        label="door frame",
        description=(
            "the white frame of a tall sliding glass door that opens onto a brick-walled balcony"
        ),
        box_min=(-1.60, -3.20, FLOOR_Z + 0.015),
        box_max=(-1.40, -2.98, 3.00),
        polygons={
            0: [(72, 0), (124, 0), (124, 390), (72, 390)],
            1: [(69, 0), (121, 0), (121, 393), (69, 393)],
            2: [(66, 0), (118, 0), (118, 395), (66, 395)],
            3: [(64, 0), (116, 0), (116, 398), (64, 398)],
            4: [(61, 0), (113, 0), (113, 400), (61, 400)],
        },
    ),
    ObjectSpec(
        id=4,
        label="floor",
        description="a glossy honey-coloured wooden plank floor",
        box_min=(-2.42, -2.99, FLOOR_Z - 0.03),
        box_max=(0.00, 0.00, FLOOR_Z + 0.012),
        polygons={k: [(0, 290), (639, 290), (639, 479), (0, 479)] for k in range(5)},
    ),
    ObjectSpec(
        id=5,
        label="wall",
        description="a white textured plaster wall",
        box_min=(-2.48, -2.99, FLOOR_Z + 0.10),
        box_max=(-2.39, -1.50, 3.00),
        polygons={k: [(250, 0), (639, 0), (639, 345), (250, 345)] for k in range(5)},
    ),
]

GROUPS: list[dict[str, Any]] = [
    {
        "id": 1,
        "description": (
            "a sunny reading corner: a white lounge chair beside the curtained balcony door, "
            "for relaxing"
        ),
        "members": [1, 2],
    },
    {
        "id": 2,
        "description": (
            "the balcony door: a sliding glass door with a sheer curtain, leading outside"
        ),
        "members": [2, 3],
    },
]


def world_points(seq: RGBDSequence, k: int) -> tuple[np.ndarray, np.ndarray]:
    """World coordinates [H, W, 3] (NaN where depth is missing) and colour of frame k."""
    frame = seq.load(k).frame
    intr = frame.intrinsics
    depth = frame.depth.astype(np.float64)
    v, u = np.mgrid[0 : intr.height, 0 : intr.width]
    cam = np.stack(
        [(u - intr.cx) / intr.fx * depth, (v - intr.cy) / intr.fy * depth, depth], axis=-1
    )
    world = cam @ frame.pose.rotation.T + frame.pose.translation
    world[depth <= 0] = np.nan
    return world, frame.rgb


def depth_edges(depth: np.ndarray) -> np.ndarray:
    """[H, W] bool: pixels within 2 px of a depth jump or of missing depth."""
    kernel = np.ones((5, 5), np.uint8)
    d = depth.astype(np.float32)
    missing = (d <= 0).astype(np.uint8)
    high = cv2.dilate(d, kernel)
    low = cv2.erode(np.where(d > 0, d, np.float32(1e6)), kernel)
    jump = high - low > EDGE_JUMP + EDGE_JUMP_PER_M2 * d * d
    return jump | (cv2.dilate(missing, kernel) > 0)


def object_mask(spec: ObjectSpec, k: int, world: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """[H, W] bool mask of one object in frame k (polygon AND world box AND not an edge)."""
    h, w = edges.shape
    poly = np.zeros((h, w), np.uint8)
    cv2.fillPoly(poly, [np.array(spec.polygons[k], np.int32)], 1)
    with np.errstate(invalid="ignore"):
        inside = np.all((world >= spec.box_min) & (world <= spec.box_max), axis=-1)
    mask = (poly > 0) & inside & ~edges
    count, labels, stats, _ = cv2.connectedComponentsWithStats(
        mask.astype(np.uint8), connectivity=8
    )
    keep = np.zeros(count, bool)
    keep[1:] = stats[1:, cv2.CC_STAT_AREA] >= MIN_SPECK
    mask = keep[labels]
    return cv2.erode(mask.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0


def build(seq: RGBDSequence) -> list[np.ndarray]:
    """Instance-id masks [H, W] uint8 for every frame."""
    masks = []
    for k in range(len(seq)):
        world, _ = world_points(seq, k)
        depth = seq.load(k).frame.depth
        edges = depth_edges(depth)
        ids = np.zeros(depth.shape, np.uint8)
        for spec in OBJECTS:
            ids[object_mask(spec, k, world, edges) & (ids == 0)] = spec.id
        masks.append(ids)
    return masks


def annotation_for(ids: np.ndarray) -> dict[str, Any]:
    """The labels JSON of one frame: the objects present and the groups they form."""
    present = {int(i) for i in np.unique(ids)} - {0}
    objects = [
        {"id": s.id, "label": s.label, "description": s.description}
        for s in OBJECTS
        if s.id in present
    ]
    groups = [g for g in GROUPS if set(g["members"]) <= present]
    return {"objects": objects, "groups": groups}


def centroid_spread(seq: RGBDSequence, masks: list[np.ndarray]) -> dict[str, tuple[float, int]]:
    """Per object: the largest distance (m) of a frame's centroid from the mean, pixel count."""
    result = {}
    for spec in OBJECTS:
        centroids, pixels = [], 0
        for k, ids in enumerate(masks):
            f = seq.load(k).frame
            cloud = backproject(f.depth, f.intrinsics, f.pose, mask=ids == spec.id)
            if len(cloud):
                centroids.append(cloud.points.mean(axis=0))
                pixels += len(cloud)
        c = np.array(centroids)
        result[spec.label] = (float(np.linalg.norm(c - c.mean(0), axis=1).max()), pixels)
    return result


def overlay(seq: RGBDSequence, masks: list[np.ndarray], path: Path) -> None:
    """Write the frames with their masks tinted and outlined, stacked vertically."""
    palette = np.array(
        [[0, 0, 0], [230, 60, 60], [60, 160, 230], [240, 200, 40], [60, 200, 90], [180, 90, 220]],
        np.uint8,
    )
    rows = []
    for k, ids in enumerate(masks):
        rgb = seq.load(k).frame.rgb.copy()
        tint = palette[ids % len(palette)]
        on = ids > 0
        rgb[on] = (0.45 * rgb[on] + 0.55 * tint[on]).astype(np.uint8)
        bgr = cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR)
        cv2.putText(bgr, f"frame {k}", (8, 470), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (0, 0, 0), 2)
        rows.append(bgr)
    grid = [
        np.hstack(rows[i : i + 2]) if i + 1 < len(rows) else np.hstack([rows[i], 0 * rows[i]])
        for i in range(0, len(rows), 2)
    ]
    cv2.imwrite(str(path), np.vstack(grid))


def main(argv: list[str] | None = None) -> int:
    """Build, check and (unless --check-only) write the annotations."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--folder", type=Path, default=BUNDLED)
    parser.add_argument("--overlay", type=Path, default=Path("/tmp/redwood_annotations.png"))
    parser.add_argument("--check-only", action="store_true")
    args = parser.parse_args(argv)
    seq = open_sequence(args.folder)
    masks = build(seq)
    for label, (spread, pixels) in centroid_spread(seq, masks).items():
        print(f"{label:>13}: centroid spread {100 * spread:5.2f} cm over {pixels} pixels")
    overlay(seq, masks, args.overlay)
    print(f"overlay written to {args.overlay}")
    if not args.check_only:
        for source, ids in zip(seq.sources, masks, strict=True):
            write_annotation(args.folder, source.rgb_path.stem, ids, annotation_for(ids))
        print(f"annotations written to {args.folder / 'annotations'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
