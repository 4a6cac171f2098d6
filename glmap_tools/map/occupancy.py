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

from glmap_tools.map.grid import cells_of_points

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

    def _added(self, cells: np.ndarray, layer: int, out: dict[tuple[int, int], np.ndarray]) -> None:
        """Count one observation in `layer` (0 free, 1 obstacle) per [N, 2] cell into `out`.

        `out` holds updated copies of chunks; the grid itself is not touched.
        """
        if len(cells) == 0:
            return
        keys = np.floor_divide(cells, CHUNK)
        local = cells - keys * CHUNK
        order = np.lexsort((keys[:, 1], keys[:, 0]))
        keys, local = keys[order], local[order]
        split = np.flatnonzero(np.any(np.diff(keys, axis=0) != 0, axis=1)) + 1
        for start, end in zip(
            np.concatenate([[0], split]), np.concatenate([split, [len(keys)]]), strict=True
        ):
            key = (int(keys[start, 0]), int(keys[start, 1]))
            chunk = out.get(key)
            if chunk is None:
                old = self.chunks.get(key)
                chunk = np.zeros((2, CHUNK, CHUNK), dtype=np.int32) if old is None else old.copy()
                out[key] = chunk
            np.add.at(chunk[layer], (local[start:end, 1], local[start:end, 0]), 1)

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
        s = self.cell_size
        out: dict[tuple[int, int], np.ndarray] = {}
        if len(points) == 0:
            return out
        h = points[:, 2] - floor_z
        obstacle = (h >= obstacle_band[0]) & (h <= obstacle_band[1])
        floor = np.abs(h) < obstacle_band[0]
        free_parts = [points[floor, :2], _carve(camera_xy, points[:, :2], obstacle, s)]
        free = cells_of_points(np.concatenate(free_parts), s)
        blocked = cells_of_points(points[obstacle, :2], s)
        # Within one frame an obstacle hit wins: a 2D ray passing over a table top is no
        # evidence that the table's cells are free.
        free = free[~_rows_in(free, blocked)]
        self._added(free, 0, out)
        self._added(blocked, 1, out)
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


def _rows_in(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """[len(a)] bool: which integer rows of a [N, 2] appear in b [M, 2]."""
    if len(a) == 0 or len(b) == 0:
        return np.zeros(len(a), dtype=bool)
    ka = (a[:, 0] << 32) + (a[:, 1] & 0xFFFFFFFF)
    kb = (b[:, 0] << 32) + (b[:, 1] & 0xFFFFFFFF)
    return np.isin(ka, kb)


BEARING_BIN = np.radians(0.5)


def _carve(
    camera_xy: np.ndarray, xy: np.ndarray, obstacle: np.ndarray, cell_size: float
) -> np.ndarray:
    """Sample points [K, 2] on free 2D rays: per 0.5 degree bearing, from the camera to one
    cell short of the nearest obstacle point, or of the farthest point if none.

    Args:
        camera_xy: [2] camera position.
        xy: [N, 2] points of the frame.
        obstacle: [N] bool, which points are obstacles.
        cell_size: metres.
    """
    delta = xy - camera_xy[None, :]
    dist = np.hypot(delta[:, 0], delta[:, 1])
    bearing = np.floor(np.arctan2(delta[:, 1], delta[:, 0]) / BEARING_BIN).astype(np.int64)
    b0 = bearing.min()
    n_bins = int(bearing.max() - b0 + 1)
    reach = np.zeros(n_bins)
    np.maximum.at(reach, bearing - b0, dist)
    blocked = np.full(n_bins, np.inf)
    np.minimum.at(blocked, bearing[obstacle] - b0, dist[obstacle])
    length = np.minimum(reach, blocked) - cell_size
    bins = np.flatnonzero(length > 0)
    if len(bins) == 0:
        return np.zeros((0, 2))
    step = cell_size / 2.0
    n_steps = (length[bins] / step).astype(np.int64) + 1
    ray = np.repeat(bins, n_steps)
    t = (np.arange(n_steps.sum()) - np.repeat(np.cumsum(n_steps) - n_steps, n_steps)) * step
    angle = (ray + b0 + 0.5) * BEARING_BIN
    return camera_xy[None, :] + t[:, None] * np.stack([np.cos(angle), np.sin(angle)], axis=1)
