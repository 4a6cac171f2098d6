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
import time

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
    CameraSetup,
    camera_setup,
)
from glmap_tools.gaussians._render_layout import (
    BLUE,
    CONIC_A,
    CONIC_B,
    CONIC_C,
    DECAY_X,
    DECAY_XY,
    DECAY_Y,
    DEPTH,
    DU,
    DV,
    GREEN,
    M_COMPACT,
    N_PARAMS,
    N_SPAN,
    OPACITY,
    PAD,
    RED,
    SPAN_HALF0,
    SPAN_HALF1,
    SPAN_SLOPE,
)
from glmap_tools.gaussians._render_raster import rasterize_kernel
from glmap_tools.gaussians.types import GaussianSet
from glmap_tools.geometry import Intrinsics, Pose


@njit(cache=True, inline="always")
def _screen_covariance(
    covs: np.ndarray,  # [N, 3, 3] float32
    i: int,
    x: float,
    y: float,
    z: float,
    rot: np.ndarray,  # [3, 3] float64, camera_from_world
    camera: np.ndarray,  # [8] float64: fx, fy, cx, cy, tan_lo x, y, tan_hi x, y
    low_pass: float,
) -> tuple[float, float, float]:
    """(a, b, c) of Sigma' = J W Sigma W^T J^T + low_pass I, px^2 (J: clamped Jacobian)."""
    fx, fy = camera[0], camera[1]
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
    return a + low_pass, b, c + low_pass


@njit(cache=True, inline="always")
def _footprint(
    u: float,
    v: float,
    a: float,
    b: float,
    c: float,
    op: float,
    width: int,
    height: int,
    alpha_min: float,
    sigma_extent: float,
) -> tuple[float, float, float, float, float]:
    """(x0, x1, y0, y1, m_cut): the pixel rectangle a Gaussian can reach, clipped to the image.

    The 3-sigma square of half-side ceil(sigma_extent sqrt(lambda_max)) intersected with the
    bounding box of d^T conic d <= m_cut = 2 ln(op / alpha_min), outside which
    alpha < alpha_min. Empty (x0 > x1 or y0 > y1) when it misses the image.
    """
    det = a * c - b * b
    mid = 0.5 * (a + c)
    radius = math.ceil(sigma_extent * math.sqrt(mid + math.sqrt(max(mid * mid - det, 0.0))))
    m_cut = 2.0 * math.log(op / alpha_min) + PAD
    ext_x = min(radius, math.sqrt(m_cut * a) + PAD)
    ext_y = min(radius, math.sqrt(m_cut * c) + PAD)
    x0 = max(math.ceil(u - ext_x), 0.0)
    x1 = min(math.floor(u + ext_x), width - 1.0)
    y0 = max(math.ceil(v - ext_y), 0.0)
    y1 = min(math.floor(v + ext_y), height - 1.0)
    return x0, x1, y0, y1, m_cut


@njit(cache=True, inline="always")
def _write_conic(
    params: np.ndarray,  # [N, N_PARAMS] float32, out
    spans: np.ndarray,  # [N, N_SPAN] float32, out
    i: int,
    u: float,
    v: float,
    rect: tuple[float, float, float, float],  # x0, x1, y0, y1
    conic: tuple[float, float, float],  # float64 values of the float32 conic
    op: float,
    m_cut: float,
) -> None:
    """The conic's forward-difference factors; the opacity, negated for a thin footprint,
    whose row spans then go to `spans` (see `_render_layout`)."""
    ca, cb, cc = conic
    for col, rate in ((DECAY_X, ca), (DECAY_Y, cc), (DECAY_XY, cb)):
        decay = math.exp(-rate)
        decay32 = np.float32(decay)
        params[i, col] = decay32
        params[i, col + 1] = decay - np.float64(decay32)
    x0, x1, y0, y1 = rect
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
        a, b, c = _screen_covariance(covs, i, x, y, z, rot, camera, low_pass)
        det = a * c - b * b
        if not det > 0.0:
            continue
        x0, x1, y0, y1, m_cut = _footprint(
            u, v, a, b, c, op, width, height, alpha_min, sigma_extent
        )
        if not (x0 <= x1 and y0 <= y1):
            continue
        # The rasterizer computes from the float32 conic; derive the rest from it too.
        ca32 = np.float32(c / det)
        cb32 = np.float32(-b / det)
        cc32 = np.float32(a / det)
        conic = (np.float64(ca32), np.float64(cb32), np.float64(cc32))
        params[i, DU] = u - x0
        params[i, DV] = v - y0
        params[i, CONIC_A] = ca32
        params[i, CONIC_B] = cb32
        params[i, CONIC_C] = cc32
        _write_conic(params, spans, i, u, v, (x0, x1, y0, y1), conic, op, m_cut)
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


