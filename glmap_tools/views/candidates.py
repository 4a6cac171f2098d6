"""Candidate cameras for view selection: rings around the target and trajectory spots.

Each candidate stands at floor + camera height, faces the target's centre and is placed in
the occupancy layer: "free" (seen-free and clear of obstacles by the agent radius),
"unobserved" or "blocked".
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np
from scipy import ndimage

from glmap_tools.errors import InvalidInputError
from glmap_tools.gaussians.types import GaussianSet
from glmap_tools.geometry import Intrinsics, Pose
from glmap_tools.map.occupancy import FREE, OBSTACLE
from glmap_tools.views.targets import instance_ids_of, map_gaussians

if TYPE_CHECKING:
    from glmap_tools.map.glmap import GLMap

Placement = Literal["free", "unobserved", "blocked"]
PLACEMENTS: tuple[Placement, ...] = ("free", "unobserved", "blocked")


@dataclass(frozen=True)
class SelectionConfig:
    """Settings of view selection.

    Attributes:
        angle_step_deg: spacing of candidate bearings around the target (degrees).
        ring_scales: candidate distances as multiples of the framing distance.
        fill: fraction of the horizontal field of view the target's extent should span at
            the framing distance.
        min_distance: nearest candidate to the target's centre (m).
        max_distance: farthest candidate (m).
        agent_radius: clearance from obstacle cells a candidate needs (m).
        max_pitch_deg: steepest downward pitch for low targets (degrees).
        score_width: width of the z-buffer renders used for scoring (pixels); the height
            follows the final camera's aspect.
        occlusion_margin: a Gaussian counts as visible if its depth is at most the
            z-buffer depth of the rest of the map plus this (m).
        near_tie: candidates scoring at least this fraction of the best are treated as
            equally good, and the one nearest the framing distance wins.
        max_trajectory_candidates: at most this many camera positions of the map's
            trajectory are added to the candidates (0 = none).
    """

    angle_step_deg: float = 15.0
    ring_scales: tuple[float, ...] = (0.5, 0.75, 1.0, 1.5, 2.0)
    fill: float = 0.6
    min_distance: float = 0.5
    max_distance: float = 6.0
    agent_radius: float = 0.18
    max_pitch_deg: float = 30.0
    score_width: int = 128
    occlusion_margin: float = 0.06
    near_tie: float = 0.95
    max_trajectory_candidates: int = 24

    def __post_init__(self) -> None:
        if not 1.0 <= self.angle_step_deg <= 90.0:
            raise InvalidInputError(
                f"angle_step_deg={self.angle_step_deg!r} must be in [1, 90] degrees."
            )
        if not self.ring_scales or min(self.ring_scales) <= 0:
            raise InvalidInputError(f"ring_scales={self.ring_scales!r} must be positive numbers.")
        if not 0.05 <= self.fill <= 1.0:
            raise InvalidInputError(f"fill={self.fill!r} must be in [0.05, 1].")
        if not 0.0 < self.min_distance < self.max_distance <= 50.0:
            raise InvalidInputError(
                f"min_distance={self.min_distance!r}, max_distance={self.max_distance!r} must "
                "satisfy 0 < min < max <= 50 metres."
            )
        if not 0.0 <= self.agent_radius < 2.0:
            raise InvalidInputError(f"agent_radius={self.agent_radius!r} must be in [0, 2) m.")
        if not 0.0 <= self.max_pitch_deg <= 80.0:
            raise InvalidInputError(f"max_pitch_deg={self.max_pitch_deg!r} must be in [0, 80].")
        if not 0.0 < self.near_tie <= 1.0:
            raise InvalidInputError(f"near_tie={self.near_tie!r} must be in (0, 1].")
        if not (
            isinstance(self.max_trajectory_candidates, int)
            and 0 <= self.max_trajectory_candidates <= 1000
        ):
            raise InvalidInputError(
                f"max_trajectory_candidates={self.max_trajectory_candidates!r} must be in 0..1000."
            )
        if self.occlusion_margin < 0:
            raise InvalidInputError(f"occlusion_margin={self.occlusion_margin!r} must be >= 0.")
        if not (isinstance(self.score_width, int) and 16 <= self.score_width <= 1024):
            raise InvalidInputError(f"score_width={self.score_width!r} must be in 16..1024 px.")


@dataclass(frozen=True)
class Candidate:
    """One candidate camera.

    Attributes:
        x: camera position (m).
        y: camera position (m).
        z: camera height (m), floor + camera_height.
        heading: planar viewing direction (radians from +x, counter-clockwise).
        pitch: downward tilt (radians).
        distance: horizontal distance to the target's centre (m).
        ring: index of its distance ring (0 = nearest); trajectory candidates come after
            the last ring.
        bearing: index of its bearing on the ring (bearing k is at k * angle_step from +x,
            seen from the target); for trajectory candidates, the frame's index.
        source: "ring" (placed around the target) or "trajectory" (a camera position of
            an integrated frame: the agent has stood there).
        placement: "free" (seen-free, clear by the agent radius), "unobserved" (not an
            obstacle and clear, but never seen free) or "blocked".
        score: the view's score (see `Visibility`); None if not scored.
        visible: opacity-weighted fraction of the target visible; None if not scored.
        in_view: opacity-weighted fraction whose means project into the image; None if not
            scored.
    """

    x: float
    y: float
    z: float
    heading: float
    pitch: float
    distance: float
    ring: int
    bearing: int
    source: Literal["ring", "trajectory"]
    placement: Placement
    score: float | None = None
    visible: float | None = None
    in_view: float | None = None

    def pose(self) -> Pose:
        """The candidate camera as world_from_camera."""
        return Pose.from_position_heading(self.x, self.y, self.z, self.heading, self.pitch)


@dataclass(frozen=True)
class TargetExtent:
    """A unit's Gaussians and robust extent, as view selection sees it."""

    center: np.ndarray  # [3] aim point (m)
    radius: float  # horizontal half-extent (m)
    z_range: tuple[float, float]  # robust min / max height of the means (m)
    gaussians: GaussianSet
    instance_ids: tuple[int, ...]


