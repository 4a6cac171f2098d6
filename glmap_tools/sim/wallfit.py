"""Objects whose footprint crosses a wall of their room are moved inside, with a warning.

Walls stand inside each room polygon (`WALL_THICKNESS` deep). A footprint crosses a wall when
one of its corners lies less than that from a polygon edge, or outside the polygon; scanned
boxes do this often (a bed box reaching 10 cm into the wall). Such an object is pushed along
the inward normals of the walls it crosses, by the least amount that clears them (a few
rounds, for corners). A push longer than `MAX_WALL_SHIFT`, or an object that no push fits
into its room (wider than the room), is refused: the layout is wrong, not noisy.
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.sim.architecture import WALL_THICKNESS
from glmap_tools.sim.layout import LayoutWarning, Room, SceneObject, point_segment_distance

MAX_WALL_SHIFT = 0.5  # metres an object may be moved to get it off a wall
TOLERANCE = 0.005  # metres of wall overlap that are let pass
ROUNDS = 4


def _edges(polygon: np.ndarray) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """(start [2], end [2], inward unit normal [2]) of each edge of a CCW polygon."""
    out = []
    for i in range(len(polygon)):
        a, b = polygon[i], polygon[(i + 1) % len(polygon)]
        d = (b - a) / max(float(np.linalg.norm(b - a)), 1e-12)
        out.append((a, b, np.array([-d[1], d[0]])))
    return out


def wall_push(room: Room, corners: np.ndarray) -> np.ndarray:
    """[2] the shift that takes footprint `corners` [4, 2] clear of the room's walls.

    Each wall the footprint reaches into contributes its deepest corner's penetration along
    its inward normal; only corners near the wall segment count (not its extended line).
    """
    push = np.zeros(2)
    reach = WALL_THICKNESS + MAX_WALL_SHIFT
    for a, b, n in _edges(room.polygon):
        depth = 0.0
        for p in corners:
            if point_segment_distance(p, a, b) > reach:
                continue
            depth = max(depth, WALL_THICKNESS - float(np.dot(p - a, n)))
        if depth > TOLERANCE:
            push += n * depth
    return push


def clears_walls(room: Room, corners: np.ndarray) -> bool:
    """Whether every corner is inside the room and at least a wall's thickness from its edges."""
    if not room.contains(corners).all():
        return False
    return all(
        point_segment_distance(p, a, b) >= WALL_THICKNESS - TOLERANCE
        for p in corners
        for a, b, _ in _edges(room.polygon)
    )


def fit_inside_room(obj: SceneObject, room: Room, where: str = "") -> SceneObject:
    """`obj`, moved off the walls of `room` when its footprint crosses one (with a warning).

    Raises:
        InvalidInputError: the object needs a longer move than `MAX_WALL_SHIFT`, or does not
            fit between the room's walls at all.
    """
    corners = obj.footprint()
    if clears_walls(room, corners):
        return obj
    total = np.zeros(2)
    for _ in range(ROUNDS):
        push = wall_push(room, corners + total)
        if not push.any():
            break
        total += push
    shift = float(np.linalg.norm(total))
    label = f"{where} (object {obj.id}, {obj.category!r})" if where else f"object {obj.id}"
    if shift > MAX_WALL_SHIFT or not clears_walls(room, corners + total):
        raise InvalidInputError(
            f"{label} crosses a wall of room {room.id} ({room.name!r}) and moving it "
            f"{shift:.2f} m (at most {MAX_WALL_SHIFT} m) does not clear the walls; fix its "
            "position or size, or the room polygon."
        )
    warnings.warn(
        f"{label} crossed a wall of room {room.id} ({room.name!r}); moved {shift:.2f} m "
        f"by ({total[0]:+.2f}, {total[1]:+.2f}) to clear it.",
        LayoutWarning,
        stacklevel=3,
    )
    position = obj.position.copy()
    position[:2] += total
    return dataclasses.replace(obj, position=position)
