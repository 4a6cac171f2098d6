"""The value map H(l) of paper Eq. 7: unit scores on their grid cells, smoothed by K_sigma.

    H(l) = 1/Z sum_{v in m} ( sum_u s_u delta(v - p_u) ) K_sigma(l - v)

Every unit u (instance or region) puts its score s_u on each index-grid cell it covers; the
score image is convolved with a sampled 2D Gaussian K_sigma (separable, truncated at
TRUNCATE sigma per axis, normalised to sum 1); Z = max_l of the sum, so H is in [0, 1] with
its maximum at 1 (0 everywhere when no unit scores above 0). `value_map_reference` evaluates
the double sum directly.
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy import ndimage

from glmap_tools.errors import InvalidInputError
from glmap_tools.map.grid import IndexGrid, gaussian_cell_owners
from glmap_tools.map.occupancy import DenseOccupancy
from glmap_tools.nav.grid import Window

if TYPE_CHECKING:
    from glmap_tools.map.glmap import GLMap
    from glmap_tools.nav.scorers import Scorer, UnitText

# Imports inside functions stay there: circle: nav.config, nav.grid, nav.scorers import this module.

TRUNCATE = 3.0  # kernel half-width in sigmas


@dataclass(frozen=True)
class ValueMap:
    """A dense value map over a window of the index grid.

    Attributes:
        values: [H, W] float in [0, 1]; row = y cell, column = x cell (as DenseOccupancy).
        origin: (i0, j0) integer cell of values[0, 0].
        cell_size: metres per cell.
        peak: Z, the largest unnormalised value (0 when nothing scored).
        sigma: kernel bandwidth (m); 0 for maps that are not smoothed (egocentric).
        scale: the score that H = 1 stands for: the largest s_u of an Eq. 7 map (H is
            normalised by Z, so `scale * H` is in score units); 1 for maps of scores.
    """

    values: np.ndarray  # [H, W]
    origin: tuple[int, int]
    cell_size: float
    peak: float = 0.0
    sigma: float = 0.0
    scale: float = 1.0

    @property
    def empty(self) -> bool:
        """True when no cell has a positive value."""
        return self.values.size == 0 or not bool((self.values > 0).any())

    def xy_of(self, row: int, col: int) -> tuple[float, float]:
        return (
            (col + self.origin[0] + 0.5) * self.cell_size,
            (row + self.origin[1] + 0.5) * self.cell_size,
        )

    def argmax_xy(self) -> tuple[float, float] | None:
        """World (x, y) of the highest cell (lowest row, then column, on ties), None if empty."""
        if self.empty:
            return None
        r, c = np.unravel_index(int(np.argmax(self.values)), self.values.shape)
        return self.xy_of(int(r), int(c))

    def value_at(self, x: float, y: float) -> float:
        """H at world (x, y); 0 outside the window."""
        return float(self.values_at(np.array([[x, y]], dtype=np.float64))[0])

    def values_at(self, xy: np.ndarray) -> np.ndarray:
        """[K] H at the world points `xy` [K, 2]; 0 outside the window."""
        r = np.floor(xy[:, 1] / self.cell_size).astype(np.int64) - self.origin[1]
        c = np.floor(xy[:, 0] / self.cell_size).astype(np.int64) - self.origin[0]
        h, w = self.values.shape
        inside = (r >= 0) & (r < h) & (c >= 0) & (c < w)
        out = np.zeros(len(xy), dtype=np.float64)
        out[inside] = self.values[r[inside], c[inside]]
        return out

    def top_cells(
        self, k: int = 5, min_separation: float = 0.5
    ) -> list[tuple[float, float, float]]:
        """Up to k local peaks as (x, y, value), highest first, `min_separation` m apart."""
        if self.empty or k < 1:
            return []
        rows, cols = np.nonzero(self.values > 0)
        vals = self.values[rows, cols]
        order = np.lexsort((cols, rows, -vals))
        sep = (min_separation / self.cell_size) ** 2
        picked: list[tuple[int, int, float]] = []
        for idx in order:
            r, c = int(rows[idx]), int(cols[idx])
            if all((r - pr) ** 2 + (c - pc) ** 2 >= sep for pr, pc, _ in picked):
                picked.append((r, c, float(vals[idx])))
                if len(picked) == k:
                    break
        return [(*self.xy_of(r, c), round(v, 4)) for r, c, v in picked]


def gaussian_kernel_1d(sigma_cells: float) -> np.ndarray:
    """[2R+1] sampled Gaussian, R = ceil(TRUNCATE sigma), normalised to sum 1."""
    radius = max(1, math.ceil(TRUNCATE * sigma_cells))
    x = np.arange(-radius, radius + 1, dtype=np.float64)
    g = np.exp(-0.5 * (x / sigma_cells) ** 2)
    return g / g.sum()


# Per-grid cache: unit id -> (the grid's frozenset of cells, [K, 2] int array of (i, j)).
_CELL_CACHE: weakref.WeakKeyDictionary[IndexGrid, dict[int, tuple[frozenset, np.ndarray]]] = (
    weakref.WeakKeyDictionary()
)


def unit_cell_array(grid: IndexGrid, unit_id: int) -> np.ndarray:
    """[K, 2] int (i, j) cells of a unit, cached until the grid replaces them."""
    cache = _CELL_CACHE.get(grid)
    if cache is None:
        cache = _CELL_CACHE[grid] = {}
    cells = grid.cells_of_unit(unit_id)
    hit = cache.get(unit_id)
    if hit is not None and hit[0] is cells:
        return hit[1]
    arr = np.array(sorted(cells), dtype=np.int64).reshape(-1, 2)
    cache[unit_id] = (cells, arr)
    return arr


CORE_MARGIN_CELLS = 2  # cells (0.1 m at 5 cm) kept around a unit's core


def unit_core_cells(glmap: GLMap, unit_id: int, share: float) -> np.ndarray:
    """[K, 2] the cells of an instance near its densest cells, those holding `share` of its
    points (within `CORE_MARGIN_CELLS`).

    Each Gaussian spreads its point count evenly over its 1-sigma cells (the cells the index
    grid gives the unit); cells are taken densest first until `share` of the count is held.
    A mask that bleeds over a depth edge adds a few points spread far behind the object:
    thin, wide Gaussians that widen the unit's cells but hold little of its mass. `share`
    >= 1, a region, or a unit without Gaussians gives every cell (`unit_cell_array`).
    """
    cells = unit_cell_array(glmap.grid, unit_id)
    unit = glmap.instances.get(unit_id)
    if share >= 1.0 or unit is None or len(unit.gaussians) == 0 or len(cells) == 0:
        return cells
    g = unit.gaussians
    ij, owner = gaussian_cell_owners(g.means, g.covs, glmap.grid.cell_size)
    per = np.bincount(owner, minlength=len(g))  # cells per Gaussian
    mass = (np.asarray(g.counts, dtype=np.float64) / per)[owner]
    keys, inverse = np.unique(ij, axis=0, return_inverse=True)
    density = np.bincount(inverse.ravel(), weights=mass, minlength=len(keys))
    order = np.argsort(-density, kind="stable")
    held = np.cumsum(density[order])
    core = keys[order[: int(np.searchsorted(held, share * held[-1])) + 1]]
    # The unit's cells within CORE_MARGIN_CELLS of the core: cell rounding and a partly seen
    # edge stay; a bleed decimetres wide goes.
    m = CORE_MARGIN_CELLS
    offsets = np.stack(np.meshgrid(np.arange(-m, m + 1), np.arange(-m, m + 1)), -1).reshape(-1, 2)
    near = {tuple(c) for c in (core[:, None, :] + offsets[None]).reshape(-1, 2).tolist()}
    return cells[np.array([tuple(c) in near for c in cells.tolist()], dtype=bool)]


def as_window(window: Window | DenseOccupancy) -> Window:
    return Window.of(window) if isinstance(window, DenseOccupancy) else window


def score_image(scores: Mapping[int, float], grid: IndexGrid, window: Window) -> np.ndarray:
    """[H, W] sum_u s_u delta(v - p_u): each unit's mass added on each of its cells."""
    ids = [int(uid) for uid, s in scores.items() if s > 0]
    img = np.zeros(window.shape, dtype=np.float64)
    if not ids:
        return img
    arrays = [unit_cell_array(grid, uid) for uid in ids]
    counts = np.array([len(a) for a in arrays])
    cells = np.concatenate(arrays)
    vals = np.repeat(np.array([float(scores[uid]) for uid in ids]), counts)
    r = cells[:, 1] - window.j0
    c = cells[:, 0] - window.i0
    keep = (r >= 0) & (r < window.height) & (c >= 0) & (c < window.width)
    flat = r[keep] * window.width + c[keep]
    img.ravel()[:] = np.bincount(flat, vals[keep], minlength=img.size)
    return img


