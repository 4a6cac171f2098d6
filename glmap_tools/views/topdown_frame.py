"""Where the top-down image lies in the world, and a canvas whose memory is the image's.

The scale comes from a fixed ladder (1, 2, 2.5, 5 x 10^k m per pixel) and the corners are
snapped to a 1-2-5 spacing of at least 16 pixels, so drawing a map again gives the same
frame until the map outgrows it (a frame can also be passed back in and kept while the map
fits). Cells are
painted straight onto the pixels (several cells per pixel), or, when a cell spans
several pixels, onto a cell grid over the frame that is then sampled per pixel: either
way memory is bounded by the pixel cap, never by the map's extent. Text labels go where
they overlap no earlier label, and ticks mark round metres along two edges.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from glmap_tools.errors import InvalidInputError

SCALES = tuple(m * 10.0**e for e in range(-3, 6) for m in (1.0, 2.0, 2.5, 5.0))
TICKS = tuple(m * 10.0**e for e in range(-2, 8) for m in (1.0, 2.0, 5.0))
MIN_TICK_PX = 64  # ticks at least this many pixels apart
MIN_SNAP_PX = 16  # the corners lie on a 1-2-5 spacing of at least this many pixels
FONT, FONT_SCALE = cv2.FONT_HERSHEY_SIMPLEX, 0.4
TICK_RGB = (0, 0, 0)


def tick_spacing(metres_per_pixel: float, min_px: int = MIN_TICK_PX) -> float:
    """The smallest 1-2-5 spacing (m) at least `min_px` pixels apart."""
    for tick in TICKS:
        if tick >= min_px * metres_per_pixel:
            return tick
    return TICKS[-1]


@dataclass(frozen=True)
class TopDownFrame:
    """A top-down image's placement: pixel (col, row) covers world x = x0 + col * mpp
    (left edge) and y = y1 - row * mpp (top edge).

    Attributes:
        x0: world x of the left edge (m), on a 1-2-5 spacing of >= 16 pixels.
        y1: world y of the top edge (m), likewise.
        metres_per_pixel: the scale.
        width: pixels across.
        height: pixels down.
        tick: metres between the edge ticks.
    """

    x0: float
    y1: float
    metres_per_pixel: float
    width: int
    height: int
    tick: float

    @property
    def x1(self) -> float:
        return self.x0 + self.width * self.metres_per_pixel

    @property
    def y0(self) -> float:
        return self.y1 - self.height * self.metres_per_pixel

    def holds(self, lo: np.ndarray, hi: np.ndarray) -> bool:
        """Whether world xy bounds lo..hi lie inside the frame."""
        return bool(lo[0] >= self.x0 and lo[1] >= self.y0 and hi[0] <= self.x1 and hi[1] <= self.y1)

    def px(self, x: float, y: float) -> tuple[int, int]:
        """Integer (col, row) of world (x, y), for drawing."""
        mpp = self.metres_per_pixel
        return int(round((x - self.x0) / mpp)), int(round((self.y1 - y) / mpp))


def choose_frame(
    lo: np.ndarray,
    hi: np.ndarray,
    min_mpp: float,
    max_side: int,
    metres_per_pixel: float | None = None,
) -> TopDownFrame:
    """The frame for content within world xy bounds lo..hi ([2] each, metres).

    Args:
        lo: [2] lower x, y of the content.
        hi: [2] upper x, y.
        min_mpp: the finest scale allowed (a cell may span at most so many pixels).
        max_side: the cap on width and height in pixels.
        metres_per_pixel: a fixed scale, or None for the finest ladder scale that fits.

    Raises:
        InvalidInputError: a fixed scale that is not positive, or too fine for max_side.
    """
    if metres_per_pixel is not None:
        if not (
            isinstance(metres_per_pixel, numbers.Real)
            and not isinstance(metres_per_pixel, bool)
            and math.isfinite(metres_per_pixel)
            and metres_per_pixel > 0
        ):
            raise InvalidInputError(
                f"metres_per_pixel={metres_per_pixel!r} must be a positive number, e.g. 0.02."
            )
        scales: Sequence[float] = (float(metres_per_pixel),)
    else:
        scales = [s for s in SCALES if s >= min_mpp] or [SCALES[-1]]
    w = h = 0
    for mpp in scales:
        tick, snap = tick_spacing(mpp), tick_spacing(mpp, MIN_SNAP_PX)
        x0, x1 = math.floor(lo[0] / snap) * snap, math.ceil(hi[0] / snap) * snap
        y0, y1 = math.floor(lo[1] / snap) * snap, math.ceil(hi[1] / snap) * snap
        w = max(1, math.ceil((x1 - x0) / mpp - 1e-9))
        h = max(1, math.ceil((y1 - y0) / mpp - 1e-9))
        if max(w, h) <= max_side:
            return TopDownFrame(float(x0), float(y1), float(mpp), int(w), int(h), float(tick))
    raise InvalidInputError(
        f"at {scales[-1]:g} m per pixel this map needs {w}x{h} pixels, over max_side="
        f"{max_side}; give a coarser metres_per_pixel or a larger max_side."
    )


class Canvas:
    """Index-grid cells painted into a frame; `image()` gives the [H, W, 3] pixels.

    Args:
        frame: the image's placement.
        cell: metres per index-grid cell.
        background: RGB of unpainted pixels.
    """

    def __init__(self, frame: TopDownFrame, cell: float, background: Sequence[int]) -> None:
        self.frame = frame
        self.cell = cell
        self.direct = frame.metres_per_pixel >= cell  # several cells per pixel
        if self.direct:
            shape = (frame.height, frame.width)
        else:  # a cell grid over the frame (fewer cells than pixels), sampled per pixel
            self.i0 = math.floor(frame.x0 / cell)
            self.j1 = math.ceil(frame.y1 / cell) - 1
            ni = math.ceil(frame.x1 / cell) - self.i0
            nj = self.j1 - math.floor(frame.y0 / cell) + 1
            shape = (max(nj, 1), max(ni, 1))
        self.grid = np.empty((*shape, 3), np.uint8)
        self.grid[:] = background

    def rows_cols(self, ij: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(rows, cols, inside) of cells ij [K, 2] on the canvas."""
        ij = np.asarray(ij, np.int64).reshape(-1, 2)
        if self.direct:
            f, mpp = self.frame, self.frame.metres_per_pixel
            cols = np.floor(((ij[:, 0] + 0.5) * self.cell - f.x0) / mpp).astype(np.int64)
            rows = np.floor((f.y1 - (ij[:, 1] + 0.5) * self.cell) / mpp).astype(np.int64)
        else:
            cols = ij[:, 0] - self.i0
            rows = self.j1 - ij[:, 1]
        h, w = self.grid.shape[:2]
        inside = (rows >= 0) & (rows < h) & (cols >= 0) & (cols < w)
        return rows, cols, inside

    def paint(self, ij: np.ndarray, color: Sequence[int]) -> None:
        """Paint cells ij [K, 2] in one colour (later paint wins a shared pixel)."""
        rows, cols, inside = self.rows_cols(ij)
        self.grid[rows[inside], cols[inside]] = color

    def centres(self) -> tuple[np.ndarray, np.ndarray]:
        """World (x, y) of every canvas element's centre, each [h * w] (row-major)."""
        h, w = self.grid.shape[:2]
        if self.direct:
            f, mpp = self.frame, self.frame.metres_per_pixel
            x = f.x0 + (np.arange(w) + 0.5) * mpp
            y = f.y1 - (np.arange(h) + 0.5) * mpp
        else:
            x = (self.i0 + np.arange(w) + 0.5) * self.cell
            y = (self.j1 - np.arange(h) + 0.5) * self.cell
        return np.tile(x, h), np.repeat(y, w)

    def image(self) -> np.ndarray:  # -> [H, W, 3] uint8
        if self.direct:
            return self.grid
        f, mpp = self.frame, self.frame.metres_per_pixel
        x = f.x0 + (np.arange(f.width) + 0.5) * mpp
        y = f.y1 - (np.arange(f.height) + 0.5) * mpp
        cols = np.clip(
            np.floor(x / self.cell).astype(np.int64) - self.i0, 0, self.grid.shape[1] - 1
        )
        rows = np.clip(
            self.j1 - np.floor(y / self.cell).astype(np.int64), 0, self.grid.shape[0] - 1
        )
        return np.ascontiguousarray(self.grid[rows][:, cols])


