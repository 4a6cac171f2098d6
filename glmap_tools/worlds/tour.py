"""A walk through every room, rendered and written as a Redwood-style RGB-D folder.

The tour visits rooms in breadth-first order through their openings: it walks the geodesic
path to a central spot of each room (a pose every `step` metres, looking along the path) and
looks around there (`spin` headings). It starts in the first room at the point farthest (by
walking) from that room's spot, so the first room is walked through too; a one-room tour
then walks on to the point farthest from where it started, instead of spinning on one spot.
The folder holds::

    color/NNNNN.png, depth/NNNNN.png (uint16 mm), annotations/NNNNN.png + .json,
    trajectory.log (camera-to-world, OpenCV camera, z-up world; the camera JSON says
    "up_axis": "z", which `glmap build` reads),
    camera_intrinsics.json (width, height, intrinsic_matrix column-major),
    preview/NNNNN.png (colour | depth | instances, for people), topdown.png, tour.txt
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from scipy import ndimage

from glmap_tools.errors import InvalidInputError
from glmap_tools.geometry import Pose
from glmap_tools.ingest.images import write_annotation
from glmap_tools.sim.annotate import annotate_view
from glmap_tools.sim.detector import PERCEPTIONS, detect_view, load_rates
from glmap_tools.sim.layout import Layout
from glmap_tools.sim.navgrid import NavGrid, build_nav_grid
from glmap_tools.sim.render import CameraSpec, SceneRenderer
from glmap_tools.sim.topdown import draw_topdown

_NEIGHBOURS = [(-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1)]


@dataclass(frozen=True)
class TourStop:
    """One pose of the tour: planar position, heading, and the room it is in."""

    x: float
    y: float
    heading: float
    room: int

    @property
    def xy(self) -> np.ndarray:  # [2]
        return np.array([self.x, self.y])


def _room_spot(layout: Layout, grid: NavGrid, room_id: int) -> np.ndarray | None:
    """The navigable point of a room farthest from obstacles (ties: nearest the centroid)."""
    clearance = ndimage.distance_transform_edt(grid.navigable)
    xs, ys = grid.cell_centers()
    inside = grid.navigable & layout.room(room_id).contains(
        np.column_stack([xs.ravel(), ys.ravel()])
    ).reshape(grid.shape)
    if not inside.any():
        return None
    centroid = layout.room(room_id).centroid
    score = np.where(inside, clearance, -1.0) - 1e-3 * np.hypot(xs - centroid[0], ys - centroid[1])
    r, c = np.unravel_index(int(np.argmax(score)), score.shape)
    return grid.to_world(np.array([[r, c]]))[0]


def _farthest(layout: Layout, grid: NavGrid, room_id: int, origin: np.ndarray) -> np.ndarray:
    """The room's navigable point with the longest walk from `origin` [2]."""
    sources = np.zeros(grid.shape, dtype=bool)
    r, c = grid.to_cell(origin[None])[0]
    sources[r, c] = True
    field = grid.distance_field(sources)
    xs, ys = grid.cell_centers()
    inside = layout.room(room_id).contains(np.column_stack([xs.ravel(), ys.ravel()]))
    score = np.where(inside.reshape(grid.shape) & np.isfinite(field), field, -1.0)
    best = np.unravel_index(int(np.argmax(score)), score.shape)
    return grid.to_world(np.array([best]))[0]


def _walk(
    layout: Layout, grid: NavGrid, start: np.ndarray, goal: np.ndarray, step: float
) -> list[TourStop]:
    """Poses every `step` metres along the shortest path, looking along it."""
    points = _resample(geodesic_path(grid, start, goal), step)
    stops = []
    for a, b in zip(points[:-1], points[1:], strict=True):
        heading = math.atan2(b[1] - a[1], b[0] - a[0])
        stops.append(TourStop(float(a[0]), float(a[1]), heading, layout.room_at(a)))
    return stops


