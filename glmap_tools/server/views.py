"""Images of a map for the MCP tools: cameras placed from unit bounds, splatted views, and a
top-down map drawn from the occupancy layer and the index grid.

The camera placement here is deliberately simple (look at the unit's bounding sphere from
the side it was observed from, 35 degrees above the horizon); map-level view selection can
replace it without changing the tools.
"""

from __future__ import annotations

import colorsys
import math
import threading
import weakref
from dataclasses import dataclass

import cv2
import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.gaussians.types import GaussianSet
from glmap_tools.geometry import Intrinsics, Pose
from glmap_tools.map import FREE, OBSTACLE, GLMap
from glmap_tools.map.units import InstanceUnit, RegionUnit

AGENT_HFOV_DEG = 79.0
VIEW_ELEVATION = math.radians(35.0)
MAP_ELEVATION = math.radians(60.0)
MIN_RADIUS = 0.5  # m: never frame less than this around a unit
TOPDOWN_MAX_SIDE = 768  # px
SITUATED = (("front", 0.0), ("left", math.pi / 2), ("back", math.pi), ("right", -math.pi / 2))

_cache_lock = threading.Lock()
_all_gaussians: weakref.WeakKeyDictionary[GLMap, tuple[int, GaussianSet]] = (
    weakref.WeakKeyDictionary()
)


@dataclass(frozen=True)
class View:
    """One rendered image and the camera it was rendered from."""

    label: str
    png: bytes
    pose: Pose
    intrinsics: Intrinsics

    def describe(self) -> str:
        """One line: the label, camera position, heading and pitch."""
        eye = self.pose.translation
        forward = self.pose.rotation[:, 2]
        pitch = round(math.degrees(math.asin(max(-1.0, min(1.0, -float(forward[2]))))))
        hfov = math.degrees(2 * math.atan(self.intrinsics.width / (2 * self.intrinsics.fx)))
        return (
            f"{self.label}: camera at ({eye[0]:.2f}, {eye[1]:.2f}, {eye[2]:.2f}) m, heading "
            f"{round(math.degrees(self.pose.heading))} deg (from +x, counter-clockwise), pitch "
            f"{pitch} deg down, hfov {hfov:.0f} deg"
        )