def write_text(
    image: np.ndarray, text: str, xy: tuple[int, int], scale: float = FONT_SCALE
) -> None:
    """Write white text with a dark outline, readable on any colour."""
    cv2.putText(image, text, xy, FONT, scale, (0, 0, 0), 3, cv2.LINE_AA)
    cv2.putText(image, text, xy, FONT, scale, (255, 255, 255), 1, cv2.LINE_AA)


class Labels:
    """Writes text labels where they overlap no earlier label (or skips them)."""

    def __init__(self, image: np.ndarray) -> None:
        self.image = image
        self.taken: np.ndarray = np.zeros(image.shape[:2], bool)
        self.boxes: list[tuple[int, int, int, int]] = []
        self.skipped = 0

    def place(self, text: str, anchor: tuple[int, int], centred: bool = True) -> bool:
        """Write `text` at `anchor` (its centre, or its bottom-left) or the nearest free
        spot around it; False when all of them would overlap a label."""
        size, base = cv2.getTextSize(text, FONT, FONT_SCALE, 3)
        tw, th = int(size[0]), int(size[1])
        h, w = self.taken.shape
        x = anchor[0] - tw // 2 if centred else anchor[0]
        y = anchor[1] + th // 2 if centred else anchor[1]
        step_x, step_y = tw // 2 + 3, th + 3
        for dx, dy in ((0, 0), (step_x, 0), (-step_x, 0), (0, -step_y), (0, step_y),
                       (step_x, -step_y), (-step_x, -step_y), (step_x, step_y),
                       (-step_x, step_y)):  # fmt: skip
            left, bottom = int(np.clip(x + dx, 0, max(w - tw - 1, 0))), y + dy
            bottom = int(np.clip(bottom, th + 1, max(h - base - 1, th + 1)))
            box = (left, bottom - th - 1, left + tw + 1, bottom + base)
            if self.taken[box[1] : box[3], box[0] : box[2]].any():
                continue
            self.taken[box[1] : box[3], box[0] : box[2]] = True
            self.boxes.append(box)
            write_text(self.image, text, (left, bottom))
            return True
        self.skipped += 1
        return False


def draw_ticks(image: np.ndarray, frame: TopDownFrame, labels: Labels) -> None:
    """Ticks every frame.tick metres on the bottom (x) and left (y) edges, labelled."""
    h, w = image.shape[:2]
    tick, mpp = frame.tick, frame.metres_per_pixel
    for k in range(math.ceil(frame.x0 / tick - 1e-9), math.floor(frame.x1 / tick + 1e-9) + 1):
        col = int(round((k * tick - frame.x0) / mpp))
        if 0 <= col < w:
            cv2.line(image, (col, h - 1), (col, h - 6), TICK_RGB, 1)
            labels.place(f"{k * tick:g}", (col + 2, h - 8), centred=False)
    for k in range(math.ceil(frame.y0 / tick - 1e-9), math.floor(frame.y1 / tick + 1e-9) + 1):
        row = int(round((frame.y1 - k * tick) / mpp))
        if 0 <= row < h:
            cv2.line(image, (0, row), (5, row), TICK_RGB, 1)
            labels.place(f"{k * tick:g}", (7, row + 4), centred=False)
