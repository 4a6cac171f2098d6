"""Furniture built from trimesh boxes and cylinders, in the catalog's unit frame.

Each builder returns parts (mesh, part name) inside x, y in [-0.5, 0.5], z in [0, 1], the
front facing -y. Part names: "main" takes the object's colour, "frame" its material colour,
"dark" and "light" are fixed near-black and near-white.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import trimesh

Part = tuple[trimesh.Trimesh, str]


def box(lo: tuple[float, float, float], hi: tuple[float, float, float]) -> trimesh.Trimesh:
    """An axis-aligned box from corner `lo` to corner `hi`."""
    lo_a, hi_a = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    transform = np.eye(4)
    transform[:3, 3] = (lo_a + hi_a) / 2
    return trimesh.creation.box(extents=hi_a - lo_a, transform=transform)


def cylinder(
    x: float, y: float, radius: float, z0: float, z1: float, sections: int = 20
) -> trimesh.Trimesh:
    """An upright cylinder with its axis at (x, y) from z0 to z1."""
    transform = np.eye(4)
    transform[:3, 3] = (x, y, (z0 + z1) / 2)
    return trimesh.creation.cylinder(
        radius=radius, height=z1 - z0, sections=sections, transform=transform
    )


def _box_part() -> list[Part]:
    return [(box((-0.5, -0.5, 0), (0.5, 0.5, 1)), "main")]


def _cylinder_part() -> list[Part]:
    return [(cylinder(0, 0, 0.5, 0, 1, sections=24), "main")]


def _sphere_part() -> list[Part]:
    s = trimesh.creation.icosphere(subdivisions=2, radius=0.5)
    s.apply_translation((0, 0, 0.5))
    return [(s, "main")]


def _table() -> list[Part]:
    parts: list[Part] = [(box((-0.5, -0.5, 0.93), (0.5, 0.5, 1.0)), "main")]
    leg = 0.05
    for x in (-0.5 + 0.03, 0.5 - 0.03 - leg):
        for y in (-0.5 + 0.04, 0.5 - 0.04 - leg):
            parts.append((box((x, y, 0), (x + leg, y + leg, 0.93)), "frame"))
    return parts


def _toilet() -> list[Part]:
    return [
        (box((-0.3, -0.1, 0), (0.3, 0.35, 0.45)), "main"),  # pedestal
        (cylinder(0, -0.1, 0.5, 0.35, 0.5, sections=24), "main"),  # bowl
        (cylinder(0, -0.1, 0.42, 0.5, 0.53, sections=24), "light"),  # seat
        (box((-0.5, 0.28, 0.45), (0.5, 0.5, 1.0)), "main"),  # tank
    ]


def _bathtub() -> list[Part]:
    wall = 0.08
    return [
        (box((-0.5, -0.5, 0), (0.5, 0.5, 0.3)), "main"),
        (box((-0.5, -0.5, 0.3), (-0.5 + wall, 0.5, 1)), "main"),
        (box((0.5 - wall, -0.5, 0.3), (0.5, 0.5, 1)), "main"),
        (box((-0.5, -0.5, 0.3), (0.5, -0.5 + wall / 2, 1)), "main"),
        (box((-0.5, 0.5 - wall / 2, 0.3), (0.5, 0.5, 1)), "main"),
        (box((-0.45, -0.45, 0.3), (0.45, 0.45, 0.35)), "light"),
    ]


def _stove() -> list[Part]:
    parts: list[Part] = [
        (box((-0.5, -0.5, 0), (0.5, 0.5, 0.96)), "main"),
        (box((-0.5, -0.5, 0.96), (0.5, 0.5, 1.0)), "dark"),
        (box((-0.4, -0.52, 0.25), (0.4, -0.5, 0.75)), "dark"),  # oven window
    ]
    for x in (-0.25, 0.25):
        for y in (-0.22, 0.22):
            parts.append((cylinder(x, y, 0.17, 1.0, 1.02), "frame"))
    return parts


def _tv() -> list[Part]:
    return [
        (box((-0.5, -0.06, 0.25), (0.5, 0.06, 1.0)), "main"),  # housing
        (box((-0.47, -0.08, 0.28), (0.47, -0.06, 0.97)), "dark"),  # screen
        (box((-0.04, -0.03, 0.05), (0.04, 0.05, 0.25)), "main"),  # neck
        (box((-0.3, -0.5, 0), (0.3, 0.5, 0.05)), "main"),  # foot
    ]


def _picture() -> list[Part]:
    return [
        (box((-0.5, -0.5, 0), (0.5, 0.5, 1)), "frame"),
        (box((-0.42, -0.55, 0.1), (0.42, -0.5, 0.9)), "main"),
    ]


def _wardrobe() -> list[Part]:
    return [
        (box((-0.5, -0.48, 0), (0.5, 0.5, 1)), "main"),
        (box((-0.005, -0.5, 0.03), (0.005, -0.48, 0.97)), "dark"),
        (box((-0.06, -0.53, 0.45), (-0.03, -0.48, 0.6)), "frame"),
        (box((0.03, -0.53, 0.45), (0.06, -0.48, 0.6)), "frame"),
    ]


def _washer() -> list[Part]:
    door = cylinder(0, 0, 0.32, 0, 0.04, sections=24)
    door.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, (1, 0, 0)))
    door.apply_translation((0, -0.5, 0.45))
    return [(box((-0.5, -0.5, 0), (0.5, 0.5, 1)), "main"), (door, "dark")]


def _dresser() -> list[Part]:
    parts: list[Part] = [(box((-0.5, -0.48, 0.05), (0.5, 0.5, 1)), "main")]
    parts.append((box((-0.48, -0.46, 0), (0.48, 0.48, 0.05)), "frame"))
    for z in (0.3, 0.6, 0.9):
        parts.append((box((-0.48, -0.5, z - 0.01), (0.48, -0.48, z + 0.01)), "dark"))
        parts.append((box((-0.08, -0.54, z - 0.14), (0.08, -0.48, z - 0.1)), "frame"))
    return parts


def _shelf() -> list[Part]:
    return [(box((-0.5, -0.5, 0), (0.5, 0.5, 1)), "main")]


BUILDERS: dict[str, Callable[[], list[Part]]] = {
    "box": _box_part,
    "cylinder": _cylinder_part,
    "sphere": _sphere_part,
    "table": _table,
    "toilet": _toilet,
    "bathtub": _bathtub,
    "stove": _stove,
    "tv": _tv,
    "picture": _picture,
    "wardrobe": _wardrobe,
    "washer": _washer,
    "dresser": _dresser,
    "shelf": _shelf,
}
