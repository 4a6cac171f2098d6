"""The top-down map image: the index grid drawn as a labelled picture.

Occupancy (free / obstacle / unseen) underneath, instance footprints (their index-grid
cells) in a colour per id, an optional value heat-map blended on top, region hulls
outlined, ids written at the units' centres, the camera trajectory and an optional agent
pose. +x points right and +y up; `TopDownImage.world_to_pixel` maps world metres to pixels.
"""

from __future__ import annotations

import colorsys
import math
import numbers
from collections.abc import Sequence
from typing import TYPE_CHECKING

import cv2
import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.geometry import Pose
from glmap_tools.map.occupancy import CHUNK, FREE, OBSTACLE
from glmap_tools.views.topdown_frame import (
    Canvas,
    Labels,
    TopDownFrame,
    choose_frame,
    draw_ticks,
)
from glmap_tools.views.topdown_image import HeatMap, TopDownImage

if TYPE_CHECKING:
    from glmap_tools.map.glmap import GLMap

MAX_SIDE = 4096  # pixels: the cap on the image's longer side
DEFAULT_SIDE = 768  # pixels
MAX_PIXELS_PER_CELL = 8
MAX_LABELS = 300  # more units than this are drawn without id labels
MARGIN_CELLS = 2  # unseen cells kept around the content
UNSEEN, FREE_RGB, OBSTACLE_RGB = (200, 200, 200), (255, 255, 255), (90, 90, 90)
TRAJECTORY_RGB, AGENT_RGB = (30, 90, 210), (220, 30, 30)
HEAT_OPACITY = 0.6


def palette(uid: int) -> tuple[int, int, int]:
    """A distinct saturated RGB colour per unit id (golden-ratio hues)."""
    r, g, b = colorsys.hsv_to_rgb((uid * 0.618033988749895) % 1.0, 0.75, 0.9)
    return int(r * 255), int(g * 255), int(b * 255)


def _agent_xy_heading(agent: Pose | Sequence[float]) -> tuple[float, float, float]:
    if isinstance(agent, Pose):
        return float(agent.translation[0]), float(agent.translation[1]), agent.heading
    try:
        x, y, heading = (float(v) for v in agent)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(
            f"agent={agent!r} must be a Pose or (x, y, heading) in metres and radians."
        ) from exc
    if not all(math.isfinite(v) and abs(v) <= 1e4 for v in (x, y, heading)):
        raise InvalidInputError(f"agent={agent!r} must be finite, within +-1e4.")
    return x, y, heading


def _unit_cells(glmap: GLMap) -> dict[int, np.ndarray]:
    out = {}
    for uid in sorted(glmap.instances):
        c = np.array(sorted(glmap.grid.cells_of_unit(uid)), dtype=np.int64).reshape(-1, 2)
        if len(c):
            out[uid] = c
    return out


def _content_bounds(
    glmap: GLMap,
    cells: dict[int, np.ndarray],
    extra_xy: list[tuple[float, float]],
    heatmap: HeatMap | None,
) -> tuple[np.ndarray, np.ndarray]:
    """World xy bounds (lo, hi) of everything drawn: observed cells, units, overlay, agent."""
    cell = glmap.config.cell_size
    lo_parts, hi_parts = [], []
    for (ci, cj), counts in glmap.occupancy.chunks.items():
        rows, cols = np.nonzero(counts.sum(axis=0))
        if len(rows):
            base = np.array([ci * CHUNK, cj * CHUNK])
            lo_parts.append((base + [cols.min(), rows.min()]) * cell)
            hi_parts.append((base + [cols.max() + 1, rows.max() + 1]) * cell)
    for c in cells.values():
        lo_parts.append(c.min(0) * cell)
        hi_parts.append((c.max(0) + 1) * cell)
    if heatmap is not None:
        hh, hw = heatmap.values.shape
        corner = np.array(heatmap.origin, np.float64) * heatmap.cell_size
        lo_parts.append(corner)
        hi_parts.append(corner + np.array([hw, hh]) * heatmap.cell_size)
    for x, y in extra_xy:
        lo_parts.append(np.array([x, y]))
        hi_parts.append(np.array([x, y]))
    if not lo_parts:
        raise InvalidInputError(
            "the map is empty: no instance in the index grid and no observed space; integrate "
            "frames before drawing it."
        )
    margin = MARGIN_CELLS * cell
    return np.min(lo_parts, 0) - margin, np.max(hi_parts, 0) + margin


