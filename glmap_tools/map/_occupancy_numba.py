"""Numba kernel of `OccupancyGrid.compute_update`: the cells one frame sees free or blocked,
marked on a grid over the frame's extent (each cell once, an obstacle hit before free: a 2D
ray passing over a table top is no evidence that the table's cells are free).

The trigonometry (distances, bearings, each bearing bin's direction) comes from numpy; the
rest is min, max, products, sums and floors, the same in numba as in numpy.
"""

from __future__ import annotations

import numba
import numpy as np

MARK_FREE, MARK_BLOCKED = 1, 2


@numba.njit(cache=True, nogil=True)
def mark_cells(  # pragma: no cover - numba
    camera_xy: np.ndarray,
    xy: np.ndarray,
    is_floor: np.ndarray,
    is_obstacle: np.ndarray,
    dist: np.ndarray,
    bin_of_point: np.ndarray,
    bin_cos: np.ndarray,
    bin_sin: np.ndarray,
    cell_size: float,
) -> tuple[np.ndarray, int, int]:
    """(marks [rows, cols] uint8 over the cells' bounding box, its first x cell, first y
    cell): MARK_BLOCKED where an obstacle point falls, else MARK_FREE where a floor point or
    a sample of a free ray (per bearing bin, from the camera to one cell short of the bin's
    nearest obstacle, or of its farthest point) falls, 0 elsewhere.

    Args:
        camera_xy: [2]; xy: [N, 2] the points; is_floor, is_obstacle: [N] bool.
        dist: [N] each point's distance from the camera; bin_of_point: [N] its bearing bin
            (0-based); bin_cos, bin_sin: [bins] the direction of each bin's centre.
    """
    n_bins = bin_cos.shape[0]
    reach = np.zeros(n_bins)
    blocked = np.full(n_bins, np.inf)
    for p in range(xy.shape[0]):
        b = bin_of_point[p]
        reach[b] = max(reach[b], dist[p])
        if is_obstacle[p]:
            blocked[b] = min(blocked[b], dist[p])
    step = cell_size / 2.0
    length = np.empty(n_bins)
    n_steps = np.zeros(n_bins, np.int64)
    for b in range(n_bins):
        length[b] = min(reach[b], blocked[b]) - cell_size
        if length[b] > 0:
            n_steps[b] = np.int64(length[b] / step) + 1
    # The bounding box of every cell marked below.
    x_lo = y_lo = np.iinfo(np.int64).max
    x_hi = y_hi = np.iinfo(np.int64).min
    for p in range(xy.shape[0]):
        if is_floor[p] or is_obstacle[p]:
            cx = int(np.floor(xy[p, 0] / cell_size))
            cy = int(np.floor(xy[p, 1] / cell_size))
            x_lo, x_hi = min(x_lo, cx), max(x_hi, cx)
            y_lo, y_hi = min(y_lo, cy), max(y_hi, cy)
    for b in range(n_bins):
        for k in (0, n_steps[b] - 1):  # a ray is straight: its ends bound it
            if n_steps[b] == 0:
                break
            t = k * step
            cx = int(np.floor((camera_xy[0] + t * bin_cos[b]) / cell_size))
            cy = int(np.floor((camera_xy[1] + t * bin_sin[b]) / cell_size))
            x_lo, x_hi = min(x_lo, cx), max(x_hi, cx)
            y_lo, y_hi = min(y_lo, cy), max(y_hi, cy)
    if x_hi < x_lo:
        return np.zeros((0, 0), np.uint8), 0, 0
    marks = np.zeros((y_hi - y_lo + 1, x_hi - x_lo + 1), np.uint8)
    for p in range(xy.shape[0]):
        if is_obstacle[p]:
            cx = int(np.floor(xy[p, 0] / cell_size))
            cy = int(np.floor(xy[p, 1] / cell_size))
            marks[cy - y_lo, cx - x_lo] = MARK_BLOCKED
    for p in range(xy.shape[0]):
        if is_floor[p]:
            cx = int(np.floor(xy[p, 0] / cell_size))
            cy = int(np.floor(xy[p, 1] / cell_size))
            if marks[cy - y_lo, cx - x_lo] == 0:
                marks[cy - y_lo, cx - x_lo] = MARK_FREE
    for b in range(n_bins):
        for k in range(n_steps[b]):
            t = k * step
            cx = int(np.floor((camera_xy[0] + t * bin_cos[b]) / cell_size))
            cy = int(np.floor((camera_xy[1] + t * bin_sin[b]) / cell_size))
            if marks[cy - y_lo, cx - x_lo] == 0:
                marks[cy - y_lo, cx - x_lo] = MARK_FREE
    return marks, x_lo, y_lo
