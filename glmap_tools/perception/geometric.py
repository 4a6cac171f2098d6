"""Model-free perception: class-agnostic segments of a posed RGB-D frame (no names).

Steps, on a grid of every `stride`-th pixel:

1. back-project to world points (z up) and estimate per-pixel normals from the point grid;
2. remove structure: the floor (lowest well-supported horizontal plane, from a height
   histogram of upward-facing points), a ceiling, and walls (vertical planes found by
   one-point-and-normal RANSAC whose inliers span a wall-sized extent);
3. split the rest into segments: 4-neighbours join when their depths are continuous (the
   jump is below `edge_absolute + edge_relative * depth`) and the surface between them is
   not a sharp concave fold (an object standing on a surface meets it in a concave crease);
4. drop small and thin segments, bring the labels back to full resolution, and attach each
   segment's mask, 3D bounds and colour crop.

The naming is someone else's job: the calling agent (`label_segments`), ground truth (the
benchmark) or an MLLM.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from glmap_tools.geometry.frame import RGBDFrame


@dataclass(frozen=True)
class GeometricConfig:
    """Settings of the geometric segmenter (lengths in metres, angles in degrees).

    Attributes:
        stride: pixel step of the working grid (2 at 640x480 -> 320x240).
        max_range: farther depth is ignored.
        plane_distance: a point within this distance of a plane is on it.
        normal_tolerance: a normal within this angle of vertical (horizontal) is vertical.
        floor_min_share: the floor needs this share of the valid points near its height.
        wall_min_share: a wall needs this share of the valid points as inliers.
        wall_min_extent: and its inliers must span this much both along and up the plane.
        max_walls: walls removed at most per frame.
        ransac_iterations: hypotheses per wall search.
        edge_absolute: depth jump (m) always allowed between neighbours.
        edge_relative: plus this fraction of the depth (sensor noise grows with range).
        concave_angle: pixels whose normals `crease_reach` grid steps either side differ
            by more than this across a concave crease are cut (an object on a table).
        crease_reach: grid steps from a crease pixel to the normals it compares.
        min_pixels: segments with fewer full-resolution pixels are dropped (at 640x480,
            scaled with the image area).
        min_thickness: segments whose second-largest 3D extent is smaller are dropped.
        crop_size: longest side of a segment's colour crop (pixels).
        seed: RANSAC seed (the result is deterministic).
    """

    stride: int = 2
    max_range: float = 8.0
    plane_distance: float = 0.03
    normal_tolerance: float = 20.0
    floor_min_share: float = 0.03
    wall_min_share: float = 0.04
    wall_min_extent: float = 1.2
    max_walls: int = 4
    ransac_iterations: int = 48
    edge_absolute: float = 0.02
    edge_relative: float = 0.03
    concave_angle: float = 50.0
    crease_reach: int = 2
    min_pixels: int = 600
    min_thickness: float = 0.04
    crop_size: int = 96
    seed: int = 0


@dataclass(frozen=True)
class Segment:
    """One class-agnostic segment of a frame.

    Attributes:
        id: local id within the frame (1, 2, ... in image order of size, largest first).
        mask: [H, W] bool full-resolution pixels.
        lo: [3] world minimum corner (m).
        hi: [3] world maximum corner (m).
        centroid: [3] world mean of its points (m).
        pixels: number of mask pixels.
        box: (row0, col0, row1, col1) image bounding box, end exclusive.
        crop: [h, w, 3] uint8 colour crop of the box, outside-mask pixels dimmed.
    """

    id: int
    mask: np.ndarray  # [H, W]
    lo: np.ndarray  # [3]
    hi: np.ndarray  # [3]
    centroid: np.ndarray  # [3]
    pixels: int
    box: tuple[int, int, int, int]
    crop: np.ndarray  # [h, w, 3]

    @property
    def size(self) -> np.ndarray:
        """[3] extent of the 3D bounds (m)."""
        return self.hi - self.lo


@dataclass
class _Grid:
    """The working grid of one frame (every `stride`-th pixel)."""

    depth: np.ndarray  # [h, w] camera depth (m), 0 where invalid
    valid: np.ndarray  # [h, w]
    points: np.ndarray  # [h, w, 3] world
    normals: np.ndarray  # [h, w, 3] world, unit, pointing towards the camera


def _grid(frame: RGBDFrame, config: GeometricConfig) -> _Grid:
    s = config.stride
    depth = np.nan_to_num(frame.depth[::s, ::s].astype(np.float32), nan=0.0, posinf=0.0)
    valid = (depth > 0) & (depth <= config.max_range)
    depth = np.where(valid, depth, 0.0).astype(np.float32)
    h, w = depth.shape
    k = frame.intrinsics
    v, u = np.mgrid[0:h, 0:w]
    x = ((u * s - k.cx) / k.fx * depth).astype(np.float32)
    y = ((v * s - k.cy) / k.fy * depth).astype(np.float32)
    cam = np.stack([x, y, depth], axis=-1)
    rot = frame.pose.rotation.astype(np.float32)
    points = cam @ rot.T + frame.pose.translation.astype(np.float32)
    # Normals from central differences of a lightly smoothed camera point grid.
    weight = ndimage.uniform_filter(valid.astype(np.float32), 3)
    smooth = ndimage.uniform_filter(cam, size=(3, 3, 1)) / np.maximum(weight, 1e-6)[..., None]
    du = np.zeros_like(smooth)
    dv = np.zeros_like(smooth)
    du[:, 1:-1] = smooth[:, 2:] - smooth[:, :-2]
    dv[1:-1] = smooth[2:] - smooth[:-2]
    n = np.cross(du, dv)
    norm = np.linalg.norm(n, axis=-1, keepdims=True)
    n = n / np.maximum(norm, 1e-9)
    flip = np.sum(n * cam, axis=-1) > 0  # make normals face the camera
    n[flip] *= -1
    normals = n @ rot.T
    return _Grid(depth, valid & (norm[..., 0] > 0), points, normals.astype(np.float32))


def _floor_and_ceiling(grid: _Grid, config: GeometricConfig) -> np.ndarray:
    """[h, w] bool pixels on the floor or the ceiling."""
    up = np.cos(np.radians(config.normal_tolerance))
    z = grid.points[..., 2]
    nz = grid.normals[..., 2]
    total = int(grid.valid.sum())
    removed = np.zeros_like(grid.valid)
    if total == 0:
        return removed
    bin_size = config.plane_distance
    for facing, pick_lowest in ((nz > up, True), (nz < -up, False)):
        sel = grid.valid & facing
        if sel.sum() < config.floor_min_share * total:
            continue
        heights = z[sel]
        lo = float(heights.min())
        counts = np.bincount(((heights - lo) / bin_size).astype(np.int64))
        counts = counts + np.roll(counts, 1) + np.roll(counts, -1)  # 3-bin window
        strong = np.nonzero(counts >= config.floor_min_share * total)[0]
        if len(strong) == 0:
            continue
        b = strong[0] if pick_lowest else strong[-1]
        window = slice(max(b - 1, 0), b + 2)
        in_window = heights[(heights >= lo + window.start * bin_size)]
        in_window = in_window[in_window < lo + window.stop * bin_size]
        height = float(np.median(in_window))
        if not pick_lowest and not removed.any():
            continue  # a ceiling is only trusted above a floor
        if not pick_lowest and height - float(np.median(z[removed])) < 1.8:
            continue
        # Normals blur next to objects; points right at the plane's height go regardless.
        gap = np.abs(z - height)
        near = (gap < config.plane_distance) & (
            (np.abs(nz) > 0.5) | (gap < config.plane_distance / 2)
        )
        removed |= grid.valid & near
    return removed


def _walls(grid: _Grid, taken: np.ndarray, config: GeometricConfig) -> np.ndarray:
    """[h, w] bool pixels on wall-sized vertical planes (one-point + normal RANSAC)."""
    rng = np.random.default_rng(config.seed)
    side = np.sin(np.radians(config.normal_tolerance))
    cos_tol = np.cos(np.radians(config.normal_tolerance))
    total = int(grid.valid.sum())
    removed = np.zeros_like(grid.valid)
    candidates = grid.valid & ~taken & (np.abs(grid.normals[..., 2]) < side)
    flat_points = grid.points.reshape(-1, 3)
    flat_normals = grid.normals.reshape(-1, 3)
    for _ in range(config.max_walls):
        idx = np.flatnonzero(candidates)
        if len(idx) == 0 or len(idx) < config.wall_min_share * total:
            break
        sample = idx[rng.choice(len(idx), size=min(len(idx), 1024), replace=False)]
        seeds = sample[: config.ransac_iterations]
        n = flat_normals[seeds].copy()  # [S, 3] hypotheses: vertical planes through seeds
        n[:, 2] = 0.0
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-9)
        d = np.sum(flat_points[seeds] * n, axis=1)  # [S]
        p, q = flat_points[sample], flat_normals[sample]  # [M, 3]
        fits = (np.abs(p @ n.T - d) < config.plane_distance) & (q @ n.T > cos_tol)  # [M, S]
        best = int(np.argmax(fits.sum(axis=0)))
        if fits[:, best].sum() < config.wall_min_share * total * len(sample) / len(idx):
            break
        nb, db = n[best], d[best]
        pts = flat_points[idx]
        inl = (np.abs(pts @ nb - db) < config.plane_distance) & (flat_normals[idx] @ nb > cos_tol)
        candidates.reshape(-1)[idx[inl]] = False  # tried: wall or not, not tried again
        if inl.sum() < config.wall_min_share * total:
            continue
        along = pts[inl] @ np.array([-nb[1], nb[0], 0.0], dtype=np.float32)
        span_along = np.percentile(along, 98) - np.percentile(along, 2)
        span_up = np.percentile(pts[inl, 2], 98) - np.percentile(pts[inl, 2], 2)
        if min(span_along, span_up) < config.wall_min_extent:
            continue
        # The wall takes every valid point on its plane, whatever the normal estimate says.
        on_plane = grid.valid & ~taken & (np.abs(grid.points @ nb - db) < config.plane_distance)
        removed |= on_plane
        candidates &= ~on_plane
    return removed


def _creases(grid: _Grid, keep: np.ndarray, config: GeometricConfig) -> np.ndarray:
    """[h, w] bool kept pixels on a sharp concave crease (compared `crease_reach` apart)."""
    r = config.crease_reach
    cos_cut = np.cos(np.radians(config.concave_angle))
    crease = np.zeros_like(keep)
    for sa, sb, sc in (
        (
            (slice(None), slice(0, -2 * r)),
            (slice(None), slice(2 * r, None)),
            (slice(None), slice(r, -r)),
        ),
        (
            (slice(0, -2 * r), slice(None)),
            (slice(2 * r, None), slice(None)),
            (slice(r, -r), slice(None)),
        ),
    ):
        na, nb = grid.normals[sa], grid.normals[sb]
        sharp = np.einsum("ijk,ijk->ij", na, nb) < cos_cut
        concave = np.einsum("ijk,ijk->ij", na - nb, grid.points[sa] - grid.points[sb]) < 0
        crease[sc] |= sharp & concave & keep[sa] & keep[sb]
    return crease & keep


def _edges(grid: _Grid, keep: np.ndarray, config: GeometricConfig) -> tuple[np.ndarray, ...]:
    """(a, b) flat indices of depth-continuous 4-neighbour pairs of kept grid pixels."""
    h, w = keep.shape
    flat_idx = np.arange(h * w).reshape(h, w)
    out_a, out_b = [], []
    for sa, sb in (
        ((slice(None), slice(0, -1)), (slice(None), slice(1, None))),
        ((slice(0, -1), slice(None)), (slice(1, None), slice(None))),
    ):
        da, db = grid.depth[sa], grid.depth[sb]
        ok = keep[sa] & keep[sb]
        ok &= np.abs(da - db) < config.edge_absolute + config.edge_relative * np.minimum(da, db)
        out_a.append(flat_idx[sa][ok])
        out_b.append(flat_idx[sb][ok])
    return np.concatenate(out_a), np.concatenate(out_b)


def _absorb(labels: np.ndarray, pixels: np.ndarray) -> np.ndarray:
    """`labels` with each of `pixels` given the label of its nearest labelled pixel."""
    if not pixels.any() or not labels.any():
        return labels
    _, (ri, ci) = ndimage.distance_transform_edt(labels == 0, return_indices=True)
    out = labels.copy()
    out[pixels] = labels[ri[pixels], ci[pixels]]
    return out


def grid_components(keep: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """[h, w] int labels (0 = not kept, 1.. = component) of kept pixels joined by edges a-b.

    Fast path: a sparse graph's connected components. `grid_components_reference` is the
    same contract as a flood fill.
    """
    n = keep.size
    graph = coo_matrix((np.ones(len(a), dtype=np.int8), (a, b)), shape=(n, n))
    _, comp = connected_components(graph, directed=False)
    comp = comp.reshape(keep.shape)
    # Renumber kept components 1..K by first pixel in raster order.
    kept = comp[keep]
    uniq, first = np.unique(kept, return_index=True)
    order = np.argsort(first)
    lut = np.zeros(comp.max() + 1, dtype=np.int32)
    lut[uniq[order]] = np.arange(1, len(uniq) + 1)
    labels = np.zeros(keep.shape, dtype=np.int32)
    labels[keep] = lut[kept]
    return labels


def grid_components_reference(keep: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Slow reference of `grid_components`: breadth-first flood fill in raster order."""
    n = keep.size
    neighbours: list[list[int]] = [[] for _ in range(n)]
    for i, j in zip(a.tolist(), b.tolist(), strict=True):
        neighbours[i].append(j)
        neighbours[j].append(i)
    flat_keep = keep.reshape(-1)
    labels = np.zeros(n, dtype=np.int32)
    current = 0
    for start in range(n):
        if not flat_keep[start] or labels[start]:
            continue
        current += 1
        labels[start] = current
        queue = [start]
        while queue:
            i = queue.pop()
            for j in neighbours[i]:
                if not labels[j]:
                    labels[j] = current
                    queue.append(j)
    return labels.reshape(keep.shape)


