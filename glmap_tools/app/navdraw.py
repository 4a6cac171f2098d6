"""Pictures of navigation for the MCP tools: the value map with frontiers, waypoint and path,
and a labelled contact sheet of the frames of a turn."""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import cv2
import numpy as np

from glmap_tools.views.topdown import HeatMap, TopDownImage, draw_topdown

if TYPE_CHECKING:
    from glmap_tools.map import GLMap
    from glmap_tools.nav import Frontier, ValueMap

NAV_SIDE = 512  # pixels: longer side of the value-map image
FRONTIER_RGB, WAYPOINT_RGB, PLAN_RGB = (0, 200, 200), (230, 0, 230), (0, 170, 0)
TILE_WIDTH = 213  # pixels per contact-sheet frame (3 across = 640 wide)
AXIS_LEFT, AXIS_BOTTOM, BAR_WIDTH = 46, 24, 64  # pixels of the axes and colour bar bands
AXIS_FONT = 0.45


def jpeg(rgb: np.ndarray, quality: int = 85) -> bytes:  # rgb: [H, W, 3] uint8
    """JPEG bytes of an RGB image."""
    ok, buf = cv2.imencode(
        ".jpg", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, quality]
    )
    assert ok
    return buf.tobytes()


def nav_image(
    glmap: GLMap,
    agent: tuple[float, float, float] | None,
    value: ValueMap | None = None,
    frontiers: Sequence[Frontier] = (),
    waypoint: tuple[float, float] | None = None,
    plan_path: np.ndarray | None = None,
    max_side: int = NAV_SIDE,
) -> TopDownImage:
    """The top-down map with a value heat map, frontiers, the waypoint and the planned path,
    at least `max_side` pixels on its longer side, with metre axes and a colour bar.

    Args:
        glmap: the map.
        agent: (x, y, heading) of the agent, drawn as a red arrow.
        value: a `glmap_tools.nav.ValueMap` (values [H, W], origin (i0, j0), cell_size) or None.
        frontiers: `glmap_tools.nav.Frontier`s, drawn as cyan circles sized by their cells.
        waypoint: (x, y) the policy chose, drawn as a magenta cross.
        plan_path: [K, 2] world (x, y) of the planned path, drawn green.
        max_side: the image's longer side in pixels.
    """
    heat, span = None, None
    if value is not None and np.size(value.values):
        values = np.asarray(value.values, np.float64)
        finite = values[np.isfinite(values)]
        if finite.size:
            span = (float(finite.min()), float(finite.max()))
            i0, j0 = value.origin
            heat = HeatMap(values, (i0, j0), value.cell_size, *span)
    draw = functools.partial(
        draw_topdown, glmap, agent=agent, heatmap=heat, regions=False, ticks=False
    )
    image = draw(max_side=max_side)
    side = max(image.rgb.shape[:2])
    if side < max_side:  # a small map: zoom in to fill max_side (snapping may add a little)
        mpp = image.metres_per_pixel * side / max_side
        image = draw(max_side=int(max_side * 1.25), metres_per_pixel=mpp)
    rgb = image.rgb.copy()
    legend = list(image.legend)

    def px(x: float, y: float) -> tuple[int, int]:
        c, r = image.world_to_pixel(x, y)
        return int(round(c)), int(round(r))

    if plan_path is not None and len(plan_path) > 1:
        pts = np.array([px(float(x), float(y)) for x, y in plan_path], np.int32)
        cv2.polylines(rgb, [pts.reshape(-1, 1, 2)], False, PLAN_RGB, 2, cv2.LINE_AA)
        legend.append("Green line = planned path.")
    for f in frontiers:
        radius = int(np.clip(np.sqrt(f.size), 3, 12))
        cv2.circle(rgb, px(*f.centroid), radius, FRONTIER_RGB, 2, cv2.LINE_AA)
    if frontiers:
        legend.append("Cyan circles = frontiers (sized by their cells).")
    if waypoint is not None:
        cv2.drawMarker(rgb, px(*waypoint), WAYPOINT_RGB, cv2.MARKER_TILTED_CROSS, 16, 3)
        legend.append(f"Magenta cross = waypoint ({waypoint[0]:.2f}, {waypoint[1]:.2f}).")
    if span is not None:
        legend.append(f"Colour bar on the right: value H from {span[0]:.2f} to {span[1]:.2f}.")
    drawn = TopDownImage(rgb, image.x0, image.y1, image.metres_per_pixel, tuple(legend), image.tick)
    return with_axes(drawn, span)