def _window_bounds(window: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    try:
        x0, y0, x1, y1 = (float(v) for v in window)
    except (TypeError, ValueError):
        raise InvalidInputError(f"window={window!r} must be (x0, y0, x1, y1) in metres.") from None
    if not all(math.isfinite(v) for v in (x0, y0, x1, y1)) or x1 <= x0 or y1 <= y0:
        raise InvalidInputError(
            f"window={window!r} must be finite with x0 < x1 and y0 < y1, e.g. (0, 0, 6, 6)."
        )
    return np.array([x0, y0]), np.array([x1, y1])


def _paint_occupancy(canvas: Canvas, glmap: GLMap) -> bool:
    """Free cells white, then obstacles dark grey (they win a shared pixel); chunk by chunk."""
    occupancy = glmap.occupancy
    for state_value, color in ((FREE, FREE_RGB), (OBSTACLE, OBSTACLE_RGB)):
        for (ci, cj), counts in occupancy.chunks.items():
            rows, cols = np.nonzero(occupancy.state_of_counts(counts) == state_value)
            if len(rows):
                canvas.paint(np.stack([cols + ci * CHUNK, rows + cj * CHUNK], axis=1), color)
    return bool(occupancy.chunks)


def _heat_overlay(canvas: Canvas, heatmap: HeatMap) -> tuple[float, float] | None:
    """Blend the heat map into the canvas; return the (vmin, vmax) drawn, or None."""
    x, y = canvas.centres()
    values = heatmap.at(x, y)
    finite = np.isfinite(values)
    if not finite.any():
        return None
    vmin = float(values[finite].min()) if heatmap.vmin is None else float(heatmap.vmin)
    vmax = float(values[finite].max()) if heatmap.vmax is None else float(heatmap.vmax)
    t = np.clip((values[finite] - vmin) / max(vmax - vmin, 1e-12), 0.0, 1.0)
    lut = cv2.applyColorMap(np.arange(256, dtype=np.uint8)[:, None], cv2.COLORMAP_TURBO)
    colors = lut[(t * 255).round().astype(np.int64), 0, ::-1].astype(np.float64)  # BGR -> RGB
    flat = canvas.grid.reshape(-1, 3)
    idx = np.flatnonzero(finite)
    blended = (1 - HEAT_OPACITY) * flat[idx] + HEAT_OPACITY * colors
    flat[idx] = blended.round().astype(np.uint8)
    return vmin, vmax


def draw_topdown(
    glmap: GLMap,
    *,
    agent: Pose | Sequence[float] | None = None,
    heatmap: HeatMap | None = None,
    max_side: int = DEFAULT_SIDE,
    labels: bool = True,
    regions: bool = True,
    trajectory: bool = True,
    metres_per_pixel: float | None = None,
    frame: TopDownFrame | None = None,
    window: Sequence[float] | None = None,
    ticks: bool = True,
) -> TopDownImage:
    """Draw the map's index grid from above as a labelled image with metre ticks.

    The scale is the finest of 1, 2, 2.5, 5 x 10^k m per pixel that fits max_side and the
    corners lie on a coarse 1-2-5 spacing, so the frame stays put while the map grows
    inside it (and a `frame` passed back is kept while everything fits).
    Memory is bounded by the image (max_side^2 pixels), whatever the map's extent.

    Args:
        glmap: the map.
        agent: an optional agent pose, drawn as a red arrow: a Pose, or (x, y, heading) in
            metres and radians (heading from +x, counter-clockwise).
        heatmap: an optional value heat-map blended over the cells it covers (turbo
            colours, cold = low).
        max_side: cap on the image's longer side in pixels, 64..MAX_SIDE (4096).
        labels: write unit ids (instances at their centroids, regions as "R<id>") where
            they overlap no other label.
        regions: outline each region's cells with their convex hull.
        trajectory: draw the integrated camera positions as a blue line.
        metres_per_pixel: a fixed scale instead of the ladder's choice.
        frame: a previous image's frame, kept when everything still fits in it.
        window: (x0, y0, x1, y1) metres: draw only this part of the map (a crop around
            the agent); ids are written for the instances whose centroid lies inside.
        ticks: draw the metre ticks on the image's left and bottom edges (False: the
            caller draws axes outside it).

    Raises:
        InvalidInputError: nothing to draw (no instances and no observed space), a bad
            agent pose, heat map, max_side or metres_per_pixel.
    """
    _check_arguments(max_side, heatmap)
    agent_xyh = _agent_xy_heading(agent) if agent is not None else None
    cells = _unit_cells(glmap)
    if window is not None:
        lo, hi = _window_bounds(window)
        frame = None
    else:
        extra = [agent_xyh[:2]] if agent_xyh is not None else []
        lo, hi = _content_bounds(glmap, cells, extra, heatmap)
    frame = _frame_for(lo, hi, frame, glmap.config.cell_size, int(max_side), metres_per_pixel)
    canvas = Canvas(frame, glmap.config.cell_size, UNSEEN)
    legend = _paint_cells(canvas, glmap, cells, heatmap)
    image = canvas.image()
    writer = Labels(image)
    if ticks:
        draw_ticks(image, frame, writer)
    if window is not None:  # ids only for what the crop shows
        cells = _centred_within(glmap, cells, lo, hi)
    _draw_overlays(image, frame, glmap, cells, writer, legend, labels, regions, trajectory)
    if writer.skipped:
        legend.append(f"{writer.skipped} labels left out where they would overlap others.")
    if agent_xyh is not None:
        legend.append(_draw_agent(image, frame, agent_xyh))
    return TopDownImage(
        image,
        frame.x0,
        frame.y1,
        frame.metres_per_pixel,
        tuple(legend),
        tick=frame.tick,
        label_boxes=tuple(writer.boxes),
        frame=frame,
    )


def _draw_overlays(
    image: np.ndarray,
    frame: TopDownFrame,
    glmap: GLMap,
    cells: dict[int, np.ndarray],
    writer: Labels,
    legend: list[str],
    labels: bool,
    regions: bool,
    trajectory: bool,
) -> None:
    """Draw the region hulls, the camera trajectory and the instance ids on `image` [H, W, 3],
    each with its legend line (ids only when there are at most MAX_LABELS labels)."""
    label_count = len(cells) + (len(glmap.regions) if regions else 0)
    write_labels = labels and label_count <= MAX_LABELS
    if regions:
        _draw_regions(image, frame, glmap, writer if write_labels else None)
        if glmap.regions:
            legend.append("Outlines labelled R<id> = region hulls.")
    if trajectory and glmap.trajectory:
        pts = np.array([frame.px(p[0, 3], p[1, 3]) for p in glmap.trajectory], np.int32)
        cv2.polylines(image, [pts.reshape(-1, 1, 2)], False, TRAJECTORY_RGB, 1, cv2.LINE_AA)
        legend.append("Blue line = camera trajectory.")
    if write_labels:
        for uid in sorted(cells, key=lambda u: (-len(cells[u]), u)):
            cx, cy = glmap.instances[uid].centroid[:2]
            writer.place(str(uid), frame.px(float(cx), float(cy)))
        legend.append("Numbers = instance ids at (or next to) their centroids.")


def _centred_within(
    glmap: GLMap, cells: dict[int, np.ndarray], lo: np.ndarray, hi: np.ndarray
) -> dict[int, np.ndarray]:
    """The instances of `cells` whose centroid lies in the box lo..hi (x, y metres)."""
    return {
        u: c
        for u, c in cells.items()
        if lo[0] <= glmap.instances[u].centroid[0] <= hi[0]
        and lo[1] <= glmap.instances[u].centroid[1] <= hi[1]
    }


def _check_arguments(max_side: int, heatmap: HeatMap | None) -> None:
    if isinstance(max_side, bool) or not isinstance(max_side, numbers.Integral):
        raise InvalidInputError(f"max_side={max_side!r} must be an integer number of pixels.")
    if not 64 <= int(max_side) <= MAX_SIDE:
        raise InvalidInputError(f"max_side={max_side!r} must be in 64..{MAX_SIDE} pixels.")
    if heatmap is not None and not isinstance(heatmap, HeatMap):
        raise InvalidInputError(
            f"heatmap is a {type(heatmap).__name__}; pass a glmap_tools.views.HeatMap."
        )


def _frame_for(
    lo: np.ndarray,
    hi: np.ndarray,
    frame: TopDownFrame | None,
    cell: float,
    max_side: int,
    metres_per_pixel: float | None,
) -> TopDownFrame:
    """`frame` while everything still fits in it at no fixed scale, else a new one."""
    keep = (
        frame is not None
        and metres_per_pixel is None
        and max(frame.width, frame.height) <= max_side
        and frame.holds(lo, hi)
    )
    if keep:
        assert frame is not None
        return frame
    return choose_frame(lo, hi, cell / MAX_PIXELS_PER_CELL, max_side, metres_per_pixel)


def _paint_cells(
    canvas: Canvas,
    glmap: GLMap,
    cells: dict[int, np.ndarray],
    heatmap: HeatMap | None,
) -> list[str]:
    """Paint occupancy, instance footprints and the heat overlay; the legend so far."""
    legend = ["Light grey = never observed."]
    if _paint_occupancy(canvas, glmap):
        legend.append("White = seen free, dark grey = obstacle.")
    # Largest footprints first, so a chair stays visible on top of the floor under it.
    for uid, c in sorted(cells.items(), key=lambda item: (-len(item[1]), item[0])):
        canvas.paint(c, palette(uid))
    if cells:
        legend.append("Coloured cells = instance footprints (a colour per id).")
    if heatmap is not None:
        drawn = _heat_overlay(canvas, heatmap)
        if drawn is not None:
            legend.append(f"Heat overlay: blue = {drawn[0]:.3g} .. red = {drawn[1]:.3g}.")
    return legend


def _draw_agent(
    image: np.ndarray, frame: TopDownFrame, agent_xyh: tuple[float, float, float]
) -> str:
    """Draw the agent as a red arrow along its heading; its legend line."""
    x, y, heading = agent_xyh
    tip = (x + 0.5 * math.cos(heading), y + 0.5 * math.sin(heading))
    start, end = frame.px(x, y), frame.px(*tip)
    cv2.arrowedLine(image, start, end, AGENT_RGB, 2, cv2.LINE_AA, tipLength=0.35)
    cv2.circle(image, start, 3, AGENT_RGB, -1, cv2.LINE_AA)
    return f"Red arrow = the agent at ({x:.2f}, {y:.2f}) facing its heading."


def _draw_regions(
    image: np.ndarray, frame: TopDownFrame, glmap: GLMap, labels: Labels | None
) -> None:
    """Outline each region's cells by their convex hull, in the region's colour."""
    mpp, cell = frame.metres_per_pixel, glmap.config.cell_size
    for rid in sorted(glmap.regions):
        cells: set[tuple[int, int]] = set()
        for iid in glmap.regions[rid].instance_ids:
            cells |= glmap.grid.cells_of_unit(iid)
        if not cells:
            continue
        ij = np.array(sorted(cells), np.float64)
        corners = np.concatenate([ij + d for d in ((0, 0), (1, 0), (0, 1), (1, 1))]) * cell
        px = np.stack([(corners[:, 0] - frame.x0) / mpp, (frame.y1 - corners[:, 1]) / mpp], 1)
        hull = cv2.convexHull(px.round().astype(np.int32))
        cv2.polylines(image, [hull], True, palette(rid), 2, cv2.LINE_AA)
        if labels is not None:
            # Above the hull's top-left corner, clear of the instance ids inside it.
            left, top = hull.reshape(-1, 2).min(axis=0)
            labels.place(f"R{rid}", (int(left), max(int(top) - 4, 10)), centred=False)
