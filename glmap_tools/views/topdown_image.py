"""What a top-down drawing (`glmap_tools.views.topdown`) takes and gives: a `HeatMap` of
values over index-grid cells, and the `TopDownImage` with its placement in the world."""

from __future__ import annotations

import numbers
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.views.common import encode_png

if TYPE_CHECKING:
    from glmap_tools.views.topdown_frame import TopDownFrame


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
        tick: metres between the ticks on the left and bottom edges (0: none).
        label_boxes: (left, top, right, bottom) pixels of each text label written;
            no two overlap.
        frame: the placement; pass it back to `draw_topdown` to keep it while the map
            fits.
    """

    rgb: np.ndarray  # [H, W, 3]
    x0: float
    y1: float
    metres_per_pixel: float
    legend: tuple[str, ...]
    tick: float = 0.0
    label_boxes: tuple[tuple[int, int, int, int], ...] = ()
    frame: TopDownFrame | None = None

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
        ticks = (
            f"; ticks every {self.tick:g} m on the left (y) and bottom (x) edges"
            if self.tick
            else ""
        )
        return (
            f"top-down map, {w}x{h} px, +x right, +y up, {self.metres_per_pixel * 100:.3g} cm "
            f"per pixel; the top-left corner is world (x, y) = ({self.x0:.2f}, {self.y1:.2f}) m"
            f"{ticks}. " + " ".join(self.legend)
        )