def _text(image: np.ndarray, text: str, org: tuple[int, int]) -> int:
    """Write `text` with its baseline's left end at `org`; return its width in pixels."""
    cv2.putText(image, text, org, cv2.FONT_HERSHEY_SIMPLEX, AXIS_FONT, (0, 0, 0), 1, cv2.LINE_AA)
    return int(cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, AXIS_FONT, 1)[0][0])


def with_axes(image: TopDownImage, span: tuple[float, float] | None = None) -> TopDownImage:
    """`image` framed by metre axes outside it (left: y, bottom: x) and, with `span`
    (vmin, vmax) of a heat overlay, a colour bar on the right."""
    h, w = image.rgb.shape[:2]
    mpp, tick = image.metres_per_pixel, image.tick or 1.0
    right = BAR_WIDTH if span is not None else 8
    out = np.full((h + AXIS_BOTTOM, AXIS_LEFT + w + right, 3), 255, np.uint8)
    out[:h, AXIS_LEFT : AXIS_LEFT + w] = image.rgb
    x1, y0 = image.x0 + w * mpp, image.y1 - h * mpp
    free_from = 0  # x labels are skipped where they would overlap the previous one
    for k in range(math.ceil(image.x0 / tick - 1e-9), math.floor(x1 / tick + 1e-9) + 1):
        col = AXIS_LEFT + int(round((k * tick - image.x0) / mpp))
        cv2.line(out, (col, h), (col, h + 4), (0, 0, 0), 1)
        label = f"{k * tick:g}"
        width = cv2.getTextSize(label, cv2.FONT_HERSHEY_SIMPLEX, AXIS_FONT, 1)[0][0]
        left = max(0, col - width // 2)
        if left >= free_from:
            free_from = left + _text(out, label, (left, h + 17)) + 6
    for k in range(math.ceil(y0 / tick - 1e-9), math.floor(image.y1 / tick + 1e-9) + 1):
        row = int(round((image.y1 - k * tick) / mpp))
        cv2.line(out, (AXIS_LEFT - 4, row), (AXIS_LEFT - 1, row), (0, 0, 0), 1)
        label = f"{k * tick:g}"
        width = cv2.getTextSize(label, cv2.FONT_HERSHEY_SIMPLEX, AXIS_FONT, 1)[0][0]
        _text(out, label, (max(0, AXIS_LEFT - 6 - width), min(max(row + 5, 10), h - 2)))
    _text(out, "m", (2, h + 17))
    if span is not None:
        top, bottom, left = 20, h - 10, AXIS_LEFT + w + 8
        ramp = np.linspace(255, 0, max(bottom - top, 2)).round().astype(np.uint8)[:, None]
        colours = cv2.applyColorMap(ramp, cv2.COLORMAP_TURBO)[:, 0, ::-1]  # BGR -> RGB
        out[top:bottom, left : left + 14] = colours[: bottom - top, None, :]
        cv2.rectangle(out, (left, top), (left + 13, bottom - 1), (0, 0, 0), 1)
        _text(out, "H", (left + 2, top - 6))
        _text(out, f"{span[1]:.2f}", (left + 17, top + 10))
        _text(out, f"{span[0]:.2f}", (left + 17, bottom))
    return TopDownImage(
        out, image.x0 - AXIS_LEFT * mpp, image.y1, mpp, image.legend, tick=image.tick
    )


def contact_sheet(frames: Sequence[np.ndarray], labels: Sequence[str], cols: int = 3) -> np.ndarray:
    """Frames tiled `cols` across, each labelled in its top-left corner.

    Args:
        frames: [H, W, 3] uint8 RGB images of one size.
        labels: one short text per frame.
        cols: frames per row.

    Returns:
        [rows * h, cols * TILE_WIDTH, 3] uint8, h the tile height keeping the aspect.
    """
    h0, w0 = frames[0].shape[:2]
    th = max(1, round(TILE_WIDTH * h0 / w0))
    rows = -(-len(frames) // cols)
    sheet = np.full((rows * th, cols * TILE_WIDTH, 3), 255, np.uint8)
    for k, (rgb, label) in enumerate(zip(frames, labels, strict=True)):
        tile = cv2.resize(rgb, (TILE_WIDTH, th), interpolation=cv2.INTER_AREA)
        (w, h), _ = cv2.getTextSize(label, cv2.FONT_HERSHEY_SIMPLEX, 0.45, 1)
        cv2.rectangle(tile, (0, 0), (w + 8, h + 10), (0, 0, 0), -1)
        cv2.putText(
            tile, label, (4, h + 4), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (255, 255, 255), 1, cv2.LINE_AA
        )
        r, c = divmod(k, cols)
        sheet[r * th : (r + 1) * th, c * TILE_WIDTH : (c + 1) * TILE_WIDTH] = tile
    return sheet
