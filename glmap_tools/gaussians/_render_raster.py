"""Tile rasterization of the projected Gaussians (numba): front-to-back alpha compositing.

A tile keeps its pixels' transmittance and r, g, b, z sums as the rows of one float64 array
and walks its depth-ordered list; a pixel that has stopped keeps its transmittance negated
(it is never below T_MIN > 0 otherwise), so one load tells both. exp(-m/2) over a compact
footprint comes from forward differences: the first row by a short recurrence along x, each
row below by one vector step per column (m is quadratic in the pixel coordinates, so the
ratios between neighbours change by constant factors). The compositing of a row is written
without branches and with unsigned indices, so LLVM vectorises it, and runs over whole
vectors (the pixels past a span get alpha 0, which changes nothing). The rows of the
Gaussians a few list entries ahead are prefetched: they lie scattered in memory.

Measured against the scalar per-pixel kernel it replaces (single thread, same images):
2.2-2.3x at 50k Gaussians / 320x240 and at 1M / 640x480.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from glmap_tools.gaussians._prefetch import prefetch_row
from glmap_tools.gaussians._render_layout import (
    CONIC_A,
    CONIC_B,
    CONIC_C,
    DECAY_X,
    DECAY_X_LO,
    DECAY_XY,
    DECAY_XY_LO,
    DECAY_Y,
    DECAY_Y_LO,
    DEPTH,
    DU,
    DV,
    OPACITY,
    RED,
    ROW_PAD,
    SPAN_HALF0,
    SPAN_HALF1,
    SPAN_SLOPE,
)

# Rows of a tile's state array [N_STATE, tile pixels].
TRANS, SUM_R, SUM_G, SUM_B, SUM_Z = range(5)
N_STATE = 5
LANES = 4  # float64 lanes of the vector loop LLVM makes of `_composite_span` (AVX2)
AHEAD = 4  # list entries between a Gaussian's prefetch and its use


@njit(cache=True, inline="always")
def _row_gauss(gauss: np.ndarray, n: int, start: float, ratio: float, decay: float) -> None:
    """exp(-m/2) along n pixels of a row by forward differences, into gauss[:n].

    `start` is the value at the first pixel, `ratio` its ratio to the next; successive
    ratios shrink by `decay` = exp(-conic_a).
    """
    for i in range(n):
        gauss[i] = start
        start *= ratio
        ratio *= decay


@njit(cache=True, inline="always")
def _pad_span(gauss: np.ndarray, n: int) -> int:
    """n rounded up to whole vectors of LANES pixels, the pixels past n given exp(-m/2) = 0.

    alpha = 0 < alpha_min leaves a padded pixel as it is (it may lie in the next row of the
    tile, or in the state's LANES spare columns), and the vector loop then needs no scalar
    remainder.
    """
    padded = (n + LANES - 1) // LANES * LANES
    for i in range(n, padded):
        gauss[i] = 0.0
    return padded


@njit(cache=True, inline="always")
def _composite_span(
    state: np.ndarray,  # [N_STATE, P] tile transmittance (negated once stopped) and sums
    base: int,
    n: int,
    gauss: np.ndarray,  # [>= n] exp(-m/2) of the span's pixels
    op: float,
    red: float,
    green: float,
    blue: float,
    z: float,
    alpha_min: float,
    alpha_max: float,
    t_min: float,
) -> int:
    """Composite one Gaussian over tile pixels base..base+n-1 of a row; returns the stops.

    alpha = min(alpha_max, op exp(-m/2)). Branch-free (selects only) so that the loop
    vectorises: a pixel is skipped when it has stopped (T < 0) or alpha < alpha_min, stops
    (T negated) when T (1 - alpha) < t_min, and otherwise adds alpha T times the colour and
    depth.
    """
    stopped = 0
    first = np.uint64(base)  # unsigned indices: no negative-index wrap, so LLVM vectorises
    for j in range(n):
        i = np.uint64(j)
        p = first + i
        a = min(alpha_max, op * gauss[i])
        t = state[TRANS, p]
        next_t = t * (1.0 - a)
        live = (a >= alpha_min) & (t > 0.0)
        stop = live & (next_t < t_min)
        keep = live & (next_t >= t_min)
        w = a * t if keep else 0.0
        state[SUM_R, p] += w * red
        state[SUM_G, p] += w * green
        state[SUM_B, p] += w * blue
        state[SUM_Z, p] += w * z
        state[TRANS, p] = next_t if keep else (-t if stop else t)
        stopped += stop
    return stopped


@njit(cache=True)
def _live_rows(
    rects: np.ndarray, g: int, ty0: int, ty1: int, row_left: np.ndarray
) -> tuple[int, int]:
    """The rows of Gaussian g's footprint in the tile between its first and last live row."""
    y_lo = max(int(rects[g, 2]), ty0)
    y_hi = min(int(rects[g, 3]), ty1)
    while y_lo <= y_hi and row_left[y_lo - ty0] == 0:
        y_lo += 1
    while y_hi >= y_lo and row_left[y_hi - ty0] == 0:
        y_hi -= 1
    return y_lo, y_hi


@njit(cache=True)
def _splat_compact(
    params: np.ndarray,  # [N, N_PARAMS] float32
    g: int,
    u: float,
    v: float,
    x_lo: int,
    x_hi: int,
    y_lo: int,
    y_hi: int,
    tx0: int,
    ty0: int,
    tile_w: int,
    state: np.ndarray,  # [N_STATE, P]
    row_left: np.ndarray,  # [tile_h] int64
    gauss: np.ndarray,  # [tile_w] float64 scratch: exp(-m/2) along a row
    down: np.ndarray,  # [tile_w] float64 scratch: its ratios to the row below
    alpha_min: float,
    alpha_max: float,
    t_min: float,
) -> int:
    """Composite a compact footprint over its whole rectangle in the tile; returns stops.

    exp(-m/2) by forward differences: m is quadratic in (px, py), so the ratios of
    exp(-m/2) between neighbours (ratio_x to the right, ratio_y below) change by constant
    factors per step.
    """
    ca = np.float64(params[g, CONIC_A])
    cb = np.float64(params[g, CONIC_B])
    cc = np.float64(params[g, CONIC_C])
    op = np.float64(params[g, OPACITY])
    decay_x = np.float64(params[g, DECAY_X]) + np.float64(params[g, DECAY_X_LO])
    decay_y = np.float64(params[g, DECAY_Y]) + np.float64(params[g, DECAY_Y_LO])
    decay_xy = np.float64(params[g, DECAY_XY]) + np.float64(params[g, DECAY_XY_LO])
    red = np.float64(params[g, RED])
    green = np.float64(params[g, RED + 1])
    blue = np.float64(params[g, RED + 2])
    z = np.float64(params[g, DEPTH])
    dx = x_lo - u
    dy = y_lo - v
    start = math.exp(-0.5 * (ca * dx * dx + 2.0 * cb * dx * dy + cc * dy * dy))
    ratio_x = math.exp(-(ca * dx + cb * dy + 0.5 * ca))
    ratio_y = math.exp(-(cc * dy + cb * dx + 0.5 * cc))
    n = x_hi - x_lo + 1
    # The first row's exp(-m/2) and ratios to the row below; each row below is then one
    # vector step: gauss *= ratio_down, ratio_down *= decay_y.
    for i in range(n):
        gauss[i] = start
        down[i] = ratio_y
        start *= ratio_x
        ratio_x *= decay_x
        ratio_y *= decay_xy
    padded = _pad_span(gauss, n)
    for i in range(n, padded):
        down[i] = 0.0
    n = padded
    stopped = 0
    for py in range(y_lo, y_hi + 1):
        if row_left[py - ty0] > 0:
            now = _composite_span(
                state, (py - ty0) * tile_w + x_lo - tx0, n, gauss, op, red, green, blue, z,
                alpha_min, alpha_max, t_min,
            )  # fmt: skip
            row_left[py - ty0] -= now
            stopped += now
        for i in range(n):
            gauss[i] *= down[i]
            down[i] *= decay_y
    return stopped


@njit(cache=True)
def _splat_thin(
    params: np.ndarray,  # [N, N_PARAMS] float32
    spans: np.ndarray,  # [N, N_SPAN] float32
    g: int,
    u: float,
    v: float,
    x_lo: int,
    x_hi: int,
    y_lo: int,
    y_hi: int,
    tx0: int,
    ty0: int,
    tile_w: int,
    state: np.ndarray,  # [N_STATE, P]
    row_left: np.ndarray,  # [tile_h] int64
    gauss: np.ndarray,  # [tile_w] float64 scratch: exp(-m/2) along a row
    alpha_min: float,
    alpha_max: float,
    t_min: float,
) -> int:
    """Composite a thin, slanted footprint: per row only the columns inside the ellipse
    where alpha can reach alpha_min (so the recurrences never under- or overflow)."""
    ca = np.float64(params[g, CONIC_A])
    cb = np.float64(params[g, CONIC_B])
    cc = np.float64(params[g, CONIC_C])
    op = -np.float64(params[g, OPACITY])
    decay_x = np.float64(params[g, DECAY_X]) + np.float64(params[g, DECAY_X_LO])
    red = np.float64(params[g, RED])
    green = np.float64(params[g, RED + 1])
    blue = np.float64(params[g, RED + 2])
    z = np.float64(params[g, DEPTH])
    half0 = np.float64(spans[g, SPAN_HALF0])
    half1 = np.float64(spans[g, SPAN_HALF1])
    slope = np.float64(spans[g, SPAN_SLOPE])
    stopped = 0
    for py in range(y_lo, y_hi + 1):
        dy = py - v
        half2 = half0 - half1 * dy * dy
        if half2 < 0.0:
            continue
        half = math.sqrt(half2) + ROW_PAD
        centre = u - slope * dy
        px_lo = max(x_lo, math.ceil(centre - half))
        px_hi = min(x_hi, math.floor(centre + half))
        if px_lo > px_hi or row_left[py - ty0] == 0:
            continue
        dx = px_lo - u
        start = math.exp(-0.5 * (ca * dx * dx + 2.0 * cb * dx * dy + cc * dy * dy))
        ratio_x = math.exp(-(ca * dx + cb * dy + 0.5 * ca))
        n = px_hi - px_lo + 1
        _row_gauss(gauss, n, start, ratio_x, decay_x)
        n = _pad_span(gauss, n)
        now = _composite_span(
            state, (py - ty0) * tile_w + px_lo - tx0, n, gauss, op, red, green, blue, z,
            alpha_min, alpha_max, t_min,
        )  # fmt: skip
        row_left[py - ty0] -= now
        stopped += now
    return stopped


@njit(cache=True)
def _write_tile(
    state: np.ndarray,  # [N_STATE, P]
    tx0: int,
    tx1: int,
    ty0: int,
    ty1: int,
    tile_w: int,
    background: np.ndarray,  # [3] float64
    rgb: np.ndarray,  # [H, W, 3] float32, out
    depth: np.ndarray,  # [H, W] float32, out
    alpha: np.ndarray,  # [H, W] float32, out
) -> None:
    """rgb = C + T background, alpha = 1 - T, depth = D / alpha (0 where alpha = 0)."""
    for py in range(ty0, ty1 + 1):
        for px in range(tx0, tx1 + 1):
            p = (py - ty0) * tile_w + px - tx0
            tr = abs(state[TRANS, p])
            for ch in range(3):
                rgb[py, px, ch] = min(max(state[SUM_R + ch, p] + tr * background[ch], 0.0), 1.0)
            opacity = 1.0 - tr
            alpha[py, px] = opacity
            depth[py, px] = state[SUM_Z, p] / opacity if opacity > 0.0 else 0.0


@njit(cache=True)
def _rasterize_tile(
    t: int,
    params: np.ndarray,  # [N, N_PARAMS] float32
    spans: np.ndarray,  # [N, N_SPAN] float32
    rects: np.ndarray,  # [N, 4] int16
    offsets: np.ndarray,  # [n_tiles + 1] int64
    lists: np.ndarray,  # [K] int32
    tile_w: int,
    tile_h: int,
    tiles_x: int,
    background: np.ndarray,  # [3] float64
    alpha_min: float,
    alpha_max: float,
    t_min: float,
    rgb: np.ndarray,  # [H, W, 3] float32, out
    depth: np.ndarray,  # [H, W] float32, out
    alpha: np.ndarray,  # [H, W] float32, out
) -> None:
    """Composite tile t's list front to back and write its pixels."""
    height, width = alpha.shape
    tx0 = (t % tiles_x) * tile_w
    ty0 = (t // tiles_x) * tile_h
    tx1 = min(tx0 + tile_w, width) - 1
    ty1 = min(ty0 + tile_h, height) - 1
    n_pixels = (tx1 - tx0 + 1) * (ty1 - ty0 + 1)
    state = np.zeros((N_STATE, tile_w * tile_h + LANES))
    state[TRANS] = 1.0
    gauss = np.empty(tile_w + LANES)
    down = np.empty(tile_w + LANES)
    row_left = np.zeros(tile_h, dtype=np.int64)  # pixels of each row not yet stopped
    row_left[: ty1 - ty0 + 1] = tx1 - tx0 + 1
    n_done = 0
    last = offsets[t + 1] - 1
    for k in range(offsets[t], offsets[t + 1]):
        ahead = lists[min(k + AHEAD, last)]
        prefetch_row(params, ahead)
        prefetch_row(rects, ahead)
        g = lists[k]
        y_lo, y_hi = _live_rows(rects, g, ty0, ty1, row_left)
        if y_lo > y_hi:
            continue
        x0 = int(rects[g, 0])
        u = x0 + np.float64(params[g, DU])
        v = int(rects[g, 2]) + np.float64(params[g, DV])
        x_lo = max(x0, tx0)
        x_hi = min(int(rects[g, 1]), tx1)
        if params[g, OPACITY] > 0.0:
            n_done += _splat_compact(
                params, g, u, v, x_lo, x_hi, y_lo, y_hi, tx0, ty0, tile_w, state, row_left,
                gauss, down, alpha_min, alpha_max, t_min,
            )  # fmt: skip
        else:
            n_done += _splat_thin(
                params, spans, g, u, v, x_lo, x_hi, y_lo, y_hi, tx0, ty0, tile_w, state,
                row_left, gauss, alpha_min, alpha_max, t_min,
            )  # fmt: skip
        if n_done == n_pixels:
            break
    _write_tile(state, tx0, tx1, ty0, ty1, tile_w, background, rgb, depth, alpha)


@njit(parallel=True, cache=True)
def rasterize_kernel(
    params: np.ndarray,  # [N, N_PARAMS] float32
    spans: np.ndarray,  # [N, N_SPAN] float32
    rects: np.ndarray,  # [N, 4] int16
    offsets: np.ndarray,  # [n_tiles + 1] int64
    lists: np.ndarray,  # [K] int32, rows of params, each tile's front to back
    tile_w: int,
    tile_h: int,
    tiles_x: int,
    tile_stride: int,
    background: np.ndarray,  # [3] float64
    alpha_min: float,
    alpha_max: float,
    t_min: float,
    rgb: np.ndarray,  # [H, W, 3] float32, out
    depth: np.ndarray,  # [H, W] float32, out
    alpha: np.ndarray,  # [H, W] float32, out
) -> None:
    """Front-to-back alpha compositing of each tile's Gaussians, tiles in parallel.

    Tiles go in a scattered order (a stride coprime to n_tiles), so that the threads' equal
    shares of iterations cover the image evenly even when the Gaussians do not.
    """
    n_tiles = offsets.shape[0] - 1
    for i in prange(n_tiles):
        _rasterize_tile(
            (i * tile_stride) % n_tiles, params, spans, rects, offsets, lists, tile_w, tile_h,
            tiles_x, background, alpha_min, alpha_max, t_min, rgb, depth, alpha,
        )  # fmt: skip
