"""Walls, floors and ceilings of a layout; walls are cut where openings are.

Each room's walls stand just inside its polygon (`WALL_THICKNESS` inwards), so two rooms
sharing an edge have back-to-back walls, each in its own colour; an opening cuts both.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from glmap_tools.sim.layout import Layout, Room, point_segment_distance, polygon_signed_area
from glmap_tools.sim.meshes import PlacedPart

WALL_THICKNESS = 0.05  # metres, per room side
ON_WALL_TOLERANCE = 0.15  # metres between an opening centre and a wall's edge


@dataclass(frozen=True)
class WallPiece:
    """An upright oriented box of wall: planar rectangle `corners`, from z0 to z1 (metres)."""

    room: int
    corners: np.ndarray  # [4, 2] counter-clockwise
    z0: float
    z1: float


def _interval_gaps(length: float, cuts: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """Sub-intervals of [0, length] not covered by any cut."""
    pieces, start = [], 0.0
    for a, b in sorted(cuts):
        a, b = max(a, 0.0), min(b, length)
        if a > start + 1e-6:
            pieces.append((start, a))
        start = max(start, b)
    if length > start + 1e-6:
        pieces.append((start, length))
    return pieces


def _rect(a: np.ndarray, u: np.ndarray, n: np.ndarray, s0: float, s1: float) -> np.ndarray:
    p0, p1 = a + u * s0, a + u * s1
    return np.stack([p0, p1, p1 + n * WALL_THICKNESS, p0 + n * WALL_THICKNESS])


def wall_pieces(layout: Layout) -> list[WallPiece]:
    """Every wall box of every room, full height beside openings, lintels above doors."""
    pieces = []
    for room in layout.rooms:
        openings = [o for o in layout.openings if room.id in o.rooms]
        poly = room.polygon
        for i in range(len(poly)):
            a, b = poly[i], poly[(i + 1) % len(poly)]
            length = float(np.linalg.norm(b - a))
            if length < 1e-6:
                continue
            u = (b - a) / length
            n = np.array([-u[1], u[0]])  # inward for a counter-clockwise polygon
            cuts, lintels = [], []
            for o in openings:
                if point_segment_distance(o.center, a, b) > ON_WALL_TOLERANCE:
                    continue
                s = float(np.dot(o.center - a, u))
                cuts.append((s - o.width / 2, s + o.width / 2))
                if o.height < room.wall_height:
                    lintels.append((s - o.width / 2, s + o.width / 2, o.height))
            for s0, s1 in _interval_gaps(length, cuts):
                pieces.append(WallPiece(room.id, _rect(a, u, n, s0, s1), 0.0, room.wall_height))
            for s0, s1, z0 in lintels:
                s0, s1 = max(s0, 0.0), min(s1, length)
                pieces.append(WallPiece(room.id, _rect(a, u, n, s0, s1), z0, room.wall_height))
    return pieces


def triangulate(polygon: np.ndarray) -> np.ndarray:  # [K - 2, 3]
    """Ear-clipping triangulation of a simple counter-clockwise [K, 2] polygon."""
    idx = list(range(len(polygon)))
    tris = []
    guard = 0
    while len(idx) > 3 and guard < 10 * len(polygon) ** 2:
        guard += 1
        for k in range(len(idx)):
            i0, i1, i2 = idx[k - 1], idx[k], idx[(k + 1) % len(idx)]
            p0, p1, p2 = polygon[i0], polygon[i1], polygon[i2]
            if polygon_signed_area(np.stack([p0, p1, p2])) <= 1e-12:
                continue  # reflex or degenerate corner
            others = [polygon[j] for j in idx if j not in (i0, i1, i2)]
            if any(_in_triangle(q, p0, p1, p2) for q in others):
                continue
            tris.append((i0, i1, i2))
            idx.pop(k)
            break
        else:
            break
    if len(idx) == 3:
        tris.append((idx[0], idx[1], idx[2]))
    return np.array(tris, dtype=np.int64).reshape(-1, 3)


def _in_triangle(q: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> bool:
    def side(p1: np.ndarray, p2: np.ndarray) -> float:
        return float((p2[0] - p1[0]) * (q[1] - p1[1]) - (p2[1] - p1[1]) * (q[0] - p1[0]))

    return side(a, b) >= 0 and side(b, c) >= 0 and side(c, a) >= 0


def _piece_mesh(piece: WallPiece) -> tuple[np.ndarray, np.ndarray]:
    c = piece.corners
    vertices = np.concatenate(
        [np.column_stack([c, np.full(4, piece.z0)]), np.column_stack([c, np.full(4, piece.z1)])]
    )
    faces = [(0, 2, 1), (0, 3, 2), (4, 5, 6), (4, 6, 7)]
    for i in range(4):
        j = (i + 1) % 4
        faces += [(i, j, 4 + j), (i, 4 + j, 4 + i)]
    return vertices, np.array(faces, dtype=np.int64)


def floor_and_ceiling(room: Room) -> tuple[PlacedPart, PlacedPart]:
    """The floor (facing up, z = 0) and ceiling (facing down) of a room."""
    tris = triangulate(room.polygon)
    n = len(room.polygon)
    floor = np.column_stack([room.polygon, np.zeros(n)])
    ceiling = np.column_stack([room.polygon, np.full(n, room.wall_height)])
    return (
        PlacedPart(floor, tris, room.floor_color),
        PlacedPart(ceiling, tris[:, ::-1].copy(), (0.96, 0.96, 0.95)),
    )


def room_walls(layout: Layout, pieces: list[WallPiece] | None = None) -> dict[int, PlacedPart]:
    """One wall mesh per room (all its pieces), in the room's wall colour."""
    pieces = wall_pieces(layout) if pieces is None else pieces
    out = {}
    for room in layout.rooms:
        verts, faces, offset = [], [], 0
        for piece in pieces:
            if piece.room != room.id:
                continue
            v, f = _piece_mesh(piece)
            verts.append(v)
            faces.append(f + offset)
            offset += len(v)
        if verts:
            out[room.id] = PlacedPart(np.concatenate(verts), np.concatenate(faces), room.wall_color)
    return out