def scatter_stride(n: int) -> int:
    """A stride coprime to n near n / golden ratio: k -> k * stride mod n scatters 0..n-1."""
    stride = max(1, int(n * 0.618)) | 1
    while math.gcd(stride, n) != 1:
        stride += 2
    return stride


def _project(
    gaussians: GaussianSet,
    cam: CameraSetup,
    k: Intrinsics,
    near: float,
    far: float,
    tile_w: int,
    tile_h: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """`project_kernel` over a set: (params, spans, depth, rects, tiles, valid)."""
    n = len(gaussians)
    params = np.empty((n, N_PARAMS), dtype=np.float32)
    spans = np.empty((n, N_SPAN), dtype=np.float32)
    z = np.empty(n, dtype=np.float64)
    rects = np.empty((n, 4), dtype=np.int16)
    tiles = np.empty((n, 4), dtype=np.int16)
    valid = np.empty(n, dtype=np.bool_)
    camera = np.array([k.fx, k.fy, k.cx, k.cy, *cam.tan_lo, *cam.tan_hi], dtype=np.float64)
    project_kernel(
        gaussians.means, gaussians.covs, gaussians.colors, gaussians.opacities, cam.rotation,
        cam.translation, camera, k.width, k.height, near, far, LOW_PASS, ALPHA_MIN,
        SIGMA_EXTENT, tile_w, tile_h, params, spans, z, rects, tiles, valid,
    )  # fmt: skip
    return params, spans, z, rects, tiles, valid


def render_fast(
    gaussians: GaussianSet,
    pose: Pose,
    intrinsics: Intrinsics,
    background: tuple[float, float, float],
    near: float,
    far: float,
    tile: tuple[int, int] = (TILE, TILE),
    stages: dict[str, list[tuple[float, float]]] | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Tile-rasterize `gaussians`; same outputs as `render_reference.render_reference`.

    Args:
        tile: (width, height) of a tile in pixels; the result does not depend on it.
        stages: when given, each stage's (wall s, process CPU s) is appended under its
            name: "project", "sort", "bin", "rasterize" (for `bench render`).
    """
    clock = _StageClock(stages)
    cam = camera_setup(pose, intrinsics)
    k = intrinsics
    w, h = int(k.width), int(k.height)
    tile_w, tile_h = tile
    tiles_x = (w + tile_w - 1) // tile_w
    n_tiles = tiles_x * ((h + tile_h - 1) // tile_h)
    params, spans, z, rects, tiles, valid = _project(
        gaussians, cam, k, float(near), float(far), tile_w, tile_h
    )
    clock.lap("project")
    order = depth_order_kernel(valid, z)
    clock.lap("sort")
    offsets, lists = bin_kernel(order, tiles, tiles_x, n_tiles, numba.get_num_threads())
    clock.lap("bin")
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
    clock.lap("rasterize")
    return rgb, depth, alpha


class _StageClock:
    """Appends (wall s, process CPU s) since the previous lap under each stage's name."""

    def __init__(self, stages: dict[str, list[tuple[float, float]]] | None) -> None:
        self.stages = stages
        self.wall = time.perf_counter()
        self.cpu = time.process_time()

    def lap(self, name: str) -> None:
        if self.stages is None:
            return
        wall, cpu = time.perf_counter(), time.process_time()
        self.stages.setdefault(name, []).append((wall - self.wall, cpu - self.cpu))
        self.wall, self.cpu = wall, cpu
