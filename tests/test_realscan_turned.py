"""`from-scan` on a room turned 27 deg (issue 40): boxes given as rotations (a scanner's
axis-aligned boxes as identity matrices, or each object's own turn), a thin picture on a
turned wall, and a refusal that says when the turned-room fix was skipped.

The bedroom is our own: a 5 m x 4 m room with a bed, two nightstands, a wardrobe, a desk
and its chair, a lamp and a picture above the bed.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from glmap_tools.errors import InvalidInputError
from glmap_tools.sim.layout import LayoutWarning
from glmap_tools.worlds.scan import box_in_room_frame, layout_from_scan

# (category, x, y in the room's frame, width, depth, height, bottom z, extra turn in deg)
BEDROOM = [
    ("bed", 2.5, 1.1, 1.6, 2.0, 0.5, 0.0, 90.0),
    ("nightstand", 1.35, 0.3, 0.45, 0.4, 0.55, 0.0, 0.0),
    ("nightstand", 3.65, 0.3, 0.45, 0.4, 0.55, 0.0, 0.0),
    ("table lamp", 1.35, 0.3, 0.25, 0.25, 0.45, 0.55, 0.0),
    ("wardrobe", 4.6, 2.6, 1.2, 0.6, 2.0, 0.0, 90.0),
    ("desk", 1.0, 3.6, 1.2, 0.6, 0.75, 0.0, 0.0),
    ("chair", 1.0, 3.0, 0.45, 0.5, 0.9, 0.0, 0.0),
    ("picture", 2.5, 0.08, 1.0, 0.03, 0.7, 1.2, 0.0),  # on the wall behind the bed
]
ROOM = [(0.0, 0.0), (5.0, 0.0), (5.0, 4.0), (0.0, 4.0)]


def _rot(deg: float) -> np.ndarray:
    a = math.radians(deg)
    return np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])


def turned_bedroom(deg: float, boxes: str) -> dict:
    """The bedroom turned by `deg`. `boxes`: 'aabb' (every box an axis-aligned bounding box
    given as an identity rotation, as a scanner gives it), 'own' (each box its own turn as a
    rotation matrix, the picture an axis-aligned box)."""
    rot = _rot(deg)
    objects = []
    for i, (cat, x, y, w, d, h, z, extra) in enumerate(BEDROOM, start=1):
        cx, cy = rot @ np.array([x, y])
        turn = deg + extra
        box_w, box_d = (d, w) if extra % 180 else (w, d)  # the box's own x and y sides
        if boxes == "aabb" or cat == "picture":
            c, s = abs(math.cos(math.radians(deg))), abs(math.sin(math.radians(deg)))
            size = [box_w * c + box_d * s, box_w * s + box_d * c, h]
            r = np.eye(3)
        else:
            size = [w, d, h]
            r = np.eye(3)
            r[:2, :2] = _rot(turn)
        objects.append(
            {"id": i, "category": cat, "center": [round(float(cx), 4), round(float(cy), 4),
             z + h / 2], "size": [round(v, 4) for v in size], "rotation": r.tolist()}
        )  # fmt: skip
    polygon = [[round(float(v), 4) for v in rot @ np.array(p)] for p in ROOM]
    return {"up": "z", "name": f"bedroom-{deg:g}", "room": {"type": "bedroom",
            "polygon": polygon}, "objects": objects}  # fmt: skip


def _load(scan: dict):  # type: ignore[no-untyped-def]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LayoutWarning)
        return layout_from_scan(scan, use_meshes=False)


@pytest.mark.parametrize("boxes", ["aabb", "own"])
def test_a_room_turned_27_degrees_converts_with_its_boxes_square_to_the_walls(boxes: str) -> None:
    layout = _load(turned_bedroom(27.0, boxes))
    assert len(layout.objects) == len(BEDROOM)
    for obj, (cat, _x, _y, w, d, *_rest) in zip(layout.objects, BEDROOM, strict=True):
        assert obj.category == cat and obj.room == 1
        # Square to the walls: the box's yaw is the room's, up to quarter turns.
        off = (math.degrees(obj.heading + math.pi / 2) - 27.0 + 45.0) % 90.0 - 45.0
        assert abs(off) < 0.5, (cat, math.degrees(obj.heading))
        assert sorted(obj.size[:2]) == pytest.approx(sorted([w, max(d, 0.05)]), abs=0.03)
    picture = layout.objects[-1]
    assert min(picture.size[:2]) == pytest.approx(0.05)  # read as a thin box on the wall
    assert picture.position[2] == pytest.approx(1.2)


def test_a_thin_box_on_a_turned_wall_is_found_inside_its_bounding_box() -> None:
    a = math.radians(27.0)
    c, s = math.cos(a), math.sin(a)
    bbox = np.array([1.0 * c + 0.03 * s, 1.0 * s + 0.03 * c])
    box = box_in_room_frame(bbox, a)
    assert box is not None
    assert box == pytest.approx([0.98, 0.05], abs=0.02)
    # The scan's noise (2 cm on the bounding box) leaves a negative depth: still found.
    noisy = box_in_room_frame(bbox - [0.0, 0.02], a)
    assert noisy is not None and noisy[1] == pytest.approx(0.05)
    # A bounding box no thin turned box comes near is refused.
    assert box_in_room_frame(np.array([1.0, 0.02]), a) is None


def test_when_the_turned_room_fix_is_skipped_the_refusal_says_so() -> None:
    scan = turned_bedroom(44.0, "aabb")  # near 45 deg: a box cannot be told from its bbox
    with pytest.raises(InvalidInputError) as info:
        _load(scan)
    said = str(info.value)
    assert "crosses a wall" in said
    assert "The turned-room fix" in said and "was skipped for object" in said
    assert "walls near 45 deg" in said
