"""The top-down map image: the index grid drawn as a labelled picture.

Occupancy (free / obstacle / unseen) underneath, instance footprints (their index-grid
cells) in a colour per id, an optional value heat-map blended on top, region hulls
outlined, ids written at the units' centres, the camera trajectory and an optional agent
pose. +x points right and +y up; `TopDownImage.world_to_pixel` maps world metres to pixels.
"""

from __future__ import annotations

import colorsys
import math
import numbers
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import cv2
import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.geometry import Pose
from glmap_tools.map.occupancy import FREE, OBSTACLE
from glmap_tools.views.common import encode_png

if TYPE_CHECKING:
    from glmap_tools.map.glmap import GLMap

MAX_SIDE = 4096  # pixels: the cap on the image's longer side
DEFAULT_SIDE = 768  # pixels
MAX_PIXELS_PER_CELL = 8
MAX_LABELS = 300  # more units than this are drawn without id labels
UNSEEN, FREE_RGB, OBSTACLE_RGB = (200, 200, 200), (255, 255, 255), (90, 90, 90)
TRAJECTORY_RGB, AGENT_RGB = (30, 90, 210), (220, 30, 30)
HEAT_OPACITY = 0.6


@dataclass(frozen=True)
class HeatMap:
    """Values over index-grid cells, drawn as a colour overlay (e.g. a value map H(l)).

    Attributes:
        values: [H, W] float; row = y cell, column = x cell (like DenseOccupancy); NaN
            cells are left undrawn.
        origin: (i0, j0) integer cell (x index, y index) of values[0, 0].
        cell_size: metres per cell (may differ from the map's; cells are looked up by
            world position).
        vmin: value drawn in the coldest colour; None = the smallest finite value.
        vmax: value drawn in the hottest colour; None = the largest finite value.
    """

    values: np.ndarray  # [H, W]
    origin: tuple[int, int]
    cell_size: float
    vmin: float | None = None
    vmax: float | None = None

    def __post_init__(self) -> None:
        v = np.asarray(self.values, dtype=np.float64)
        if v.ndim != 2 or v.size == 0:
            raise InvalidInputError(
                f"heat map values have shape {v.shape}; pass a non-empty [H, W] array."
            )
        if not (isinstance(self.cell_size, numbers.Real) and self.cell_size > 0):
            raise InvalidInputError(f"heat map cell_size={self.cell_size!r} must be > 0 metres.")
        object.__setattr__(self, "values", v)

    def at(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:  # x, y: [K] -> [K]
        """Values at world points (NaN outside the array)."""
        c = np.floor(x / self.cell_size).astype(np.int64) - self.origin[0]
        r = np.floor(y / self.cell_size).astype(np.int64) - self.origin[1]
        h, w = self.values.shape
        inside = (r >= 0) & (r < h) & (c >= 0) & (c < w)
        out = np.full(len(x), np.nan)
        out[inside] = self.values[r[inside], c[inside]]
        return out


@dataclass(frozen=True)
class TopDownImage:
    """A top-down map image and how its pixels map to the world.

    Pixel (col, row) covers world x = x0 + col * metres_per_pixel (left edge) and
    y = y1 - row * metres_per_pixel (top edge): +x right, +y up.

    Attributes:
        rgb: [H, W, 3] uint8 RGB.
        x0: world x of the image's left edge (m).
        y1: world y of the image's top edge (m).
        metres_per_pixel: scale.
        legend: one line per drawn layer, saying what its colours mean.
    """

    rgb: np.ndarray  # [H, W, 3]
    x0: float
    y1: float
    metres_per_pixel: float
    legend: tuple[str, ...]

    def world_to_pixel(self, x: float, y: float) -> tuple[float, float]:
        """(col, row) pixel coordinates of world (x, y)."""
        return ((x - self.x0) / self.metres_per_pixel, (self.y1 - y) / self.metres_per_pixel)

    def pixel_to_world(self, col: float, row: float) -> tuple[float, float]:
        """World (x, y) of pixel coordinates (col, row)."""
        return (self.x0 + col * self.metres_per_pixel, self.y1 - row * self.metres_per_pixel)

    def to_png(self) -> bytes:
        return encode_png(self.rgb)

    def describe(self) -> str:
        """How to read the image, for people and agents."""
        h, w = self.rgb.shape[:2]
        return (
            f"top-down map, {w}x{h} px, +x right, +y up, {self.metres_per_pixel * 100:.1f} cm "
            f"per pixel; the top-left corner is world (x, y) = ({self.x0:.2f}, {self.y1:.2f}) m. "
            + " ".join(self.legend)
        )


@dataclass(frozen=True)
class _Frame:
    """Raster geometry: cells lo..hi (inclusive), k cells per raster cell, s px per raster cell."""

    lo: np.ndarray  # [2] int (i, j)
    hi: np.ndarray  # [2] int
    k: int
    s: int
    cell: float

    @property
    def shape(self) -> tuple[int, int]:
        span = self.hi - self.lo + 1
        return int(-(-span[1] // self.k)), int(-(-span[0] // self.k))

    def raster(self, ij: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # ij: [K, 2]
        """(rows, cols) of raster cells holding grid cells ij."""
        return (self.hi[1] - ij[:, 1]) // self.k, (ij[:, 0] - self.lo[0]) // self.k

    def px(self, x: float, y: float) -> tuple[int, int]:
        mpp = self.cell * self.k / self.s
        x0, y1 = self.lo[0] * self.cell, (self.hi[1] + 1) * self.cell
        return int(round((x - x0) / mpp)), int(round((y1 - y) / mpp))


def palette(uid: int) -> tuple[int, int, int]:
    """A distinct saturated RGB colour per unit id (golden-ratio hues)."""
    r, g, b = colorsys.hsv_to_rgb((uid * 0.618033988749895) % 1.0, 0.75, 0.9)
    return int(r * 255), int(g * 255), int(b * 255)


def _agent_xy_heading(agent: Pose | Sequence[float]) -> tuple[float, float, float]:
    if isinstance(agent, Pose):
        return float(agent.translation[0]), float(agent.translation[1]), agent.heading
    try:
        x, y, heading = (float(v) for v in agent)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(
            f"agent={agent!r} must be a Pose or (x, y, heading) in metres and radians."
        ) from exc
    if not all(math.isfinite(v) and abs(v) <= 1e4 for v in (x, y, heading)):
        raise InvalidInputError(f"agent={agent!r} must be finite, within +-1e4.")
    return x, y, heading


def _unit_cells(glmap: GLMap) -> dict[int, np.ndarray]:
    out = {}
    for uid in sorted(glmap.instances):
        c = np.array(sorted(glmap.grid.cells_of_unit(uid)), dtype=np.int64).reshape(-1, 2)
        if len(c):
            out[uid] = c
    return out


def _frame(
    glmap: GLMap,
    cells: dict[int, np.ndarray],
    extra_xy: list[tuple[float, float]],
    heatmap: HeatMap | None,
    max_side: int,
) -> _Frame:
    cell = glmap.config.cell_size
    lo_parts, hi_parts = [], []
    if glmap.occupancy.chunks:
        dense = glmap.occupancy.to_dense()
        h, w = dense.state.shape
        lo_parts.append(np.array(dense.origin))
        hi_parts.append(np.array(dense.origin) + [w - 1, h - 1])
    for c in cells.values():
        lo_parts.append(c.min(0))
        hi_parts.append(c.max(0))
    if heatmap is not None:
        hh, hw = heatmap.values.shape
        corners = np.array(heatmap.origin, np.float64) * heatmap.cell_size
        far = corners + np.array([hw, hh]) * heatmap.cell_size
        lo_parts.append(np.floor(corners / cell).astype(np.int64))
        hi_parts.append(np.floor(far / cell).astype(np.int64) - 1)
    for x, y in extra_xy:
        ij = np.floor(np.array([x, y]) / cell).astype(np.int64)
        lo_parts.append(ij)
        hi_parts.append(ij)
    if not lo_parts:
        raise InvalidInputError(
            "the map is empty: no instance in the index grid and no observed space; integrate "
            "frames before drawing it."
        )
    lo = np.min(lo_parts, 0).astype(np.int64) - 2
    hi = np.max(hi_parts, 0).astype(np.int64) + 2
    span = int(max(hi - lo + 1))
    k = max(1, -(-span // max_side))  # cells per raster cell, so the raster fits max_side
    s = int(max(1, min(MAX_PIXELS_PER_CELL, max_side // -(-span // k))))
    return _Frame(lo, hi, k, s, cell)


def _paint(raster: np.ndarray, f: _Frame, ij: np.ndarray, color: Sequence[int]) -> None:
    if len(ij):
        r, c = f.raster(ij)
        raster[r, c] = color


def _heat_overlay(raster: np.ndarray, f: _Frame, heatmap: HeatMap) -> tuple[float, float] | None:
    """Blend the heat map into the raster; return the (vmin, vmax) drawn, or None."""
    rows, cols = np.mgrid[0 : raster.shape[0], 0 : raster.shape[1]]
    # Centre of each raster cell in world metres.
    x = (f.lo[0] + cols.ravel() * f.k + f.k / 2.0) * f.cell
    y = (f.hi[1] + 1 - rows.ravel() * f.k - f.k / 2.0) * f.cell
    values = heatmap.at(x, y)
    finite = np.isfinite(values)
    if not finite.any():
        return None
    vmin = float(values[finite].min()) if heatmap.vmin is None else float(heatmap.vmin)
    vmax = float(values[finite].max()) if heatmap.vmax is None else float(heatmap.vmax)
    t = np.clip((values[finite] - vmin) / max(vmax - vmin, 1e-12), 0.0, 1.0)
    lut = cv2.applyColorMap(np.arange(256, dtype=np.uint8)[:, None], cv2.COLORMAP_TURBO)
    colors = lut[(t * 255).round().astype(np.int64), 0, ::-1].astype(np.float64)  # BGR -> RGB
    flat = raster.reshape(-1, 3)
    idx = np.flatnonzero(finite)
    blended = (1 - HEAT_OPACITY) * flat[idx] + HEAT_OPACITY * colors
    flat[idx] = blended.round().astype(np.uint8)
    return vmin, vmax


def _text(image: np.ndarray, text: str, xy: tuple[int, int], scale: float = 0.4) -> None:
    """Write white text with a dark outline, readable on any colour."""
    font = cv2.FONT_HERSHEY_SIMPLEX
    cv2.putText(image, text, xy, font, scale, (0, 0, 0), 3, cv2.LINE_AA)
    cv2.putText(image, text, xy, font, scale, (255, 255, 255), 1, cv2.LINE_AA)


def draw_topdown(
    glmap: GLMap,
    *,
    agent: Pose | Sequence[float] | None = None,
    heatmap: HeatMap | None = None,
    max_side: int = DEFAULT_SIDE,
    labels: bool = True,
    regions: bool = True,
    trajectory: bool = True,
) -> TopDownImage:
    """Draw the map's index grid from above as a labelled image.

    Args:
        glmap: the map.
        agent: an optional agent pose, drawn as a red arrow: a Pose, or (x, y, heading) in
            metres and radians (heading from +x, counter-clockwise).
        heatmap: an optional value heat-map blended over the cells it covers (turbo
            colours, cold = low).
        max_side: cap on the image's longer side in pixels, 64..MAX_SIDE (4096); a map
            with more cells than pixels is drawn several cells per pixel.
        labels: write unit ids (instances at their centroids, regions as "R<id>").
        regions: outline each region's cells with their convex hull.
        trajectory: draw the integrated camera positions as a blue line.

    Raises:
        InvalidInputError: nothing to draw (no instances and no observed space), a bad
            agent pose, heat map or max_side.
    """
    if isinstance(max_side, bool) or not isinstance(max_side, numbers.Integral):
        raise InvalidInputError(f"max_side={max_side!r} must be an integer number of pixels.")
    if not 64 <= int(max_side) <= MAX_SIDE:
        raise InvalidInputError(f"max_side={max_side!r} must be in 64..{MAX_SIDE} pixels.")
    if heatmap is not None and not isinstance(heatmap, HeatMap):
        raise InvalidInputError(
            f"heatmap is a {type(heatmap).__name__}; pass a glmap_tools.views.HeatMap."
        )
    agent_xyh = _agent_xy_heading(agent) if agent is not None else None
    cells = _unit_cells(glmap)
    extra = [agent_xyh[:2]] if agent_xyh is not None else []
    f = _frame(glmap, cells, extra, heatmap, int(max_side))
    raster = np.empty((*f.shape, 3), np.uint8)
    raster[:] = UNSEEN
    legend = ["Light grey = never observed."]
    if glmap.occupancy.chunks:
        dense = glmap.occupancy.to_dense()
        rr, cc = np.nonzero(dense.state != 0)
        ij = np.stack([cc + dense.origin[0], rr + dense.origin[1]], axis=1)
        state = dense.state[rr, cc]
        _paint(raster, f, ij[state == FREE], FREE_RGB)
        _paint(raster, f, ij[state == OBSTACLE], OBSTACLE_RGB)  # obstacles win a shared pixel
        legend.append("White = seen free, dark grey = obstacle.")
    # Largest footprints first, so a chair stays visible on top of the floor under it.
    for uid, c in sorted(cells.items(), key=lambda item: (-len(item[1]), item[0])):
        _paint(raster, f, c, palette(uid))
    if cells:
        legend.append("Coloured cells = instance footprints (a colour per id).")
    if heatmap is not None:
        drawn = _heat_overlay(raster, f, heatmap)
        if drawn is not None:
            legend.append(f"Heat overlay: blue = {drawn[0]:.3g} .. red = {drawn[1]:.3g}.")
    image = np.ascontiguousarray(
        cv2.resize(
            raster,
            (raster.shape[1] * f.s, raster.shape[0] * f.s),
            interpolation=cv2.INTER_NEAREST,
        )
    )
    label_count = len(cells) + (len(glmap.regions) if regions else 0)
    write_labels = labels and label_count <= MAX_LABELS
    if regions:
        _draw_regions(image, f, glmap, write_labels)
        if glmap.regions:
            legend.append("Outlines labelled R<id> = region hulls.")
    if trajectory and glmap.trajectory:
        pts = np.array([f.px(p[0, 3], p[1, 3]) for p in glmap.trajectory], np.int32)
        cv2.polylines(image, [pts.reshape(-1, 1, 2)], False, TRAJECTORY_RGB, 1, cv2.LINE_AA)
        legend.append("Blue line = camera trajectory.")
    if write_labels:
        for uid in cells:
            cx, cy = glmap.instances[uid].centroid[:2]
            _text(image, str(uid), f.px(float(cx), float(cy)))
        legend.append("Numbers = instance ids at their centroids.")
    if agent_xyh is not None:
        x, y, heading = agent_xyh
        tip = (x + 0.5 * math.cos(heading), y + 0.5 * math.sin(heading))
        cv2.arrowedLine(image, f.px(x, y), f.px(*tip), AGENT_RGB, 2, cv2.LINE_AA, tipLength=0.35)
        cv2.circle(image, f.px(x, y), 3, AGENT_RGB, -1, cv2.LINE_AA)
        legend.append(f"Red arrow = the agent at ({x:.2f}, {y:.2f}) facing its heading.")
    mpp = f.cell * f.k / f.s
    return TopDownImage(
        image, float(f.lo[0] * f.cell), float((f.hi[1] + 1) * f.cell), mpp, tuple(legend)
    )


def _draw_regions(image: np.ndarray, f: _Frame, glmap: GLMap, write_labels: bool) -> None:
    """Outline each region's cells by their convex hull, in the region's colour."""
    mpp = f.cell * f.k / f.s
    for rid in sorted(glmap.regions):
        cells: set[tuple[int, int]] = set()
        for iid in glmap.regions[rid].instance_ids:
            cells |= glmap.grid.cells_of_unit(iid)
        if not cells:
            continue
        ij = np.array(sorted(cells), np.float64)
        corners = np.concatenate([ij + d for d in ((0, 0), (1, 0), (0, 1), (1, 1))]) * f.cell
        x0, y1 = f.lo[0] * f.cell, (f.hi[1] + 1) * f.cell
        px = np.stack([(corners[:, 0] - x0) / mpp, (y1 - corners[:, 1]) / mpp], axis=1)
        hull = cv2.convexHull(px.round().astype(np.int32))
        cv2.polylines(image, [hull], True, palette(rid), 2, cv2.LINE_AA)
        if write_labels:
            # Above the hull's top-left corner, clear of the instance ids inside it.
            left, top = hull.reshape(-1, 2).min(axis=0)
            _text(image, f"R{rid}", (int(left), max(int(top) - 4, 10)))