def check_scores(scores: Mapping[int, float]) -> None:
    for uid, s in scores.items():
        if not (math.isfinite(s) and 0.0 <= s <= 1.0):
            raise InvalidInputError(f"score {s!r} of unit {uid} must be in [0, 1].")


def value_map_from_scores(
    scores: Mapping[int, float],
    grid: IndexGrid,
    window: Window | DenseOccupancy,
    sigma: float,
    *,
    unit_mass: str = "unit",
) -> ValueMap:
    """Eq. 7 over `window` for unit scores s_u (fast: separable convolution of the cells).

    Args:
        scores: unit id -> s_u in [0, 1].
        grid: the index grid m holding each unit's cells.
        window: the cells to evaluate (units outside it do not contribute).
        sigma: kernel bandwidth, metres.
        unit_mass: 'unit' (s_u / |cells| on each cell: every unit adds s_u in total) or
            'cells' (s_u on each cell: a unit weighs with its area); see `NavConfig.unit_mass`.
    """
    check_scores(scores)
    win = as_window(window)
    img = score_image(spread_scores(scores, grid, unit_mass), grid, win)
    g = gaussian_kernel_1d(sigma / grid.cell_size)
    # K_sigma is separable: filter along columns (only those holding a score), then rows.
    h = np.zeros_like(img)
    cols = np.flatnonzero(img.any(axis=0))
    if len(cols):
        h[:, cols] = ndimage.correlate1d(img[:, cols], g, axis=0, mode="constant")
        rows = np.flatnonzero(h.any(axis=1))
        h[rows] = ndimage.correlate1d(h[rows], g, axis=1, mode="constant")
    peak = float(h.max()) if h.size else 0.0
    values = h / peak if peak > 0 else np.zeros_like(h)
    scale = max((float(v) for v in scores.values()), default=0.0)
    return ValueMap(np.clip(values, 0.0, 1.0), win.origin, grid.cell_size, peak, sigma, scale)


