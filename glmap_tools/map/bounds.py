"""The world a map may cover: where a frame's camera and points may lie.

Two bounds, both in `MapConfig`:

- `world_limit` (default 1 km): every camera centre and every observed point lies within
  this many metres of the origin on each axis. Far-off coordinates (a pose translated
  1e300 m, a depth image in the wrong unit) would overflow extents, grids and images.
- `max_span` (default 200 m): on each axis, the extent of the map's camera centres and
  the new frame's points and camera centre is at most this. A map stays one building,
  and every grid or image over it has a bounded size.

`check_frame_bounds` is called before a frame is integrated; a frame outside either bound
is refused (`OutOfBoundsError`) and the map and its file stay as they were.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.geometry.frame import RGBDFrame
from glmap_tools.map.config import MapConfig

__all__ = ["OutOfBoundsError", "check_frame_bounds", "frame_extent", "map_extent"]

AXES = "xyz"


class OutOfBoundsError(InvalidInputError):
    """A frame's camera or points lie outside the world a map may cover."""


def frame_extent(frame: RGBDFrame, max_range: float) -> tuple[np.ndarray, np.ndarray]:
    """Bounding box of the camera centre and the valid depth points of `frame`.

    Args:
        frame: the posed RGB-D frame.
        max_range: depth beyond this (m) is ignored, as integration ignores it.

    Returns:
        (lo [3], hi [3]) world metres.
    """
    intr, pose = frame.intrinsics, frame.pose
    centre = pose.translation
    valid = frame.valid_depth(max_range)
    v, u = np.nonzero(valid)
    if len(v) == 0:
        return centre.copy(), centre.copy()
    z = frame.depth[v, u].astype(np.float64)  # [N]
    x = (u - intr.cx) / intr.fx * z
    y = (v - intr.cy) / intr.fy * z
    lo, hi = centre.copy(), centre.copy()
    r = pose.rotation
    for k in range(3):  # one world axis at a time: no [N, 3] matrix product
        w = r[k, 0] * x + r[k, 1] * y + r[k, 2] * z
        lo[k] = min(lo[k], float(w.min()) + centre[k])
        hi[k] = max(hi[k], float(w.max()) + centre[k])
    return lo, hi


def frustum_extent(frame: RGBDFrame, max_range: float) -> tuple[np.ndarray, np.ndarray]:
    """Bounding box of the camera's view out to `max_range`: the camera centre and the four
    image corners' rays at depth `max_range`. It holds `frame_extent` (a valid point has
    depth <= max_range and projects inside the image) and costs no pass over the pixels.
    """
    intr, pose = frame.intrinsics, frame.pose
    u = np.array([-0.5, intr.width - 0.5, -0.5, intr.width - 0.5])
    v = np.array([-0.5, -0.5, intr.height - 0.5, intr.height - 0.5])
    rays = np.stack([(u - intr.cx) / intr.fx, (v - intr.cy) / intr.fy, np.ones(4)], axis=1)
    corners = pose.translation + (rays * max_range) @ pose.rotation.T  # [4, 3]
    everything = np.vstack([corners, pose.translation[None]])
    return everything.min(axis=0), everything.max(axis=0)


def map_extent(trajectory: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray] | None:
    """Bounding box (lo [3], hi [3]) of the camera centres of `trajectory` ([4, 4] poses)."""
    if not trajectory:
        return None
    centres = np.array([np.asarray(p)[:3, 3] for p in trajectory], dtype=np.float64)  # [F, 3]
    return centres.min(axis=0), centres.max(axis=0)


def _fmt(v: np.ndarray) -> str:
    return "(" + ", ".join(f"{x:.4g}" for x in v) + ")"


def check_frame_bounds(
    frame: RGBDFrame, config: MapConfig, trajectory: Sequence[np.ndarray]
) -> None:
    """Refuse a frame whose camera or points leave the map's world (see module doc).

    Args:
        frame: the frame about to be integrated.
        config: the map's settings (world_limit, max_span, max_range).
        trajectory: [4, 4] poses of the frames already integrated.

    Raises:
        OutOfBoundsError: a camera centre or point beyond world_limit, or an extent over
            max_span; the message names the axis, the value and the fix.
    """
    known = map_extent(trajectory)
    if _violation(*frustum_extent(frame, config.max_range), frame, config, known) is None:
        return  # the whole view fits, so every point does: no pass over the pixels
    problem = _violation(*frame_extent(frame, config.max_range), frame, config, known)
    if problem is not None:
        raise OutOfBoundsError(problem)


def _violation(
    lo: np.ndarray,
    hi: np.ndarray,
    frame: RGBDFrame,
    config: MapConfig,
    known: tuple[np.ndarray, np.ndarray] | None,
) -> str | None:
    """What a frame whose camera and points lie in lo..hi breaks (a message), or None."""
    limit = config.world_limit
    centre = frame.pose.translation
    for k, axis in enumerate(AXES):
        if abs(centre[k]) > limit:
            return (
                f"the camera centre {_fmt(centre)} is {abs(centre[k]):.4g} m from the origin "
                f"along {axis}; this map's world is +-{limit:g} m (MapConfig.world_limit). "
                "Give poses in metres relative to a nearby origin."
            )
        if max(-lo[k], hi[k]) > limit:
            return (
                f"the frame's points reach {axis} = {lo[k] if -lo[k] > hi[k] else hi[k]:.4g} m; "
                f"this map's world is +-{limit:g} m (MapConfig.world_limit). Check the depth "
                "scale and units, or lower max_range."
            )
    span_lo, span_hi = (
        (lo, hi) if known is None else (np.minimum(known[0], lo), np.maximum(known[1], hi))
    )
    span = span_hi - span_lo
    for k, axis in enumerate(AXES):
        if span[k] > config.max_span:
            return (
                f"with this frame the map would span {span[k]:.4g} m along {axis} (from "
                f"{span_lo[k]:.4g} to {span_hi[k]:.4g} m; camera at {_fmt(centre)}); a map "
                f"spans at most {config.max_span:g} m (MapConfig.max_span). Start a new map "
                "for a far-off place, or raise max_span."
            )
    return None
