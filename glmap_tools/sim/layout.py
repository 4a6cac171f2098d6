"""Scene layouts as data: rooms, openings, objects and regions of one apartment.

World frame: z up, metres. Angles are radians, counter-clockwise from +x. An object stands
at `position` = the centre of its footprint at its base (z = height of its bottom), its front
facing `heading`, with `size` = (width, depth, height). The JSON form is documented in
`glmap_tools/sim/design.md` and read/written by `glmap_tools.sim.layout_io`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np


class LayoutWarning(UserWarning):
    """A layout was accepted after a repair (an object moved off a wall, a mesh replaced)."""


@dataclass(frozen=True)
class Room:
    """A room: a floor polygon (counter-clockwise) with walls of `wall_height` around it."""

    id: int
    type: str
    name: str
    polygon: np.ndarray  # [K, 2] metres, counter-clockwise
    wall_height: float = 2.6
    floor_color: tuple[float, float, float] = (0.6, 0.5, 0.4)
    wall_color: tuple[float, float, float] = (0.9, 0.9, 0.88)

    @property
    def area(self) -> float:
        return abs(polygon_signed_area(self.polygon))

    @property
    def centroid(self) -> np.ndarray:  # [2]
        return polygon_centroid(self.polygon)

    def contains(self, points: np.ndarray) -> np.ndarray:
        """[N] bool: which of the [N, 2] points lie inside the floor polygon."""
        return points_in_polygon(points, self.polygon)


@dataclass(frozen=True)
class Opening:
    """A door or an open passage in the wall between two rooms, centred on their shared wall."""

    id: int
    rooms: tuple[int, int]
    center: np.ndarray  # [2] metres
    width: float = 0.9
    height: float = 2.1
    kind: str = "door"


@dataclass(frozen=True)
class SceneObject:
    """One object instance (the mask id is `id`)."""

    id: int
    category: str
    mesh: str
    position: np.ndarray  # [3] centre of the footprint at the base, metres
    heading: float
    size: np.ndarray  # [3] width, depth, height, metres
    attributes: dict[str, str] = field(default_factory=dict)
    color: tuple[float, float, float] | None = None
    description: str = ""
    room: int = 0
    supported_by: int | None = None

    @property
    def text(self) -> str:
        """The description, else the category."""
        return self.description or self.category

    @property
    def top(self) -> float:
        """Height of the top surface (metres)."""
        return float(self.position[2] + self.size[2])

    @property
    def rotation(self) -> np.ndarray:  # [3, 3]
        """world_from_object rotation: local -y (the front) maps to `heading`."""
        return yaw_matrix(self.heading + math.pi / 2)

    def footprint(self, margin: float = 0.0) -> np.ndarray:  # [4, 2]
        """Corners of the oriented footprint rectangle, grown by `margin` metres."""
        w, d = self.size[0] / 2 + margin, self.size[1] / 2 + margin
        local = np.array([[-w, -d], [w, -d], [w, d], [-w, d]])
        return local @ self.rotation[:2, :2].T + self.position[:2]

    def distance_to(self, points: np.ndarray) -> np.ndarray:
        """[N] planar distances (metres) from [N, 2] points to the footprint (0 inside)."""
        pts = np.atleast_2d(np.asarray(points, dtype=np.float64))
        local = (pts - self.position[:2]) @ self.rotation[:2, :2]
        half = np.asarray(self.size[:2], dtype=np.float64) / 2
        excess = np.maximum(np.abs(local) - half, 0.0)
        return np.sqrt((excess**2).sum(axis=1))


@dataclass(frozen=True)
class Region:
    """A functional group of objects with a description (paper: a region unit)."""

    id: int
    name: str
    description: str
    members: tuple[int, ...]
    room: int = 0


@dataclass(frozen=True)
class Layout:
    """A whole apartment."""

    name: str
    rooms: list[Room]
    openings: list[Opening]
    objects: list[SceneObject]
    regions: list[Region] = field(default_factory=list)
    seed: int | None = None

    def room(self, room_id: int) -> Room:
        return next(r for r in self.rooms if r.id == room_id)

    def object(self, object_id: int) -> SceneObject:
        return next(o for o in self.objects if o.id == object_id)

    @property
    def objects_by_id(self) -> dict[int, SceneObject]:
        return {o.id: o for o in self.objects}

    @property
    def categories(self) -> list[str]:
        """Sorted distinct object categories."""
        return sorted({o.category for o in self.objects})

    def room_at(self, xy: np.ndarray) -> int:
        """Id of the room containing planar point `xy`, or 0 when outside every room."""
        pt = np.asarray(xy, dtype=np.float64).reshape(1, 2)
        for room in self.rooms:
            if room.contains(pt)[0]:
                return room.id
        return 0

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Planar (min [2], max [2]) over all room polygons."""
        pts = np.concatenate([r.polygon for r in self.rooms])
        return pts.min(axis=0), pts.max(axis=0)


def yaw_matrix(angle: float) -> np.ndarray:  # [3, 3]
    """Rotation about +z by `angle` radians."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def polygon_signed_area(polygon: np.ndarray) -> float:
    """Shoelace area of a [K, 2] polygon; positive when counter-clockwise."""
    x, y = polygon[:, 0], polygon[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def polygon_centroid(polygon: np.ndarray) -> np.ndarray:  # [2]
    """Area centroid of a simple [K, 2] polygon."""
    x, y = polygon[:, 0], polygon[:, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    cross = x * yn - xn * y
    a = cross.sum() / 2
    if abs(a) < 1e-12:
        return polygon.mean(axis=0)
    return np.array([((x + xn) * cross).sum(), ((y + yn) * cross).sum()]) / (6 * a)


def points_in_polygon(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """[N] bool: even-odd ray casting of [N, 2] points against a [K, 2] polygon."""
    pts = np.atleast_2d(np.asarray(points, dtype=np.float64))
    px, py = pts[:, 0:1], pts[:, 1:2]
    x0, y0 = polygon[:, 0], polygon[:, 1]
    x1, y1 = np.roll(x0, -1), np.roll(y0, -1)
    crosses = (y0 > py) != (y1 > py)
    with np.errstate(divide="ignore", invalid="ignore"):
        x_at = x0 + (py - y0) * (x1 - x0) / (y1 - y0)
    inside = crosses & (px < x_at)
    return (inside.sum(axis=1) % 2).astype(bool)


def point_segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """Planar distance from point p to segment ab."""
    ab = b - a
    t = float(np.clip(np.dot(p - a, ab) / max(float(np.dot(ab, ab)), 1e-12), 0.0, 1.0))
    return float(np.linalg.norm(p - (a + t * ab)))


def rects_overlap(a: np.ndarray, b: np.ndarray) -> bool:
    """Separating-axis test of two convex quadrilaterals [4, 2] (touching is not overlap)."""
    for poly in (a, b):
        for i in range(4):
            edge = poly[(i + 1) % 4] - poly[i]
            axis = np.array([-edge[1], edge[0]])
            pa, pb = a @ axis, b @ axis
            if pa.max() <= pb.min() + 1e-9 or pb.max() <= pa.min() + 1e-9:
                return False
    return True