def target_extent(glmap: GLMap, unit_id: int) -> TargetExtent:
    ids = instance_ids_of(glmap, unit_id)
    cached = map_gaussians(glmap)
    g = cached.gaussians.subset(cached.mask_of(ids))
    means = g.means.astype(np.float64)
    # Robust extent: 1st-99th percentile, so a few stray Gaussians (depth noise) do not
    # push the camera away.
    lo, hi = np.percentile(means, 1, axis=0), np.percentile(means, 99, axis=0)
    center = (lo + hi) / 2.0
    radius = float(max(np.hypot(*(hi[:2] - lo[:2])) / 2.0, 0.05))
    return TargetExtent(center, radius, (float(lo[2]), float(hi[2])), g, ids)


def _clearance(glmap: GLMap) -> tuple[np.ndarray, np.ndarray, tuple[int, int], float]:
    """(state [H, W], distance to the nearest obstacle cell centre [H, W] (m), origin, cell)."""
    dense = glmap.occupancy.to_dense(margin=1)
    blocked = dense.state == OBSTACLE
    if blocked.any():
        dist = ndimage.distance_transform_edt(~blocked) * dense.cell_size
    else:
        dist = np.full(dense.state.shape, np.inf)
    return dense.state, dist, dense.origin, dense.cell_size


def _placements(glmap: GLMap, xy: np.ndarray, agent_radius: float) -> list[Placement]:
    """Placement of each [K, 2] candidate position."""
    state, dist, origin, cell = _clearance(glmap)
    cols = np.floor(xy[:, 0] / cell).astype(np.int64) - origin[0]
    rows = np.floor(xy[:, 1] / cell).astype(np.int64) - origin[1]
    inside = (rows >= 0) & (rows < state.shape[0]) & (cols >= 0) & (cols < state.shape[1])
    out: list[Placement] = []
    for k in range(len(xy)):
        if not inside[k]:  # beyond every observed chunk: unobserved, nothing known nearby
            out.append("unobserved")
            continue
        s = int(state[rows[k], cols[k]])
        clear = dist[rows[k], cols[k]] - cell / 2.0 >= agent_radius - 1e-9
        if s == FREE and clear:
            out.append("free")
        elif s != OBSTACLE and clear:
            out.append("unobserved")
        else:
            out.append("blocked")
    return out


