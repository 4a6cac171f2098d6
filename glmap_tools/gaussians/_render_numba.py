"""Fast tile-based EWA splatting with numba; same contract as `render_reference`.

Pipeline: project every Gaussian in parallel (cull by near/far, opacity and the image
rectangle) -> one global stable depth sort of the survivors -> per-tile Gaussian lists by a
counting sort (each list stays front to back) -> rasterize tiles in parallel, each Gaussian
visiting only the pixels of its footprint inside the tile. The screen parameters are one
64-byte float32 row per Gaussian, read where they lie (no gather into depth order).

The rendering constants of `_render_common` are passed to the kernels as arguments, so a
cached compiled kernel never holds a stale copy of them.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import njit, prange

from glmap_tools.gaussians._render_bins import bin_kernel, depth_order_kernel
from glmap_tools.gaussians._render_common import (
    ALPHA_MAX,
    ALPHA_MIN,
    LOW_PASS,
    SIGMA_EXTENT,
    T_MIN,
    TILE,
    camera_setup,
)
from glmap_tools.gaussians.types import GaussianSet
from glmap_tools.geometry import Intrinsics, Pose

# Columns of the per-Gaussian screen parameters, one 64-byte float32 row per Gaussian. DU, DV:
# the screen mean minus the footprint rectangle's first column and row (small numbers, so
# float32 keeps them to ~1e-7 of the footprint size). OPACITY is negated for a thin footprint
# (see SPAN_*); a compact one keeps d^T conic d below M_COMPACT over its whole rectangle,
# which is then walked whole. DECAY_X, DECAY_Y, DECAY_XY = exp(-ca), exp(-cc), exp(-cb) step
# exp(-m/2) across pixels; each is stored as a float32 pair (value, remainder) that sums to
# the float64, as the recurrences multiply them up to a tile side of times.
(DU, DV, CONIC_A, CONIC_B, CONIC_C, OPACITY) = range(6)
(DECAY_X, DECAY_X_LO, DECAY_Y, DECAY_Y_LO, DECAY_XY, DECAY_XY_LO) = range(6, 12)
RED, GREEN, BLUE, DEPTH = range(12, 16)
N_PARAMS = 16
# Columns of the thin footprints' row spans (float32, unset for compact ones): on pixel row
# y the footprint is the column interval centre(y) +- sqrt(SPAN_HALF0 - SPAN_HALF1 dy^2)
# where the alpha can reach ALPHA_MIN, centre(y) = u - SPAN_SLOPE dy.
SPAN_HALF0, SPAN_HALF1, SPAN_SLOPE = range(3)
N_SPAN = 3
M_COMPACT = 200.0  # exp(-m/2) by forward differences stays far from under/overflow below this
PAD = 1e-6  # px slack on the footprint rectangle; the exact alpha test decides inside it
ROW_PAD = 1e-3  # px slack on the row spans, wider than the float32 rounding of their terms


@njit(parallel=True, cache=True)
def project_kernel(
    means: np.ndarray,  # [N, 3] float32
    covs: np.ndarray,  # [N, 3, 3] float32
    colors: np.ndarray,  # [N, 3] float32
    opacities: np.ndarray,  # [N] float32
    rot: np.ndarray,  # [3, 3] float64, camera_from_world
    trans: np.ndarray,  # [3] float64
    camera: np.ndarray,  # [8] float64: fx, fy, cx, cy, tan_lo x, y, tan_hi x, y
    width: int,
    height: int,
    near: float,
    far: float,
    low_pass: float,
    alpha_min: float,
    sigma_extent: float,
    tile_w: int,
    tile_h: int,
    params: np.ndarray,  # [N, N_PARAMS] float32, out
    spans: np.ndarray,  # [N, N_SPAN] float32, out (thin footprints only)
    depth: np.ndarray,  # [N] float64 out: camera z, the sort key
    rects: np.ndarray,  # [N, 4] int16 out: x0, x1, y0, y1 (inclusive pixel footprint)
    tiles: np.ndarray,  # [N, 4] int16 out: the tile columns and rows the footprint touches
    valid: np.ndarray,  # [N] bool, out
) -> None:
    """EWA projection of every Gaussian; `valid[i]` is False for culled ones."""
    fx, fy, cx, cy = camera[0], camera[1], camera[2], camera[3]
    for i in prange(means.shape[0]):
        valid[i] = False
        op = np.float64(opacities[i])
        if not op >= alpha_min:  # can never reach the alpha threshold (or NaN)
            continue
        mx, my, mz = np.float64(means[i, 0]), np.float64(means[i, 1]), np.float64(means[i, 2])
        x = rot[0, 0] * mx + rot[0, 1] * my + rot[0, 2] * mz + trans[0]
        y = rot[1, 0] * mx + rot[1, 1] * my + rot[1, 2] * mz + trans[1]
        z = rot[2, 0] * mx + rot[2, 1] * my + rot[2, 2] * mz + trans[2]
        if not (z >= near and z <= far):
            continue
        u = fx * x / z + cx
        v = fy * y / z + cy
        if not (math.isfinite(u) and math.isfinite(v)):
            continue
        # Jacobian of the projection at the mean, x/z and y/z clamped.
        tx = min(max(x / z, camera[4]), camera[6]) * z
        ty = min(max(y / z, camera[5]), camera[7]) * z
        j00 = fx / z
        j02 = -fx * tx / (z * z)
        j11 = fy / z
        j12 = -fy * ty / (z * z)
        # Rows p, q of M = J W; cov2d = M Sigma M^T (Sigma symmetric).
        p0 = j00 * rot[0, 0] + j02 * rot[2, 0]
        p1 = j00 * rot[0, 1] + j02 * rot[2, 1]
        p2 = j00 * rot[0, 2] + j02 * rot[2, 2]
        q0 = j11 * rot[1, 0] + j12 * rot[2, 0]
        q1 = j11 * rot[1, 1] + j12 * rot[2, 1]
        q2 = j11 * rot[1, 2] + j12 * rot[2, 2]
        s00 = np.float64(covs[i, 0, 0])
        s01 = np.float64(covs[i, 0, 1])
        s02 = np.float64(covs[i, 0, 2])
        s11 = np.float64(covs[i, 1, 1])
        s12 = np.float64(covs[i, 1, 2])
        s22 = np.float64(covs[i, 2, 2])
        sq0 = s00 * q0 + s01 * q1 + s02 * q2
        sq1 = s01 * q0 + s11 * q1 + s12 * q2
        sq2 = s02 * q0 + s12 * q1 + s22 * q2
        a = p0 * (s00 * p0 + s01 * p1 + s02 * p2)
        a += p1 * (s01 * p0 + s11 * p1 + s12 * p2)
        a += p2 * (s02 * p0 + s12 * p1 + s22 * p2)
        b = p0 * sq0 + p1 * sq1 + p2 * sq2
        c = q0 * sq0 + q1 * sq1 + q2 * sq2
        a += low_pass
        c += low_pass
        det = a * c - b * b
        if not det > 0.0:
            continue
        mid = 0.5 * (a + c)
        radius = math.ceil(sigma_extent * math.sqrt(mid + math.sqrt(max(mid * mid - det, 0.0))))
        # alpha >= alpha_min  <=>  d^T conic d <= m_cut; its ellipse bounds the footprint.
        m_cut = 2.0 * math.log(op / alpha_min) + PAD
        ext_x = min(radius, math.sqrt(m_cut * a) + PAD)
        ext_y = min(radius, math.sqrt(m_cut * c) + PAD)
        x0 = max(math.ceil(u - ext_x), 0.0)
        x1 = min(math.floor(u + ext_x), width - 1.0)
        y0 = max(math.ceil(v - ext_y), 0.0)
        y1 = min(math.floor(v + ext_y), height - 1.0)
        if not (x0 <= x1 and y0 <= y1):
            continue
        ca = c / det
        cb = -b / det
        cc = a / det
        # The rasterizer computes from the float32 values; derive the rest from them too.
        ca32 = np.float32(ca)
        cb32 = np.float32(cb)
        cc32 = np.float32(cc)
        ca = np.float64(ca32)
        cb = np.float64(cb32)
        cc = np.float64(cc32)
        params[i, DU] = u - x0
        params[i, DV] = v - y0
        params[i, CONIC_A] = ca32
        params[i, CONIC_B] = cb32
        params[i, CONIC_C] = cc32
        for col, rate in ((DECAY_X, ca), (DECAY_Y, cc), (DECAY_XY, cb)):
            decay = math.exp(-rate)
            decay32 = np.float32(decay)
            params[i, col] = decay32
            params[i, col + 1] = decay - np.float64(decay32)
        m_corner = 0.0
        for cx_ in (x0, x1):
            for cy_ in (y0, y1):
                ddx = cx_ - u
                ddy = cy_ - v
                m_corner = max(m_corner, ca * ddx * ddx + 2.0 * cb * ddx * ddy + cc * ddy * ddy)
        if m_corner <= M_COMPACT:
            params[i, OPACITY] = op
        else:
            params[i, OPACITY] = -op
            spans[i, SPAN_HALF0] = m_cut / ca
            spans[i, SPAN_HALF1] = (ca * cc - cb * cb) / (ca * ca)
            spans[i, SPAN_SLOPE] = cb / ca
        params[i, RED] = colors[i, 0]
        params[i, GREEN] = colors[i, 1]
        params[i, BLUE] = colors[i, 2]
        params[i, DEPTH] = z
        depth[i] = z
        rects[i, 0] = int(x0)
        rects[i, 1] = int(x1)
        rects[i, 2] = int(y0)
        rects[i, 3] = int(y1)
        tiles[i, 0] = int(x0) // tile_w
        tiles[i, 1] = int(x1) // tile_w
        tiles[i, 2] = int(y0) // tile_h
        tiles[i, 3] = int(y1) // tile_h
        valid[i] = True


@njit(cache=True, inline="always")
def _composite_row(
    row: int,
    px_lo: int,
    px_hi: int,
    gauss: float,
    ratio: float,
    decay: float,
    op: float,
    red: float,
    green: float,
    blue: float,
    z: float,
    alpha_min: float,
    alpha_max: float,
    t_min: float,
    trans: np.ndarray,  # [P] tile transmittance
    acc: np.ndarray,  # [P, 4] tile r, g, b, z sums
    done: np.ndarray,  # [P] bool, pixel terminated
    n_done: int,
) -> int:
    """Composite one Gaussian over pixels px_lo..px_hi of a tile row; returns n_done.

    `gauss` is exp(-m/2) at px_lo and `ratio` its ratio to the next pixel; successive
    ratios shrink by `decay` = exp(-conic_a).
    """
    for px in range(px_lo, px_hi + 1):
        p = row + px
        a = min(alpha_max, op * gauss)
        gauss *= ratio
        ratio *= decay
        if done[p] or a < alpha_min:
            continue
        next_t = trans[p] * (1.0 - a)
        if next_t < t_min:
            done[p] = True
            n_done += 1
            continue
        w = a * trans[p]
        acc[p, 0] += w * red
        acc[p, 1] += w * green
        acc[p, 2] += w * blue
        acc[p, 3] += w * z
        trans[p] = next_t
    return n_done


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
    """Front-to-back alpha compositing of each tile's Gaussians, tiles in parallel."""
    height, width = alpha.shape
    n_tiles = offsets.shape[0] - 1
    # Tiles in a scattered order (a stride coprime to n_tiles), so that the threads' equal
    # shares of iterations cover the image evenly even when the Gaussians do not.
    stride = tile_stride
    for i in prange(n_tiles):
        t = (i * stride) % n_tiles
        tx0 = (t % tiles_x) * tile_w
        ty0 = (t // tiles_x) * tile_h
        tx1 = min(tx0 + tile_w, width) - 1
        ty1 = min(ty0 + tile_h, height) - 1
        n_pixels = (tx1 - tx0 + 1) * (ty1 - ty0 + 1)
        trans = np.ones(tile_w * tile_h)
        acc = np.zeros((tile_w * tile_h, 4))  # r, g, b, z sums
        n_done = 0
        done = np.zeros(tile_w * tile_h, dtype=np.bool_)
        row_left = np.zeros(tile_h, dtype=np.int64)  # pixels of each row not yet terminated
        row_left[: ty1 - ty0 + 1] = tx1 - tx0 + 1
        for k in range(offsets[t], offsets[t + 1]):
            g = lists[k]
            # Only the rows of the footprint between its first and last live row.
            y_lo = max(np.int64(rects[g, 2]), ty0)
            y_hi = min(np.int64(rects[g, 3]), ty1)
            while y_lo <= y_hi and row_left[y_lo - ty0] == 0:
                y_lo += 1
            while y_hi >= y_lo and row_left[y_hi - ty0] == 0:
                y_hi -= 1
            if y_lo > y_hi:
                continue
            x0 = np.int64(rects[g, 0])
            y0 = np.int64(rects[g, 2])
            u = x0 + np.float64(params[g, DU])
            v = y0 + np.float64(params[g, DV])
            ca = np.float64(params[g, CONIC_A])
            cb = np.float64(params[g, CONIC_B])
            cc = np.float64(params[g, CONIC_C])
            op = np.float64(params[g, OPACITY])
            decay_x = np.float64(params[g, DECAY_X]) + np.float64(params[g, DECAY_X_LO])
            red = np.float64(params[g, RED])
            green = np.float64(params[g, GREEN])
            blue = np.float64(params[g, BLUE])
            z = np.float64(params[g, DEPTH])
            x_lo = max(x0, tx0)
            x_hi = min(np.int64(rects[g, 1]), tx1)
            if op > 0.0:
                # Whole rectangle; exp(-m/2) by forward differences: m is quadratic in
                # (px, py), so the ratios of exp(-m/2) between neighbours (ratio_x to the
                # right, ratio_y below) change by constant factors per step.
                dx = x_lo - u
                dy = y_lo - v
                start = math.exp(-0.5 * (ca * dx * dx + 2.0 * cb * dx * dy + cc * dy * dy))
                ratio_x = math.exp(-(ca * dx + cb * dy + 0.5 * ca))
                ratio_y = math.exp(-(cc * dy + cb * dx + 0.5 * cc))
                decay_y = np.float64(params[g, DECAY_Y]) + np.float64(params[g, DECAY_Y_LO])
                decay_xy = np.float64(params[g, DECAY_XY]) + np.float64(params[g, DECAY_XY_LO])
                for py in range(y_lo, y_hi + 1):
                    if row_left[py - ty0] > 0:
                        before = n_done
                        n_done = _composite_row(
                            (py - ty0) * tile_w - tx0,
                            x_lo,
                            x_hi,
                            start,
                            ratio_x,
                            decay_x,
                            op,
                            red,
                            green,
                            blue,
                            z,
                            alpha_min,
                            alpha_max,
                            t_min,
                            trans,
                            acc,
                            done,
                            n_done,
                        )
                        row_left[py - ty0] -= n_done - before
                    start *= ratio_y
                    ratio_x *= decay_xy
                    ratio_y *= decay_y
            else:
                # Thin, slanted footprints: only the columns of each row inside the ellipse
                # where alpha can reach alpha_min.
                op = -op
                half0 = np.float64(spans[g, SPAN_HALF0])
                half1 = np.float64(spans[g, SPAN_HALF1])
                slope = np.float64(spans[g, SPAN_SLOPE])
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
                    before = n_done
                    n_done = _composite_row(
                        (py - ty0) * tile_w - tx0,
                        px_lo,
                        px_hi,
                        start,
                        ratio_x,
                        decay_x,
                        op,
                        red,
                        green,
                        blue,
                        z,
                        alpha_min,
                        alpha_max,
                        t_min,
                        trans,
                        acc,
                        done,
                        n_done,
                    )
                    row_left[py - ty0] -= n_done - before
            if n_done == n_pixels:
                break
        for py in range(ty0, ty1 + 1):
            for px in range(tx0, tx1 + 1):
                p = (py - ty0) * tile_w + px - tx0
                tr = trans[p]
                for ch in range(3):
                    rgb[py, px, ch] = min(max(acc[p, ch] + tr * background[ch], 0.0), 1.0)
                opacity = 1.0 - tr
                alpha[py, px] = opacity
                depth[py, px] = acc[p, 3] / opacity if opacity > 0.0 else 0.0


def scatter_stride(n: int) -> int:
    """A stride coprime to n near n / golden ratio: k -> k * stride mod n scatters 0..n-1."""
    stride = max(1, int(n * 0.618)) | 1
    while math.gcd(stride, n) != 1:
        stride += 2
    return stride


def render_fast(
    gaussians: GaussianSet,
    pose: Pose,
    intrinsics: Intrinsics,
    background: tuple[float, float, float],
    near: float,
    far: float,
    tile: tuple[int, int] = (TILE, TILE),
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Tile-rasterize `gaussians`; same outputs as `render_reference.render_reference`.

    Args:
        tile: (width, height) of a tile in pixels; the result does not depend on it.
    """
    cam = camera_setup(pose, intrinsics)
    k = intrinsics
    w, h = int(k.width), int(k.height)
    n = len(gaussians)
    tile_w, tile_h = tile
    tiles_x = (w + tile_w - 1) // tile_w
    n_tiles = tiles_x * ((h + tile_h - 1) // tile_h)
    params = np.empty((n, N_PARAMS), dtype=np.float32)
    spans = np.empty((n, N_SPAN), dtype=np.float32)
    z = np.empty(n, dtype=np.float64)
    rects = np.empty((n, 4), dtype=np.int16)
    tiles = np.empty((n, 4), dtype=np.int16)
    valid = np.empty(n, dtype=np.bool_)
    camera = np.array([k.fx, k.fy, k.cx, k.cy, *cam.tan_lo, *cam.tan_hi], dtype=np.float64)
    project_kernel(
        gaussians.means,
        gaussians.covs,
        gaussians.colors,
        gaussians.opacities,
        cam.rotation,
        cam.translation,
        camera,
        w,
        h,
        float(near),
        float(far),
        LOW_PASS,
        ALPHA_MIN,
        SIGMA_EXTENT,
        tile_w,
        tile_h,
        params,
        spans,
        z,
        rects,
        tiles,
        valid,
    )
    order = depth_order_kernel(valid, z)
    offsets, lists = bin_kernel(order, tiles, tiles_x, n_tiles, numba.get_num_threads())
    rgb = np.empty((h, w, 3), dtype=np.float32)
    depth = np.empty((h, w), dtype=np.float32)
    alpha = np.empty((h, w), dtype=np.float32)
    rasterize_kernel(
        params,
        spans,
        rects,
        offsets,
        lists,
        tile_w,
        tile_h,
        tiles_x,
        scatter_stride(n_tiles),
        np.asarray(background, dtype=np.float64),
        ALPHA_MIN,
        ALPHA_MAX,
        T_MIN,
        rgb,
        depth,
        alpha,
    )
    return rgb, depth, alpha
