"""Occupancy layer on the index-grid cells: seen-free, obstacle or unknown.

Updated from every frame's full depth image: points in a height band above the floor mark
obstacles; floor points, and 2D rays from the camera up to the nearest obstacle in each
bearing (as a planar laser scan would see it), mark free space. Stored sparsely in
64x64-cell chunks of hit counters, so the map stays unbounded and a store commit writes
only the chunks a frame touched.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

UNKNOWN, FREE, OBSTACLE = 0, 1, 2
CHUNK = 64
# An obstacle cell stays an obstacle unless free observations outnumber it this many times.
FREE_OVERRULES_OBSTACLE = 5


@dataclass(frozen=True)
class DenseOccupancy:
    """A dense window of the occupancy layer.

    Attributes:
        state: [H, W] int8 of UNKNOWN/FREE/OBSTACLE; row = y cell, column = x cell.
        origin: (i0, j0) integer cell of state[0, 0] (x index, y index).
        cell_size: metres per cell.
    """

    state: np.ndarray  # [H, W]
    origin: tuple[int, int]
    cell_size: float

    def world_to_index(self, x: float, y: float) -> tuple[int, int]:
        """(row, col) of the cell containing world (x, y); may fall outside the window."""
        return (
            int(np.floor(y / self.cell_size)) - self.origin[1],
            int(np.floor(x / self.cell_size)) - self.origin[0],
        )

    def index_to_world(self, row: int, col: int) -> tuple[float, float]:
        """World (x, y) of a cell centre."""
        return (
            (col + self.origin[0] + 0.5) * self.cell_size,
            (row + self.origin[1] + 0.5) * self.cell_size,
        )


class OccupancyGrid:
    """Counts of free and obstacle observations per cell, in sparse chunks."""

    def __init__(self, cell_size: float = 0.05) -> None:
        self.cell_size = float(cell_size)
        self.chunks: dict[tuple[int, int], np.ndarray] = {}  # key -> [2, CHUNK, CHUNK] int32

    def copy(self) -> OccupancyGrid:
        other = OccupancyGrid(self.cell_size)
        other.chunks = {k: v.copy() for k, v in self.chunks.items()}
        return other

    def compute_update(
        self,
        camera_xy: np.ndarray,
        points: np.ndarray,
        floor_z: float,
        obstacle_band: tuple[float, float],
    ) -> dict[tuple[int, int], np.ndarray]:
        """Updated copies of the chunks one frame touches; `apply` makes them current.

        Args:
            camera_xy: [2] camera position (m).
            points: [N, 3] world points of the frame's valid depth.
            floor_z: floor height (m).
            obstacle_band: heights above the floor (m) whose points are obstacles.

        Each cell counts at most one observation per frame, obstacle before free.
        """
        from glmap_tools.map._occupancy_numba import MARK_BLOCKED, MARK_FREE, mark_cells

        out: dict[tuple[int, int], np.ndarray] = {}
        if len(points) == 0:
            return out
        h = points[:, 2] - floor_z
        obstacle = (h >= obstacle_band[0]) & (h <= obstacle_band[1])
        floor = np.abs(h) < obstacle_band[0]
        xy = np.ascontiguousarray(points[:, :2], dtype=np.float64)
        delta = xy - camera_xy[None, :]
        dist = np.hypot(delta[:, 0], delta[:, 1])
        bearing = np.floor(np.arctan2(delta[:, 1], delta[:, 0]) / BEARING_BIN).astype(np.int64)
        b0 = bearing.min()
        angle = (np.arange(int(bearing.max() - b0 + 1)) + b0 + 0.5) * BEARING_BIN
        marks, x0, y0 = mark_cells(
            np.ascontiguousarray(camera_xy, np.float64), xy, floor, obstacle, dist, bearing - b0,
            np.cos(angle), np.sin(angle), self.cell_size,
        )  # fmt: skip
        x0, y0 = int(x0), int(y0)
        x1, y1 = x0 + marks.shape[1], y0 + marks.shape[0]  # past the last marked cell
        parts = {}  # chunk -> (its rows and columns the marks cover, those marks)
        for kx in range(x0 // CHUNK, (x1 - 1) // CHUNK + 1):
            cx = slice(max(kx * CHUNK, x0), min((kx + 1) * CHUNK, x1))
            for ky in range(y0 // CHUNK, (y1 - 1) // CHUNK + 1):
                cy = slice(max(ky * CHUNK, y0), min((ky + 1) * CHUNK, y1))
                part = marks[cy.start - y0 : cy.stop - y0, cx.start - x0 : cx.stop - x0]
                if part.any():
                    local = (slice(cy.start - ky * CHUNK, cy.stop - ky * CHUNK),
                             slice(cx.start - kx * CHUNK, cx.stop - kx * CHUNK))  # fmt: skip
                    parts[(kx, ky)] = (local, part)
        # Chunks in key order, those with free cells first (as the grid always added them).
        for layer, value in ((0, MARK_FREE), (1, MARK_BLOCKED)):
            for key, (local, part) in parts.items():
                hit = part == value
                if not hit.any():
                    continue
                if key not in out:
                    old = self.chunks.get(key)
                    out[key] = np.zeros((2, CHUNK, CHUNK), np.int32) if old is None else old.copy()
                out[key][(layer, *local)] += hit
        return out

    def apply(self, chunks: dict[tuple[int, int], np.ndarray]) -> None:
        """Make chunks from `compute_update` current."""
        self.chunks.update(chunks)

    def state_of_counts(self, counts: np.ndarray) -> np.ndarray:
        """[2, ...] counters -> int8 states."""
        free, obstacle = counts[0], counts[1]
        state = np.full(free.shape, UNKNOWN, dtype=np.int8)
        state[free > 0] = FREE
        state[(obstacle > 0) & (free < FREE_OVERRULES_OBSTACLE * obstacle)] = OBSTACLE
        return state

    def state_at(self, x: float, y: float) -> int:
        i, j = int(np.floor(x / self.cell_size)), int(np.floor(y / self.cell_size))
        chunk = self.chunks.get((i // CHUNK, j // CHUNK))
        if chunk is None:
            return UNKNOWN
        counts = chunk[:, j % CHUNK, i % CHUNK]
        return int(self.state_of_counts(counts.reshape(2, 1))[0])

    def to_dense(self, margin: int = 0) -> DenseOccupancy:
        """All observed chunks as one dense window (plus `margin` unknown cells around)."""
        if not self.chunks:
            return DenseOccupancy(np.zeros((1, 1), dtype=np.int8), (0, 0), self.cell_size)
        keys = np.array(list(self.chunks))
        k0, k1 = keys.min(0), keys.max(0)
        w = (k1[0] - k0[0] + 1) * CHUNK
        h = (k1[1] - k0[1] + 1) * CHUNK
        counts = np.zeros((2, h, w), dtype=np.int32)
        for (ci, cj), chunk in self.chunks.items():
            r, c = (cj - k0[1]) * CHUNK, (ci - k0[0]) * CHUNK
            counts[:, r : r + CHUNK, c : c + CHUNK] = chunk
        state = self.state_of_counts(counts)
        origin = (int(k0[0] * CHUNK) - margin, int(k0[1] * CHUNK) - margin)
        if margin:
            state = np.pad(state, margin, constant_values=UNKNOWN)
        return DenseOccupancy(state, origin, self.cell_size)

    def equals(self, other: OccupancyGrid) -> bool:
        if set(self.chunks) != set(other.chunks):
            return False
        return all(np.array_equal(v, other.chunks[k]) for k, v in self.chunks.items())


BEARING_BIN = np.radians(0.5)
