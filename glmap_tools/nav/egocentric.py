"""The VLFM-like egocentric baseline: per-frame scores spread over the view cone, no units.

Each frame gives one score (how well what is visible matches the goal). It is written on
the cells of the view cone the depth image saw, weighted by a confidence that falls off as
cos^2 of the angle from the optical axis (1 on the axis, 0 at the edge of the field of view),
and fused per cell with the confidence-weighted average of VLFM:

    v <- (c_old v_old + c v) / (c_old + c),   c_old <- (c_old^2 + c^2) / (c_old + c)
"""

from __future__ import annotations

import math

import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.geometry.frame import RGBDFrame
from glmap_tools.map.occupancy import DenseOccupancy
from glmap_tools.nav.grid import Window
from glmap_tools.nav.value import ValueMap, as_window

DEPTH_STRIDE = 4
GROW = 64  # cells added on each side when the accumulator grows


def _within(angle: float, heading: float, half_fov: float) -> bool:
    """Whether `angle` lies within `half_fov` of `heading` (radians; a hair wider)."""
    return abs((angle - heading + math.pi) % (2 * math.pi) - math.pi) <= half_fov + 1e-9


class EgocentricValueMap:
    """Accumulates per-frame goal scores over the cells each frame's view cone covered.

    Args:
        cell_size: metres (use the map's cell size so windows line up).
        max_range: depth beyond this many metres is ignored.
    """

    def __init__(self, cell_size: float = 0.05, max_range: float = 5.0) -> None:
        if not (cell_size > 0 and max_range > 0):
            raise InvalidInputError(
                f"cell_size={cell_size!r} and max_range={max_range!r} must be positive metres."
            )
        self.cell_size = float(cell_size)
        self.max_range = float(max_range)
        self.origin = (0, 0)
        self.values = np.zeros((0, 0))  # [H, W] fused score
        self.confidence = np.zeros((0, 0))  # [H, W]
        self.frames = 0

    def _ensure(self, i_lo: int, j_lo: int, i_hi: int, j_hi: int) -> None:
        """Grow the arrays to hold cells i_lo..i_hi, j_lo..j_hi."""
        h, w = self.values.shape
        i0, j0 = self.origin
        if h and i0 <= i_lo and j0 <= j_lo and i_hi < i0 + w and j_hi < j0 + h:
            return
        if h == 0:
            ni0, nj0, ni1, nj1 = i_lo - GROW, j_lo - GROW, i_hi + GROW, j_hi + GROW
        else:
            ni0 = min(i0, i_lo - GROW) if i_lo < i0 else i0
            nj0 = min(j0, j_lo - GROW) if j_lo < j0 else j0
            ni1 = max(i0 + w - 1, i_hi + GROW) if i_hi >= i0 + w else i0 + w - 1
            nj1 = max(j0 + h - 1, j_hi + GROW) if j_hi >= j0 + h else j0 + h - 1
        values = np.zeros((nj1 - nj0 + 1, ni1 - ni0 + 1))
        conf = np.zeros_like(values)
        if h:
            values[j0 - nj0 : j0 - nj0 + h, i0 - ni0 : i0 - ni0 + w] = self.values
            conf[j0 - nj0 : j0 - nj0 + h, i0 - ni0 : i0 - ni0 + w] = self.confidence
        self.values, self.confidence, self.origin = values, conf, (ni0, nj0)

    def view_cone(self, frame: RGBDFrame) -> tuple[np.ndarray, np.ndarray]:
        """Cells the frame saw and their confidence: ([K, 2] int (i, j), [K] float in (0, 1]).

        A cell is in the cone when its bearing from the camera falls on an image column and
        it is no farther (in the plane) than the farthest depth point of that column.
        """
        intr = frame.intrinsics
        half_fov = math.atan2(intr.width / 2.0, intr.fx)
        cam = frame.pose.translation[:2]
        heading = frame.pose.heading
        depth = frame.depth[::DEPTH_STRIDE]
        valid = np.isfinite(depth) & (depth > 0) & (depth <= self.max_range)
        if not valid.any():
            return np.zeros((0, 2), np.int64), np.zeros(0)
        # Planar reach per image column: a level camera's column u looks along bearing
        # atan((u - cx) / fx) to the right, at planar distance z * sqrt(1 + x^2) of depth z.
        cols = (np.arange(intr.width) - intr.cx) / intr.fx
        planar = np.where(valid, depth * np.sqrt(1.0 + cols**2)[None, :], 0.0)
        reach = planar.max(axis=0)  # [W]
        s = self.cell_size
        r_max = float(reach.max())
        # Cells of the view's sector only: its bounding box (the camera, the arc's ends and
        # the axis directions the arc crosses), a cell wider for the cells' centres.
        arc = [heading - half_fov, heading + half_fov]
        arc += [k * math.pi / 2 for k in range(4) if _within(k * math.pi / 2, heading, half_fov)]
        xs = [cam[0]] + [cam[0] + r_max * math.cos(a) for a in arc]
        ys = [cam[1]] + [cam[1] + r_max * math.sin(a) for a in arc]
        i_lo, i_hi = math.floor(min(xs) / s) - 1, math.floor(max(xs) / s) + 1
        j_lo, j_hi = math.floor(min(ys) / s) - 1, math.floor(max(ys) / s) + 1
        jj, ii = np.mgrid[j_lo : j_hi + 1, i_lo : i_hi + 1]
        cx, cy = (ii + 0.5) * s - cam[0], (jj + 0.5) * s - cam[1]
        dist = np.hypot(cx, cy)
        ang = (np.arctan2(cy, cx) - heading + math.pi) % (2 * math.pi) - math.pi
        inside = np.abs(ang) < half_fov
        # Image x grows to the right, bearing to the left (counter-clockwise).
        u = np.round(intr.cx - intr.fx * np.tan(np.where(inside, ang, 0.0))).astype(np.int64)
        u = np.clip(u, 0, intr.width - 1)
        inside &= dist <= reach[u]
        conf = np.cos(ang[inside] / half_fov * (math.pi / 2)) ** 2
        cells = np.stack([ii[inside], jj[inside]], axis=1)
        keep = conf > 1e-6
        return cells[keep], conf[keep]

    def add_frame(self, frame: RGBDFrame, frame_score: float) -> int:
        """Fuse one frame's goal score into the cells of its view cone; returns the cell count.

        Args:
            frame: the posed RGB-D frame.
            frame_score: in [0, 1], how well the frame's content matches the goal.
        """
        if not (math.isfinite(frame_score) and 0.0 <= frame_score <= 1.0):
            raise InvalidInputError(f"frame_score={frame_score!r} must be in [0, 1].")
        cells, conf = self.view_cone(frame)
        self.frames += 1
        if len(cells) == 0:
            return 0
        self._ensure(
            int(cells[:, 0].min()),
            int(cells[:, 1].min()),
            int(cells[:, 0].max()),
            int(cells[:, 1].max()),
        )
        r = cells[:, 1] - self.origin[1]
        c = cells[:, 0] - self.origin[0]
        v_old, c_old = self.values[r, c], self.confidence[r, c]
        total = c_old + conf
        self.values[r, c] = (c_old * v_old + conf * frame_score) / total
        self.confidence[r, c] = (c_old**2 + conf**2) / total
        return int(len(cells))

    def as_value_map(self, window: Window | DenseOccupancy | None = None) -> ValueMap:
        """The fused scores over `window` (default: everything seen), as a ValueMap."""
        if window is None:
            h, w = self.values.shape
            win = Window(self.origin[0], self.origin[1], h, w)
        else:
            win = as_window(window)
        out = np.zeros(win.shape)
        h, w = self.values.shape
        r0, c0 = self.origin[1] - win.j0, self.origin[0] - win.i0
        rs0, cs0 = max(0, -r0), max(0, -c0)
        rs1, cs1 = min(h, win.height - r0), min(w, win.width - c0)
        if rs1 > rs0 and cs1 > cs0:
            out[r0 + rs0 : r0 + rs1, c0 + cs0 : c0 + cs1] = self.values[rs0:rs1, cs0:cs1]
        peak = float(out.max()) if out.size else 0.0
        return ValueMap(np.clip(out, 0.0, 1.0), win.origin, self.cell_size, peak, 0.0)