def _room_order(layout: Layout) -> list[int]:
    order, queue = [], [layout.rooms[0].id]
    while queue:
        room = queue.pop(0)
        if room in order:
            continue
        order.append(room)
        for o in layout.openings:
            if room in o.rooms:
                other = o.rooms[1] if o.rooms[0] == room else o.rooms[0]
                if other not in order:
                    queue.append(other)
    order += [r.id for r in layout.rooms if r.id not in order]
    return order


def geodesic_path(grid: NavGrid, start: np.ndarray, goal: np.ndarray) -> np.ndarray:
    """[N, 2] world points of a shortest 8-connected grid path from start to goal."""
    sources = np.zeros(grid.shape, dtype=bool)
    gr, gc = grid.to_cell(goal[None])[0]
    sources[gr, gc] = True
    field = grid.distance_field(sources)
    r, c = (int(v) for v in grid.to_cell(start[None])[0])
    if not np.isfinite(field[r, c]):
        return np.empty((0, 2))
    h, w = grid.shape
    cells = [(r, c)]
    while field[r, c] > 0:
        best = (r, c)
        for dr, dc in _NEIGHBOURS:
            rr, cc = r + dr, c + dc
            if 0 <= rr < h and 0 <= cc < w and field[rr, cc] < field[best]:
                best = (rr, cc)
        if best == (r, c):
            break
        r, c = best
        cells.append((r, c))
    return grid.to_world(np.array(cells))


MIN_STEP, MAX_STEP = 0.05, 50.0  # metres between walking frames (0.05: the nav grid's cell)
MAX_SPIN = 72  # headings looked at in a room (5 deg apart)