def _full_resolution(labels: np.ndarray, frame: RGBDFrame, config: GeometricConfig) -> np.ndarray:
    """[H, W] labels: each pixel takes its grid cell's label when its depth agrees."""
    s = config.stride
    height, width = frame.depth.shape
    up = np.repeat(np.repeat(labels, s, axis=0), s, axis=1)[:height, :width]
    ref = np.repeat(np.repeat(frame.depth[::s, ::s], s, axis=0), s, axis=1)[:height, :width]
    depth = np.nan_to_num(frame.depth, nan=0.0, posinf=0.0)
    agree = np.abs(depth - ref) < config.edge_absolute + config.edge_relative * ref
    return np.where(agree & (depth > 0), up, 0)


def _crop(rgb: np.ndarray, mask: np.ndarray, box: tuple[int, int, int, int], size: int):
    r0, c0, r1, c1 = box
    patch = rgb[r0:r1, c0:c1].astype(np.float32)
    inside = mask[r0:r1, c0:c1, None]
    patch = np.where(inside, patch, patch * 0.35)
    step = max(1, int(np.ceil(max(r1 - r0, c1 - c0) / size)))
    return patch[::step, ::step].round().astype(np.uint8)


def segment_frame(frame: RGBDFrame, config: GeometricConfig | None = None) -> list[Segment]:
    """Class-agnostic segments of a posed RGB-D frame, floor, ceiling and walls removed.

    Args:
        frame: the posed frame (world z up).
        config: segmenter settings (defaults: `GeometricConfig()`).

    Returns:
        Segments, largest first, ids 1..K.
    """
    config = config or GeometricConfig()
    grid = _grid(frame, config)
    structure = _floor_and_ceiling(grid, config)
    structure |= _walls(grid, structure, config)
    keep = grid.valid & ~structure
    crease = _creases(grid, keep, config)
    inner = keep & ~crease
    a, b = _edges(grid, inner, config)
    coarse = _absorb(grid_components(inner, a, b), crease)
    labels = _full_resolution(coarse, frame, config)
    height, width = labels.shape
    min_pixels = max(8, round(config.min_pixels * height * width / (640 * 480)))
    counts = np.bincount(labels.ravel())
    candidates = [
        i for i in np.argsort(-counts, kind="stable") if i > 0 and counts[i] >= min_pixels
    ]
    if not candidates:
        return []
    objects = ndimage.find_objects(labels)
    # 3D bounds from the working grid's points (a quarter of the pixels at stride 2).
    flat = coarse.ravel()
    order = np.argsort(flat, kind="stable")
    starts = np.searchsorted(flat[order], np.arange(len(counts) + 1))
    grid_points = grid.points.reshape(-1, 3).astype(np.float64)
    segments: list[Segment] = []
    for label in candidates:
        sl = objects[label - 1]
        assert sl is not None
        pts = grid_points[order[starts[label] : starts[label + 1]]]
        if len(pts) == 0:
            continue
        lo, hi = np.percentile(pts, [1, 99], axis=0)
        local = labels[sl] == label
        rows, cols = np.nonzero(local)
        rows = rows + sl[0].start
        cols = cols + sl[1].start
        if np.sort(hi - lo)[1] < config.min_thickness:
            continue
        mask = np.zeros((height, width), dtype=bool)
        mask[rows, cols] = True
        box = (sl[0].start, sl[1].start, sl[0].stop, sl[1].stop)
        segments.append(
            Segment(
                id=len(segments) + 1,
                mask=mask,
                lo=lo,
                hi=hi,
                centroid=pts.mean(axis=0),
                pixels=len(rows),
                box=box,
                crop=_crop(frame.rgb, mask, box, config.crop_size),
            )
        )
    return segments
