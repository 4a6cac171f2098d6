"""The navigable occupancy grid of a layout and geodesic distances on it.

A cell is navigable when its centre is on a floor (or in an opening) and farther than the
agent radius from every wall and obstacle. Obstacles are object footprints (oriented boxes)
of objects that stand below `OBSTACLE_MAX_BASE` and rise above `OBSTACLE_MIN_TOP` (a picture
on the wall is not in the way), except flat floor coverings: an object whose category names
one (`FLAT_WORDS`: rug, carpet, mat, doormat, ...), that lies on the floor and is lower than
`FLAT_MAX_HEIGHT` is walked over. Scanned rugs come out 7-15 cm high (their boxes take in
the floor's noise), so a height rule alone would block them or let low boxes through.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from glmap_tools.errors import InvalidInputError
from glmap_tools.sim.architecture import WALL_THICKNESS, WallPiece, wall_pieces
from glmap_tools.sim.geodesic import geodesic_distance
from glmap_tools.sim.layout import Layout, Room, SceneObject, point_segment_distance

DEFAULT_CELL = 0.05  # metres
AGENT_RADIUS = 0.18  # metres
OBSTACLE_MAX_BASE = 1.5  # metres: objects starting higher do not block the agent
OBSTACLE_MIN_TOP = 0.05  # metres: flatter objects of any kind do not block the agent
FLAT_MAX_HEIGHT = 0.2  # metres: floor coverings lower than this are walked over
FLAT_BASE = 0.05  # metres: a floor covering's base is at most this high
MIN_PASSAGE_CELLS = 3  # navigable cells across the narrowest passage an episode may need
FLAT_WORDS = frozenset(
    {"rug", "rugs", "carpet", "carpets", "mat", "mats", "doormat", "doormats", "bathmat", "runner"}
)


def is_flat(obj: SceneObject) -> bool:
    """Whether the object is a floor covering the agent walks over (see the module doc)."""
    words = set(re.split(r"[\s_\-/]+", obj.category.lower()))
    return (
        bool(words & FLAT_WORDS)
        and obj.position[2] <= FLAT_BASE
        and obj.top - obj.position[2] < FLAT_MAX_HEIGHT
    )


def is_obstacle(obj: SceneObject) -> bool:
    """Whether the object blocks an agent walking on the floor."""
    return obj.position[2] < OBSTACLE_MAX_BASE and obj.top > OBSTACLE_MIN_TOP and not is_flat(obj)


@dataclass
class NavGrid:
    """A planar grid over the layout; `navigable[i, j]` is the cell at x = x0 + (j + 0.5) cell.

    Attributes:
        origin: [2] world (x, y) of the grid's lower-left corner.
        cell: cell side, metres.
        free: [H, W] bool, floor not covered by walls or obstacles (ignoring the agent size).
        navigable: [H, W] bool, where the agent centre may be (free, eroded by the radius,
            restricted to the largest connected component).
        walls: [H, W] bool wall cells (pieces below `OBSTACLE_MAX_BASE`; doorways open), or
            None for a grid built without a layout.
    """

    origin: np.ndarray  # [2]
    cell: float
    free: np.ndarray  # [H, W]
    navigable: np.ndarray  # [H, W]
    agent_radius: float
    walls: np.ndarray | None = None  # [H, W]

    @property
    def shape(self) -> tuple[int, int]:
        return (int(self.navigable.shape[0]), int(self.navigable.shape[1]))

    def to_cell(self, xy: np.ndarray) -> np.ndarray:
        """[N, 2] int (row, col) of [N, 2] world points (may be out of the grid)."""
        pts = np.atleast_2d(np.asarray(xy, dtype=np.float64))
        col = np.floor((pts[:, 0] - self.origin[0]) / self.cell).astype(np.int64)
        row = np.floor((pts[:, 1] - self.origin[1]) / self.cell).astype(np.int64)
        return np.stack([row, col], axis=1)

    def to_world(self, cells: np.ndarray) -> np.ndarray:
        """[N, 2] world (x, y) of cell centres given as [N, 2] (row, col)."""
        rc = np.atleast_2d(np.asarray(cells, dtype=np.float64))
        return np.stack(
            [
                self.origin[0] + (rc[:, 1] + 0.5) * self.cell,
                self.origin[1] + (rc[:, 0] + 0.5) * self.cell,
            ],
            axis=1,
        )

    def cell_of(self, x: float, y: float) -> tuple[int, int]:
        """(row, col) of one world point (scalar fast path of `to_cell`)."""
        return (
            math.floor((y - self.origin[1]) / self.cell),
            math.floor((x - self.origin[0]) / self.cell),
        )

    def navigable_at(self, x: float, y: float) -> bool:
        """Whether one world point is navigable (scalar fast path of `is_navigable`)."""
        r, c = self.cell_of(x, y)
        h, w = self.navigable.shape
        return bool(0 <= r < h and 0 <= c < w and self.navigable[r, c])

    def is_navigable(self, xy: np.ndarray) -> np.ndarray:
        """[N] bool for [N, 2] world points (False outside the grid)."""
        rc = self.to_cell(xy)
        h, w = self.shape
        inside = (rc[:, 0] >= 0) & (rc[:, 0] < h) & (rc[:, 1] >= 0) & (rc[:, 1] < w)
        out = np.zeros(len(rc), dtype=bool)
        out[inside] = self.navigable[rc[inside, 0], rc[inside, 1]]
        return out

    def cell_centers(self) -> tuple[np.ndarray, np.ndarray]:
        """World x [H, W] and y [H, W] of every cell centre."""
        h, w = self.shape
        xs = self.origin[0] + (np.arange(w) + 0.5) * self.cell
        ys = self.origin[1] + (np.arange(h) + 0.5) * self.cell
        return np.meshgrid(xs, ys)

    def distance_field(self, sources: np.ndarray) -> np.ndarray:
        """[H, W] geodesic metres from the [H, W] bool `sources` over navigable cells."""
        return geodesic_distance(self.navigable, sources & self.navigable, self.cell)

    def passable_parts(self, width: int = MIN_PASSAGE_CELLS) -> np.ndarray:
        """[H, W] int labels of the navigable space with passages under `width` cells closed.

        A binary opening with a `width` x `width` square keeps every navigable cell that lies
        in such a square and drops slivers narrower than it; the rest is labelled in
        4-connected parts (0: dropped). An agent with 30 deg turns and 0.25 m steps cannot
        follow a one-cell (5 cm) sliver of centre positions, so two places joined only by
        one are apart for it.
        """
        square = np.ones((width, width), dtype=bool)
        opened = ndimage.binary_opening(self.navigable, structure=square)
        labels, _ = ndimage.label(opened)
        return np.asarray(labels)

    def segment_is_free(self, a: np.ndarray, b: np.ndarray, step: float | None = None) -> bool:
        """Whether every point of the straight segment a-b is navigable."""
        step = step or self.cell / 2
        n = max(2, int(math.ceil(float(np.linalg.norm(b - a)) / step)) + 1)
        t = np.linspace(0.0, 1.0, n)[:, None]
        return bool(self.is_navigable(a[None] + t * (b - a)[None]).all())


def _fill_rect(
    mask: np.ndarray, xs: np.ndarray, ys: np.ndarray, corners: np.ndarray, value: bool
) -> None:
    """Set cells whose centres fall in the convex quadrilateral `corners` [4, 2]."""
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    cols = np.nonzero((xs >= lo[0]) & (xs <= hi[0]))[0]
    rows = np.nonzero((ys >= lo[1]) & (ys <= hi[1]))[0]
    if len(cols) == 0 or len(rows) == 0:
        return
    gx, gy = np.meshgrid(xs[cols], ys[rows])
    inside = np.ones(gx.shape, dtype=bool)
    for i in range(4):
        a, b = corners[i], corners[(i + 1) % 4]
        inside &= (b[0] - a[0]) * (gy - a[1]) - (b[1] - a[1]) * (gx - a[0]) >= -1e-9
    sub = mask[rows[0] : rows[-1] + 1, cols[0] : cols[-1] + 1]
    sub[inside] = value


def _ccw(corners: np.ndarray) -> np.ndarray:
    x, y = corners[:, 0], corners[:, 1]
    area = float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))
    return corners if area >= 0 else corners[::-1]


def build_nav_grid(
    layout: Layout,
    cell: float = DEFAULT_CELL,
    agent_radius: float = AGENT_RADIUS,
    pieces: list[WallPiece] | None = None,
) -> NavGrid:
    """Rasterise floors, openings, walls and obstacles, and erode by the agent radius."""
    if not (0.005 <= cell <= 0.5):
        raise InvalidInputError(f"grid cell {cell!r} m must be in [0.005, 0.5] metres.")
    if not (0.0 < agent_radius < 2.0):
        raise InvalidInputError(f"agent radius {agent_radius!r} m must be in (0, 2) metres.")
    lo, hi = layout.bounds()
    origin = lo - 0.5
    w = int(math.ceil((hi[0] - origin[0] + 0.5) / cell))
    h = int(math.ceil((hi[1] - origin[1] + 0.5) / cell))
    xs = origin[0] + (np.arange(w) + 0.5) * cell
    ys = origin[1] + (np.arange(h) + 0.5) * cell
    gx, gy = np.meshgrid(xs, ys)
    pts = np.column_stack([gx.ravel(), gy.ravel()])
    free = np.zeros((h, w), dtype=bool)
    for room in layout.rooms:
        free |= room.contains(pts).reshape(h, w)
    for opening in layout.openings:
        a, b = (layout.room(r) for r in opening.rooms)
        axis = b.centroid - a.centroid
        # The opening's passage: its width along the wall, both wall thicknesses across it.
        along = _wall_direction(layout, opening.center, a)
        across = np.array([-along[1], along[0]])
        if np.dot(across, axis) < 0:
            across = -across
        half_w, half_t = opening.width / 2, 2 * WALL_THICKNESS + cell
        c = opening.center
        corners = np.stack(
            [
                c - along * half_w - across * half_t,
                c + along * half_w - across * half_t,
                c + along * half_w + across * half_t,
                c - along * half_w + across * half_t,
            ]
        )
        _fill_rect(free, xs, ys, _ccw(corners), True)
    walls = np.zeros((h, w), dtype=bool)
    for piece in wall_pieces(layout) if pieces is None else pieces:
        if piece.z0 < OBSTACLE_MAX_BASE:
            _fill_rect(walls, xs, ys, _ccw(piece.corners), True)
    free &= ~walls
    for obj in layout.objects:
        if is_obstacle(obj):
            _fill_rect(free, xs, ys, _ccw(obj.footprint()), False)
    clearance = ndimage.distance_transform_edt(free) * cell
    # A cell centre is safe when its nearest blocked cell's edge is beyond the radius.
    navigable = clearance - cell / 2 >= agent_radius - 1e-9
    labels, n = ndimage.label(navigable, structure=np.ones((3, 3)))
    if n > 1:
        sizes = ndimage.sum(navigable, labels, index=np.arange(1, n + 1))
        navigable = labels == (1 + int(np.argmax(sizes)))
    return NavGrid(origin, cell, free, navigable, agent_radius, walls)


def _wall_direction(layout: Layout, center: np.ndarray, room: Room) -> np.ndarray:
    poly = room.polygon
    best = min(
        range(len(poly)),
        key=lambda i: point_segment_distance(center, poly[i], poly[(i + 1) % len(poly)]),
    )
    d = poly[(best + 1) % len(poly)] - poly[best]
    return d / max(float(np.linalg.norm(d)), 1e-12)