def _resample(path: np.ndarray, step: float) -> np.ndarray:
    if len(path) < 2:
        return path
    seg = np.linalg.norm(np.diff(path, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    if s[-1] < step:
        return path[[0, -1]]
    t = np.arange(0.0, s[-1], step)
    return np.column_stack([np.interp(t, s, path[:, 0]), np.interp(t, s, path[:, 1])])


def plan_tour(
    layout: Layout, grid: NavGrid | None = None, step: float = 0.4, spin: int = 8
) -> list[TourStop]:
    """Poses of a walk through all rooms (deterministic)."""
    if not (MIN_STEP <= step <= MAX_STEP and 0 <= spin <= MAX_SPIN):
        raise InvalidInputError(
            f"step={step} m must lie in [{MIN_STEP}, {MAX_STEP}] m and spin={spin} in "
            f"[0, {MAX_SPIN}] headings (defaults 0.4 m and 8)."
        )
    grid = grid or build_nav_grid(layout)
    spots: list[tuple[int, np.ndarray]] = []
    for room_id in _room_order(layout):
        spot = _room_spot(layout, grid, room_id)
        if spot is not None:
            spots.append((room_id, spot))
    if not spots:
        raise InvalidInputError(f"layout {layout.name!r} has no navigable floor to walk on.")
    stops: list[TourStop] = []
    first_room, first_spot = spots[0]
    here = _farthest(layout, grid, first_room, first_spot)
    heading = 0.0
    for _, spot in spots:
        walk = _walk(layout, grid, here, spot, step)
        stops += walk
        heading = walk[-1].heading if walk else heading
        for k in range(spin):
            h = heading + 2 * math.pi * k / spin
            stops.append(TourStop(float(spot[0]), float(spot[1]), h, layout.room_at(spot)))
        here = spot
    if len(spots) == 1:  # one room: walk on through it
        stops += _walk(layout, grid, here, _farthest(layout, grid, first_room, stops[0].xy), step)
    return stops


def _depth_preview(depth: np.ndarray) -> np.ndarray:
    d = np.clip(depth / 6.0, 0, 1)
    img = cv2.applyColorMap((255 * (1 - d)).astype(np.uint8), cv2.COLORMAP_TURBO)[:, :, ::-1]
    img[depth <= 0] = 0
    return img


def _mask_preview(rgb: np.ndarray, mask: np.ndarray) -> np.ndarray:
    ids = mask.astype(np.int64)
    colors = np.stack([(ids * 97) % 256, (ids * 57 + 80) % 256, (ids * 151 + 40) % 256], -1)
    out = np.where(ids[..., None] > 0, 0.45 * rgb + 0.55 * colors, 0.5 * rgb)
    return out.astype(np.uint8)


def write_tour(
    layout: Layout,
    out: str | Path,
    camera: CameraSpec | None = None,
    step: float = 0.4,
    spin: int = 8,
    max_frames: int | None = None,
    preview_every: int = 5,
    perception: str = "gt",
) -> int:
    """Render the tour into folder `out` (see the module docstring); returns the frame count.

    `perception`: "gt" (exact annotations) or "detector" (a detector's misses, confusions,
    bleeding masks and wrong colours, `sim/detector.py`; no goal, so no goal hallucinations).
    """
    if perception not in PERCEPTIONS:
        raise InvalidInputError(f"perception={perception!r} is not one of {list(PERCEPTIONS)}.")
    rates = load_rates() if perception == "detector" else None
    folder = Path(out)
    camera = camera or CameraSpec()
    grid = build_nav_grid(layout)
    stops = plan_tour(layout, grid, step, spin)[: max_frames or None]
    for sub in ("color", "depth", "annotations", "preview"):
        (folder / sub).mkdir(parents=True, exist_ok=True)
    renderer = SceneRenderer(layout, camera)
    log_lines = []
    try:
        for i, stop in enumerate(stops):
            pose = Pose.from_position_heading(stop.x, stop.y, camera.camera_height, stop.heading)
            view = renderer.render(pose)
            if rates is None:
                mask, annotation = annotate_view(view.instance_mask, layout)
            else:
                mask, annotation = detect_view(
                    view.instance_mask,
                    view.depth,
                    layout,
                    camera.intrinsics,
                    pose.matrix,
                    goal_category="",
                    episode="tour",
                    rates=rates,
                )
            stem = f"{i:05d}"
            cv2.imwrite(str(folder / "color" / f"{stem}.png"), view.rgb[:, :, ::-1])
            depth_mm = np.clip(np.round(view.depth * 1000.0), 0, 65535).astype(np.uint16)
            cv2.imwrite(str(folder / "depth" / f"{stem}.png"), depth_mm)
            write_annotation(folder, stem, mask, annotation)
            log_lines.append(f"{i} {i} {i + 1}")
            log_lines += [" ".join(f"{v:.9g}" for v in row) for row in pose.matrix]
            if preview_every and i % preview_every == 0:
                panel = np.concatenate(
                    [view.rgb, _depth_preview(view.depth), _mask_preview(view.rgb, mask)], axis=1
                )
                cv2.imwrite(str(folder / "preview" / f"{stem}.png"), panel[:, :, ::-1])
    finally:
        renderer.close()
    (folder / "trajectory.log").write_text("\n".join(log_lines) + "\n")
    k = camera.intrinsics
    intrinsics = {
        "width": k.width,
        "height": k.height,
        "intrinsic_matrix": [k.fx, 0, 0, 0, k.fy, 0, k.cx, k.cy, 1],
        "up_axis": "z",  # poses are already z-up; `glmap build` reads this
    }
    (folder / "camera_intrinsics.json").write_text(json.dumps(intrinsics, indent=1) + "\n")
    path = np.array([[s.x, s.y] for s in stops])
    cv2.imwrite(str(folder / "topdown.png"), draw_topdown(layout, grid, path)[:, :, ::-1])
    (folder / "tour.txt").write_text(
        f"layout {layout.name} (seed {layout.seed}): {len(stops)} frames of "
        f"{camera.width}x{camera.height}, hfov {camera.hfov_deg} deg, camera height "
        f"{camera.camera_height} m.\nPoses are z-up and OpenCV-camera already (the camera "
        "JSON says so): ingest with `glmap build FOLDER`; depth PNGs are millimetres.\n"
    )
    return len(stops)
