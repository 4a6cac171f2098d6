"""Real-room scans of our own (issue 40), written from object lists we describe ourselves:
a living room + kitchen flat (axis-aligned, turned -27 deg as a scanner's axis-aligned boxes,
turned 27 deg with each box's own rotation), a dining room whose vase stands in the middle of
a wide table, and a bedroom turned 27 deg with two bedside lamps and a ceiling light. Each
scan is what a scanner gives: category + oriented box, no descriptions.

    python -m tests.realscan_rooms OUT      # writes OUT/<scene>.json for glmap sim from-scan
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np

# (category, x, y in the room's frame, width, depth, height, bottom z, extra turn in deg)
Furniture = list[tuple[str, float, float, float, float, float, float, float]]

LIVING = [
    ("sofa", 3.0, 0.55, 2.0, 0.9, 0.85, 0.0, 0.0),
    ("coffee table", 3.0, 1.7, 1.0, 0.55, 0.45, 0.0, 0.0),
    ("tv stand", 3.0, 3.7, 1.6, 0.45, 0.5, 0.0, 0.0),
    ("tv", 3.0, 3.75, 1.2, 0.1, 0.7, 0.5, 0.0),
    ("armchair", 0.7, 2.2, 0.8, 0.8, 0.9, 0.0, 90.0),
    ("side table", 1.5, 0.45, 0.45, 0.45, 0.55, 0.0, 0.0),
    ("lamp", 1.5, 0.45, 0.3, 0.3, 0.5, 0.55, 0.0),
    ("side table", 4.5, 0.45, 0.45, 0.45, 0.55, 0.0, 0.0),
    ("lamp", 4.5, 0.45, 0.3, 0.3, 0.5, 0.55, 0.0),
    ("lamp", 3.0, 2.0, 0.5, 0.5, 0.15, 2.5, 0.0),  # a ceiling light
    ("plant", 5.6, 3.6, 0.5, 0.5, 1.1, 0.0, 0.0),
    ("picture", 3.0, 0.07, 1.0, 0.03, 0.6, 1.3, 0.0),
    ("bookshelf", 0.3, 3.4, 0.9, 0.35, 1.8, 0.0, 90.0),
]
KITCHEN = [  # x from 6 to 10
    ("counter", 8.0, 3.7, 3.0, 0.6, 0.9, 0.0, 0.0),
    ("sink", 8.0, 3.7, 0.6, 0.45, 0.2, 0.9, 0.0),
    ("refrigerator", 9.6, 2.2, 0.7, 0.7, 1.8, 0.0, 90.0),
    ("table", 7.9, 1.4, 1.2, 0.8, 0.75, 0.0, 0.0),
    ("chair", 7.4, 0.7, 0.45, 0.5, 0.9, 0.0, 0.0),
    ("chair", 8.4, 0.7, 0.45, 0.5, 0.9, 0.0, 0.0),
    ("trash can", 6.4, 3.7, 0.35, 0.35, 0.6, 0.0, 0.0),
    ("clock", 8.0, 0.07, 0.3, 0.05, 0.3, 1.9, 0.0),
]
ROOMS = [
    ("living room", [(0, 0), (6, 0), (6, 4), (0, 4)]),
    ("kitchen", [(6, 0), (10, 0), (10, 4), (6, 4)]),
]
OPENING = (6.0, 2.0, 0.9)


DINING = [
    ("table", 3.0, 2.5, 2.0, 1.2, 0.75, 0.0, 0.0),
    ("vase", 3.0, 2.5, 0.15, 0.15, 0.3, 0.75, 0.0),
    ("chair", 1.65, 2.5, 0.45, 0.5, 0.9, 0.0, 90.0),
    ("chair", 4.35, 2.5, 0.45, 0.5, 0.9, 0.0, 90.0),
    ("sideboard", 3.0, 4.7, 1.8, 0.45, 0.8, 0.0, 0.0),
    ("picture", 3.0, 4.93, 0.9, 0.03, 0.6, 1.4, 0.0),
    ("plant", 0.4, 0.4, 0.5, 0.5, 1.2, 0.0, 0.0),
    ("lamp", 3.0, 2.5, 0.6, 0.6, 0.2, 2.4, 0.0),
    ("cabinet", 5.6, 1.0, 0.5, 1.0, 1.0, 0.0, 0.0),
]
BEDROOM = [
    ("bed", 2.5, 3.9, 1.6, 2.0, 0.55, 0.0, 0.0),
    ("nightstand", 1.4, 4.65, 0.45, 0.4, 0.55, 0.0, 0.0),
    ("nightstand", 3.6, 4.65, 0.45, 0.4, 0.55, 0.0, 0.0),
    ("lamp", 1.4, 4.65, 0.25, 0.25, 0.45, 0.55, 0.0),
    ("lamp", 3.6, 4.65, 0.25, 0.25, 0.45, 0.55, 0.0),
    ("lamp", 2.5, 2.5, 0.5, 0.5, 0.15, 2.5, 0.0),
    ("wardrobe", 4.65, 1.5, 1.2, 0.6, 2.0, 0.0, 90.0),
    ("desk", 0.45, 1.2, 1.2, 0.7, 0.75, 0.0, 90.0),
    ("chair", 1.1, 1.2, 0.45, 0.5, 0.9, 0.0, 90.0),
    ("picture", 2.5, 4.93, 1.0, 0.03, 0.7, 1.2, 0.0),
]


def _rot2(deg: float) -> np.ndarray:
    a = math.radians(deg)
    return np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])


def _objects(furniture: Furniture, deg: float, boxes: str) -> list[dict]:
    """Scan objects of `furniture` in a frame turned by `deg`. `boxes`: 'own' (each box its
    own rotation matrix) or 'aabb' (a scanner's axis-aligned bounding boxes, identity
    rotations)."""
    rot = _rot2(deg)
    c, s = abs(math.cos(math.radians(deg))), abs(math.sin(math.radians(deg)))
    out = []
    for i, (cat, x, y, w, d, h, z, extra) in enumerate(furniture, start=1):
        cx, cy = (round(float(v), 4) for v in rot @ np.array([x, y]))
        r = np.eye(3)
        if boxes == "own":
            r[:2, :2] = _rot2(deg + extra)
            size = [w, d, h]
        else:
            sx, sy = (d, w) if extra % 180 else (w, d)
            size = [round(sx * c + sy * s, 4), round(sx * s + sy * c, 4), h]
        out.append({"id": i, "category": cat, "center": [cx, cy, z + h / 2], "size": size,
                    "rotation": r.tolist()})  # fmt: skip
    return out


def _polygon(points: list[tuple[float, float]], deg: float) -> list[list[float]]:
    rot = _rot2(deg)
    return [[round(float(v), 4) for v in rot @ np.array(p)] for p in points]


def flat(name: str, deg: float, boxes: str) -> dict:
    """The living room + kitchen flat, 10 m x 4 m, a 0.9 m opening between the rooms."""
    rooms = [{"type": t, "polygon": _polygon(poly, deg)} for t, poly in ROOMS]
    centre = _polygon([OPENING[:2]], deg)[0]
    openings = [{"id": 1, "rooms": [1, 2], "center": centre, "width": OPENING[2]}]
    objects = _objects(LIVING + KITCHEN, deg, boxes)
    return {"up": "z", "name": name, "rooms": rooms, "openings": openings, "objects": objects}


def one_room(
    name: str, deg: float, furniture: Furniture, size: tuple[float, float], kind: str
) -> dict:
    w, d = size
    room = {"type": kind, "polygon": _polygon([(0, 0), (w, 0), (w, d), (0, d)], deg)}
    return {"up": "z", "name": name, "room": room, "objects": _objects(furniture, deg, "own")}


def scans() -> dict[str, dict]:
    """Scene name -> scan JSON object."""
    return {
        "flat": flat("flat", 0.0, "aabb"),
        "flat27own": flat("flat27own", 27.0, "own"),
        "flat27aabb": flat("flat27aabb", -27.0, "aabb"),
        "dining": one_room("dining", 0.0, DINING, (6.0, 5.0), "dining room"),
        "bedroom27": one_room("bedroom27", 27.0, BEDROOM, (5.0, 5.0), "bedroom"),
    }


def write_scans(out: Path) -> list[Path]:
    """Write every scan to `out`/<scene>.json."""
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, data in scans().items():
        path = out / f"{name}.json"
        path.write_text(json.dumps(data), encoding="utf-8")
        paths.append(path)
    return paths


if __name__ == "__main__":
    for p in write_scans(Path(sys.argv[1])):
        print(p)
