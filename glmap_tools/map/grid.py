"""`IndexGrid`: the paper's 2D indexing grid m — sparse cells holding unit ids."""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np

from glmap_tools.gaussians.types import GaussianSet

Cell = tuple[int, int]


def cells_of_points(xy: np.ndarray, cell_size: float) -> np.ndarray:
    """Unique integer cells [M, 2] containing the points xy [N, 2] (m)."""
    if len(xy) == 0:
        return np.zeros((0, 2), dtype=np.int64)
    ij = np.floor(np.asarray(xy, dtype=np.float64)[:, :2] / cell_size).astype(np.int64)
    # 1D keys make np.unique several times faster than unique rows.
    # The low 32 bits hold j as unsigned, so the arithmetic shift recovers i exactly.
    keys = np.unique((ij[:, 0] << 32) + (ij[:, 1] & 0xFFFFFFFF))
    j = (keys & 0xFFFFFFFF).astype(np.int64)
    j[j >= 1 << 31] -= 1 << 32
    return np.stack([keys >> 32, j], axis=1)


def gaussian_cells(
    means: np.ndarray, covs: np.ndarray, cell_size: float, k: float = 1.0
) -> np.ndarray:
    """Unique cells [M, 2] covered by the x-y footprints (mean +- k sigma) of Gaussians.

    Args:
        means: [N, 3] metres.
        covs: [N, 3, 3] m^2.
        cell_size: metres.
        k: footprint half-width in standard deviations.
    """
    if len(means) == 0:
        return np.zeros((0, 2), dtype=np.int64)
    ij, _ = gaussian_cell_owners(means, covs, cell_size, k)
    return cells_of_points((ij + 0.5) * cell_size, cell_size)


def gaussian_cell_owners(
    means: np.ndarray, covs: np.ndarray, cell_size: float, k: float = 1.0
) -> tuple[np.ndarray, np.ndarray]:
    """Every (cell, Gaussian) pair of the footprints (mean +- k sigma) in x-y: cells [M, 2]
    int64 (repeated where footprints overlap) and the index of the Gaussian of each [M]."""
    xy = np.asarray(means, dtype=np.float64)[:, :2]
    sigma = np.sqrt(np.maximum(np.asarray(covs, dtype=np.float64)[:, [0, 1], [0, 1]], 0.0))
    lo = np.floor((xy - k * sigma) / cell_size).astype(np.int64)
    hi = np.floor((xy + k * sigma) / cell_size).astype(np.int64)
    nx, ny = hi[:, 0] - lo[:, 0] + 1, hi[:, 1] - lo[:, 1] + 1
    per = nx * ny
    owner = np.repeat(np.arange(len(xy)), per)
    local = np.arange(per.sum()) - np.repeat(np.cumsum(per) - per, per)
    ij = np.stack([lo[owner, 0] + local % nx[owner], lo[owner, 1] + local // nx[owner]], axis=1)
    return ij, owner


def unit_cells(gaussians: GaussianSet, cell_size: float) -> frozenset[Cell]:
    """The cells an instance's Gaussians project into."""
    cells = gaussian_cells(gaussians.means, gaussians.covs, cell_size)
    return frozenset(map(tuple, cells.tolist()))


class IndexGrid:
    """Sparse, unbounded 2D grid over the world x-y plane.

    Each cell holds the ids of the units (instances and regions) whose Gaussians project
    into it; a reverse index keeps each unit's cells so updates replace them cheaply.
    """

    def __init__(self, cell_size: float = 0.05) -> None:
        self.cell_size = float(cell_size)
        self._cells: dict[Cell, set[int]] = {}
        self._unit_cells: dict[int, frozenset[Cell]] = {}

    def __len__(self) -> int:
        """Number of occupied cells."""
        return len(self._cells)

    def cell_of(self, x: float, y: float) -> Cell:
        return (math.floor(x / self.cell_size), math.floor(y / self.cell_size))

    def set_unit(self, unit_id: int, cells: Iterable[Cell]) -> None:
        """Replace the cells of `unit_id` (only the cells that change are touched)."""
        if isinstance(cells, frozenset) and all(type(i) is int for c in cells for i in c):
            new = cells
        else:
            new = frozenset((int(i), int(j)) for i, j in cells)
        old = self._unit_cells.get(unit_id, frozenset())
        for c in old - new:
            ids = self._cells[c]
            ids.discard(unit_id)
            if not ids:
                del self._cells[c]
        for c in new - old:
            self._cells.setdefault(c, set()).add(unit_id)
        self._unit_cells[unit_id] = new

    def remove_unit(self, unit_id: int) -> None:
        for c in self._unit_cells.pop(unit_id, frozenset()):
            ids = self._cells[c]
            ids.discard(unit_id)
            if not ids:
                del self._cells[c]

    def cells_of_unit(self, unit_id: int) -> frozenset[Cell]:
        return self._unit_cells.get(unit_id, frozenset())

    def ids_at(self, cell: Cell) -> frozenset[int]:
        return frozenset(self._cells.get(cell, ()))

    def units_near(self, x: float, y: float, radius: float) -> list[tuple[int, float]]:
        """Units with a cell within `radius` (m) of (x, y), as (id, distance), nearest first.

        Distance is from (x, y) to the nearest point of the unit's nearest cell (0 inside).
        """
        s = self.cell_size
        i0, i1 = math.floor((x - radius) / s), math.floor((x + radius) / s)
        j0, j1 = math.floor((y - radius) / s), math.floor((y + radius) / s)
        best: dict[int, float] = {}
        for i in range(i0, i1 + 1):
            dx = max(i * s - x, 0.0, x - (i + 1) * s)
            for j in range(j0, j1 + 1):
                ids = self._cells.get((i, j))
                if not ids:
                    continue
                dy = max(j * s - y, 0.0, y - (j + 1) * s)
                d = math.hypot(dx, dy)
                if d > radius:
                    continue
                for uid in ids:
                    if d < best.get(uid, math.inf):
                        best[uid] = d
        return sorted(best.items(), key=lambda item: (item[1], item[0]))

    def snapshot(self) -> dict[Cell, frozenset[int]]:
        """A copy of every non-empty cell (for equality checks)."""
        return {c: frozenset(ids) for c, ids in self._cells.items()}

    def copy(self) -> IndexGrid:
        other = IndexGrid(self.cell_size)
        other._cells = {c: set(ids) for c, ids in self._cells.items()}
        other._unit_cells = dict(self._unit_cells)
        return other