def _pitch(
    target: TargetExtent, distance: float, eye_z: float, half_vfov: float, max_pitch: float
) -> float:
    """Downward pitch that keeps the target's bottom in view, level when it already is."""
    near = max(distance - target.radius, 0.2)
    to_bottom = math.atan2(eye_z - target.z_range[0], near)  # angle below the horizon
    to_top = math.atan2(eye_z - target.z_range[1], near)
    need = to_bottom - 0.9 * half_vfov  # least pitch that shows the bottom
    allow = to_top + 0.9 * half_vfov  # most pitch that still shows the top
    pitch = max(need, 0.0) if need <= allow else (to_bottom + to_top) / 2.0
    return float(min(max(pitch, 0.0), max_pitch))


def framing_distance(
    target: TargetExtent, intrinsics: Intrinsics, config: SelectionConfig
) -> float:
    """Distance (m) at which the target's horizontal extent spans `fill` of the view."""
    half_hfov = math.atan(intrinsics.width / (2.0 * intrinsics.fx))
    d = target.radius / math.tan(config.fill * half_hfov) + target.radius
    return min(max(d, config.min_distance), config.max_distance)


def _trajectory_spots(glmap: GLMap, limit: int) -> list[tuple[int, tuple[float, float]]]:
    """(frame index, camera x-y) of up to `limit` integrated frames, one per grid cell,
    evenly spread over the trajectory."""
    spots: dict[tuple[int, int], tuple[int, tuple[float, float]]] = {}
    cell = glmap.config.cell_size
    for k, m in enumerate(glmap.trajectory):
        x, y = float(m[0, 3]), float(m[1, 3])
        spots.setdefault((math.floor(x / cell), math.floor(y / cell)), (k, (x, y)))
    found = sorted(spots.values())
    if len(found) > limit:
        found = [found[i] for i in np.linspace(0, len(found) - 1, limit).round().astype(int)]
    return found


def make_candidates(
    glmap: GLMap, target: TargetExtent, intrinsics: Intrinsics, config: SelectionConfig
) -> list[Candidate]:
    half_vfov = math.atan(intrinsics.height / (2.0 * intrinsics.fy))
    framing = framing_distance(target, intrinsics, config)
    distances: list[float] = []
    for s in sorted(config.ring_scales):
        d = min(max(framing * s, config.min_distance), config.max_distance)
        if not distances or d > distances[-1] + 1e-6:
            distances.append(d)
    floor = glmap.floor_z if glmap.floor_z is not None else float(target.z_range[0])
    eye_z = floor + glmap.config.camera_height
    n_bearings = max(int(round(360.0 / config.angle_step_deg)), 1)
    rows: list[Candidate] = []  # placed below
    for ring, d in enumerate(distances):
        pitch = _pitch(target, d, eye_z, half_vfov, math.radians(config.max_pitch_deg))
        for b in range(n_bearings):
            a = 2.0 * math.pi * b / n_bearings
            x = float(target.center[0] + d * math.cos(a))
            y = float(target.center[1] + d * math.sin(a))
            heading = math.atan2(-math.sin(a), -math.cos(a))
            rows.append(Candidate(x, y, eye_z, heading, pitch, d, ring, b, "ring", "blocked"))
    ring = len(distances)
    for k, (x, y) in _trajectory_spots(glmap, config.max_trajectory_candidates):
        d = math.hypot(target.center[0] - x, target.center[1] - y)
        if config.min_distance <= d <= config.max_distance:
            heading = math.atan2(target.center[1] - y, target.center[0] - x)
            pitch = _pitch(target, d, eye_z, half_vfov, math.radians(config.max_pitch_deg))
            rows.append(Candidate(x, y, eye_z, heading, pitch, d, ring, k, "trajectory", "blocked"))
    xy = np.array([(c.x, c.y) for c in rows])
    placements = _placements(glmap, xy, config.agent_radius)
    return [dataclasses.replace(c, placement=p) for c, p in zip(rows, placements, strict=True)]