def encode_png(rgb: np.ndarray) -> bytes:  # rgb: [H, W, 3] uint8
    """PNG bytes of an RGB image."""
    ok, buf = cv2.imencode(".png", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    assert ok, "PNG encoding of a uint8 image cannot fail"
    return buf.tobytes()


def map_gaussians(glmap: GLMap) -> GaussianSet:
    """All instance Gaussians of the map, cached until the map integrates another frame."""
    version = len(glmap.trajectory) + glmap.next_id * 1_000_003
    with _cache_lock:
        cached = _all_gaussians.get(glmap)
        if cached is not None and cached[0] == version:
            return cached[1]
    g = GaussianSet.concat([u.gaussians for u in glmap.instances.values()])
    with _cache_lock:
        _all_gaussians[glmap] = (version, g)
    return g


# ---------------------------------------------------------------------- cameras


def unit_bounds(glmap: GLMap, unit: InstanceUnit | RegionUnit) -> tuple[np.ndarray, np.ndarray]:
    """([3] min, [3] max) of a unit's Gaussian means (regions: of their members)."""
    if isinstance(unit, InstanceUnit):
        return unit.bounds()
    members = [glmap.instances[i].bounds() for i in unit.instance_ids if i in glmap.instances]
    if not members:
        raise InvalidInputError(f"region {unit.id} has no instances to look at.")
    return np.min([m[0] for m in members], 0), np.max([m[1] for m in members], 0)


def map_bounds(glmap: GLMap) -> tuple[np.ndarray, np.ndarray]:
    """([3] min, [3] max) of every instance; raises on an empty map."""
    if not glmap.instances:
        raise InvalidInputError("the map is empty; observe frames before rendering it.")
    b = [u.bounds() for u in glmap.instances.values()]
    return np.min([x[0] for x in b], 0), np.max([x[1] for x in b], 0)


def _observed_side(glmap: GLMap, center: np.ndarray) -> np.ndarray:
    """Unit [2] direction from `center` towards the nearest camera of the trajectory."""
    if glmap.trajectory:
        eyes = np.array([p[:2, 3] for p in glmap.trajectory])
        d = eyes - center[None, :2]
        nearest = d[int(np.argmin(np.linalg.norm(d, axis=1)))]
        n = float(np.linalg.norm(nearest))
        if n > 1e-6:
            return nearest / n
    return np.array([0.0, -1.0])


def framing_pose(
    glmap: GLMap, lo: np.ndarray, hi: np.ndarray, intrinsics: Intrinsics, elevation: float
) -> Pose:
    """A camera that sees the bounding sphere of [lo, hi] whole, from the observed side."""
    center = (np.asarray(lo, np.float64) + np.asarray(hi, np.float64)) / 2
    radius = max(float(np.linalg.norm(np.asarray(hi) - np.asarray(lo))) / 2, MIN_RADIUS)
    half_fov = math.atan(min(intrinsics.width, intrinsics.height) / (2 * intrinsics.fx))
    distance = 1.15 * radius / math.sin(half_fov)
    side = _observed_side(glmap, center)
    eye = center + distance * np.array(
        [math.cos(elevation) * side[0], math.cos(elevation) * side[1], math.sin(elevation)]
    )
    return Pose.looking_at(eye, center)


def agent_intrinsics(width: int, height: int) -> Intrinsics:
    return Intrinsics.from_fov(width, height, AGENT_HFOV_DEG)


# ---------------------------------------------------------------------- rendering


def render_views(
    glmap: GLMap, cameras: list[tuple[str, Pose]], intrinsics: Intrinsics
) -> list[View]:
    """Splat the whole map from each (label, pose) camera onto a white background."""
    from glmap_tools.gaussians.render import render

    gaussians = map_gaussians(glmap)
    views = []
    for label, pose in cameras:
        result = render(gaussians, pose, intrinsics, background=(1.0, 1.0, 1.0))
        views.append(View(label, encode_png(result.to_uint8()), pose, intrinsics))
    return views


def situated_cameras(glmap: GLMap, x: float, y: float, heading: float) -> list[tuple[str, Pose]]:
    """Front/left/back/right cameras at (x, y), agent camera height above the floor."""
    floor = glmap.floor_z if glmap.floor_z is not None else 0.0
    height = floor + glmap.config.camera_height
    return [
        (label, Pose.from_position_heading(x, y, height, heading + turn))
        for label, turn in SITUATED
    ]


def warm_up() -> None:
    """Compile (or load from cache) the splatting kernels with a tiny render."""
    from glmap_tools.gaussians.render import render

    g = GaussianSet(
        np.zeros((1, 3)), np.eye(3)[None] * 1e-3, np.ones((1, 3)), np.ones(1) * 0.8, np.ones(1)
    )
    render(g, Pose.looking_at(np.array([1.0, 0, 0]), np.zeros(3)), agent_intrinsics(16, 16))


# ---------------------------------------------------------------------- top-down


def _palette(uid: int) -> tuple[int, int, int]:
    """A distinct saturated BGR colour per unit id."""
    r, g, b = colorsys.hsv_to_rgb((uid * 0.618033988749895) % 1.0, 0.75, 0.9)
    return int(b * 255), int(g * 255), int(r * 255)


@dataclass(frozen=True)
class TopDown:
    """A top-down map image and how its pixels map to the world.

    World (x, y) is at pixel column (x / cell_size - origin[0]) * scale and row
    (origin[1] + rows - y / cell_size) * scale: +x to the right, +y up.
    """

    png: bytes
    origin: tuple[int, int]
    cell_size: float
    scale: int
    rows: int

    def describe(self) -> str:
        x0 = self.origin[0] * self.cell_size
        y1 = (self.origin[1] + self.rows) * self.cell_size
        return (
            f"top-down map: +x right, +y up, {self.cell_size * 100:.0f} cm cells at {self.scale} "
            f"px each; the top-left pixel corner is world (x, y) = ({x0:.2f}, {y1:.2f}) m. "
            "White = free, dark grey = obstacle, light grey = unseen, coloured = instances "
            "(labelled with their ids), blue = the camera trajectory."
        )


def topdown(glmap: GLMap, max_side: int = TOPDOWN_MAX_SIDE, labels: bool = True) -> TopDown:
    """Draw the occupancy layer, the instance cells and the trajectory from above."""
    dense = glmap.occupancy.to_dense()
    cells: dict[int, np.ndarray] = {}
    for uid in glmap.instances:
        c = np.array(sorted(glmap.grid.cells_of_unit(uid)), dtype=np.int64).reshape(-1, 2)
        if len(c):
            cells[uid] = c
    have_occupancy = bool(glmap.occupancy.chunks)
    lo_parts, hi_parts = [], []
    if have_occupancy:
        h, w = dense.state.shape
        lo_parts.append(np.array(dense.origin))
        hi_parts.append(np.array(dense.origin) + np.array([w - 1, h - 1]))
    for c in cells.values():
        lo_parts.append(c.min(0))
        hi_parts.append(c.max(0))
    if not lo_parts:
        blank = np.full((96, 160, 3), 200, np.uint8)
        cv2.putText(blank, "empty map", (28, 54), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (60, 60, 60), 1)
        return TopDown(encode_png(blank), (0, 0), glmap.config.cell_size, 1, 96)
    lo = np.min(lo_parts, 0) - 2
    hi = np.max(hi_parts, 0) + 2
    cols, rows = int(hi[0] - lo[0] + 1), int(hi[1] - lo[1] + 1)
    scale = int(max(1, min(8, max_side // max(cols, rows))))
    grid = np.full((rows, cols, 3), 200, np.uint8)  # unseen: light grey (BGR)
    if have_occupancy:
        h, w = dense.state.shape
        r0, c0 = dense.origin[1] - lo[1], dense.origin[0] - lo[0]
        window = grid[r0 : r0 + h, c0 : c0 + w]
        window[dense.state == FREE] = (255, 255, 255)
        window[dense.state == OBSTACLE] = (90, 90, 90)
    for uid, c in cells.items():
        grid[c[:, 1] - lo[1], c[:, 0] - lo[0]] = _palette(uid)
    image = cv2.resize(grid[::-1], (cols * scale, rows * scale), interpolation=cv2.INTER_NEAREST)
    image = np.ascontiguousarray(image)

    def to_px(x: float, y: float) -> tuple[int, int]:
        s = glmap.config.cell_size
        return (
            int((x / s - lo[0]) * scale),
            int((lo[1] + rows - y / s) * scale),
        )

    if len(glmap.trajectory) >= 1:
        pts = np.array([to_px(p[0, 3], p[1, 3]) for p in glmap.trajectory], np.int32)
        cv2.polylines(image, [pts.reshape(-1, 1, 2)], False, (200, 90, 20), 1, cv2.LINE_AA)
        last = glmap.trajectory[-1]
        heading = math.atan2(last[1, 2], last[0, 2])
        tip = (last[0, 3] + 0.4 * math.cos(heading), last[1, 3] + 0.4 * math.sin(heading))
        cv2.arrowedLine(image, to_px(last[0, 3], last[1, 3]), to_px(*tip), (200, 90, 20), 2)
    if labels and len(cells) <= 300:
        for uid in cells:
            cx, cy = glmap.instances[uid].centroid[:2]
            px = to_px(float(cx), float(cy))
            cv2.putText(image, str(uid), px, cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 2)
            cv2.putText(image, str(uid), px, cv2.FONT_HERSHEY_SIMPLEX, 0.4, (255, 255, 255), 1)
    ok, buf = cv2.imencode(".png", image)
    assert ok
    return TopDown(buf.tobytes(), (int(lo[0]), int(lo[1])), glmap.config.cell_size, scale, rows)