def value_map_reference(
    scores: Mapping[int, float],
    grid: IndexGrid,
    window: Window | DenseOccupancy,
    sigma: float,
    *,
    unit_mass: str = "unit",
) -> ValueMap:
    """Slow reference of `value_map_from_scores`: the explicit double sum of Eq. 7."""
    win = as_window(window)
    s_cell = grid.cell_size
    g = gaussian_kernel_1d(sigma / s_cell)
    radius = len(g) // 2
    sources: dict[tuple[int, int], float] = {}
    for uid, mass in spread_scores(scores, grid, unit_mass).items():
        for i, j in unit_cell_array(grid, int(uid)).tolist():
            if win.i0 <= i < win.i0 + win.width and win.j0 <= j < win.j0 + win.height:
                sources[(i, j)] = sources.get((i, j), 0.0) + float(mass)
    h = np.zeros(win.shape)
    for r in range(win.height):
        for c in range(win.width):
            li, lj = win.i0 + c, win.j0 + r
            total = 0.0
            for (vi, vj), sv in sources.items():
                di, dj = li - vi, lj - vj
                if abs(di) <= radius and abs(dj) <= radius:
                    total += sv * g[di + radius] * g[dj + radius]
            h[r, c] = total
    peak = float(h.max()) if h.size else 0.0
    values = h / peak if peak > 0 else np.zeros_like(h)
    scale = max((float(v) for v in scores.values()), default=0.0)
    return ValueMap(values, win.origin, s_cell, peak, sigma, scale)


def map_window(glmap: GLMap, margin: float) -> Window:
    """The cells of every unit and the occupancy's known area, plus `margin` metres."""
    from glmap_tools.nav.grid import known_window

    occ = glmap.occupancy.to_dense()
    return known_window(occ, math.ceil(margin / glmap.grid.cell_size))


def value_map(
    glmap: GLMap,
    goal: str,
    scorer: Scorer,
    *,
    units: str = "both",
    sigma: float | None = None,
    window: Window | DenseOccupancy | None = None,
    unit_mass: str | None = None,
) -> ValueMap:
    """Eq. 7 for a goal text over a GLMap: s_u = f_S(u, goal) for its instances and/or regions.

    Args:
        glmap: the map.
        goal: goal description T_g (non-empty).
        scorer: f_S, e.g. `EmbeddingScorer(glmap.embedder)`.
        units: 'both' | 'instances' | 'regions'.
        sigma: kernel bandwidth (m); default NavConfig().value_sigma.
        window: cells to evaluate; default the known map plus TRUNCATE sigma.
        unit_mass: 'unit' | 'cells'; default NavConfig().unit_mass.

    Raises:
        InvalidInputError: empty goal, unknown `units` or `unit_mass`, non-positive sigma.
    """
    from glmap_tools.nav.config import NavConfig
    from glmap_tools.nav.scorers import check_goal, map_units

    check_goal(goal)
    defaults = NavConfig() if unit_mass is None else NavConfig(unit_mass=unit_mass)
    sigma = defaults.value_sigma if sigma is None else float(sigma)
    if not (math.isfinite(sigma) and sigma > 0):
        raise InvalidInputError(f"sigma={sigma!r} must be a positive number of metres, e.g. 0.5.")
    unit_texts = map_units(glmap, units)
    scores = scorer.score(goal, unit_texts) if unit_texts else np.zeros(0)
    by_id = {u.unit_id: float(s) for u, s in zip(unit_texts, scores, strict=True)}
    win = as_window(window) if window is not None else map_window(glmap, TRUNCATE * sigma)
    return value_map_from_scores(by_id, glmap.grid, win, sigma, unit_mass=defaults.unit_mass)


def spread_scores(
    scores: Mapping[int, float], grid: IndexGrid, unit_mass: str
) -> Mapping[int, float]:
    """The mass of each unit on each of its cells for `unit_mass` ('unit' or 'cells')."""
    if unit_mass == "unit":
        return per_unit_mass(scores, grid)
    if unit_mass == "cells":
        return scores
    raise InvalidInputError(f"unit_mass={unit_mass!r} must be 'unit' or 'cells'.")


def per_unit_mass(scores: Mapping[int, float], grid: IndexGrid) -> dict[int, float]:
    """Scores spread over each unit's cells: s_u / |cells of u|, so that every unit adds
    the same total s_u to Eq. 7 whatever its area (`NavConfig.unit_mass` = 'unit')."""
    return {
        int(uid): float(s) / max(1, len(unit_cell_array(grid, int(uid))))
        for uid, s in scores.items()
    }


def evidence_scores(
    units: Sequence[UnitText],
    scores: Mapping[int, float],
    kinds: Sequence[str],
    least: Mapping[str, float],
    region_hint: float,
) -> tuple[dict[int, float], str]:
    """The unit scores that enter Eq. 7, and what they are.

    Units of `kinds` whose score reaches their kind's floor `least[kind]` (the evidence
    gate: 'units'). When none does, the regions whose text suggests the goal ('region
    hint'): every region scoring at least `region_hint` times the best region's score (> 0),
    since the best-scoring region lies in the goal's room far more often than chance
    (nav/design.md, "Evidence gate"); so the value map is empty only when no region text
    says anything of the goal ('none'), and only then does the nearest frontier decide.

    Args:
        units: the scored units.
        scores: unit id -> s_u.
        kinds: the unit kinds the policy reads ('instance', 'region').
        least: kind -> the least score that enters Eq. 7.
        region_hint: share in (0, 1] of the best region score a hint region needs; 0 = no
            hint (the value map stays empty below the gate).
    """
    used = {
        u.unit_id: float(scores[u.unit_id])
        for u in units
        if u.kind in kinds and scores[u.unit_id] >= least[u.kind]
    }
    if used:
        return used, "units"
    if region_hint <= 0 or "region" not in kinds:
        return {}, "none"
    regions = {u.unit_id: float(scores[u.unit_id]) for u in units if u.kind == "region"}
    best = max(regions.values(), default=0.0)
    if best <= 0:
        return {}, "none"
    return {uid: s for uid, s in regions.items() if s >= region_hint * best}, "region hint"
