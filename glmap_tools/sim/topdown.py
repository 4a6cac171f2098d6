"""A labelled top-down picture of a layout (rooms, walls, objects, optional grid and path)."""

from __future__ import annotations

import cv2
import numpy as np

from glmap_tools.sim.architecture import wall_pieces
from glmap_tools.sim.layout import Layout
from glmap_tools.sim.navgrid import NavGrid
from glmap_tools.sim.palette import COLORS

MARGIN = 0.5  # metres around the apartment


def draw_topdown(
    layout: Layout,
    grid: NavGrid | None = None,
    path: np.ndarray | None = None,
    pixels_per_metre: float = 60.0,
    labels: bool = True,
) -> np.ndarray:  # [H, W, 3] uint8 RGB
    """Draw the layout seen from above (north up).

    Args:
        layout: the scene.
        grid: when given, navigable cells are tinted green.
        path: [N, 2] world (x, y) points drawn as a red polyline (e.g. a tour).
        pixels_per_metre: scale.
        labels: write object ids and room names.
    """
    lo, hi = layout.bounds()
    lo, hi = lo - MARGIN, hi + MARGIN
    s = pixels_per_metre
    w, h = int(np.ceil((hi[0] - lo[0]) * s)), int(np.ceil((hi[1] - lo[1]) * s))
    img = np.full((h, w, 3), 40, dtype=np.uint8)

    def px(xy: np.ndarray) -> np.ndarray:
        xy = np.atleast_2d(xy)
        return np.stack([(xy[:, 0] - lo[0]) * s, (hi[1] - xy[:, 1]) * s], axis=1).astype(np.int32)

    for room in layout.rooms:
        color = tuple(int(c * 255) for c in room.floor_color)
        cv2.fillPoly(img, [px(room.polygon)], color)
    if grid is not None:
        u, v = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
        world = np.column_stack([lo[0] + u.ravel() / s, hi[1] - v.ravel() / s])
        nav = grid.is_navigable(world).reshape(h, w)
        tinted = img[nav].astype(np.float32) * 0.6 + np.array([0.0, 160.0, 0.0]) * 0.4
        img[nav] = tinted.astype(np.uint8)
    for piece in wall_pieces(layout):
        if piece.z0 < 0.5:
            cv2.fillPoly(img, [px(piece.corners)], (235, 235, 235))
    for obj in sorted(layout.objects, key=lambda o: o.position[2]):
        rgb = COLORS.get(obj.attributes.get("color", ""), (0.6, 0.45, 0.3))
        color = tuple(int(c * 255) for c in rgb)
        corners = px(obj.footprint())
        cv2.fillPoly(img, [corners], color)
        cv2.polylines(img, [corners], True, (20, 20, 20), 1)
        front = px(
            obj.position[:2]
            + 0.5 * obj.size[1] * np.array([np.cos(obj.heading), np.sin(obj.heading)])
        )[0]
        cv2.line(img, tuple(px(obj.position[:2])[0]), tuple(front), (20, 20, 20), 1)
    if path is not None and len(path) > 1:
        cv2.polylines(img, [px(np.asarray(path)[:, :2])], False, (220, 30, 30), 2)
    if labels:
        for room in layout.rooms:
            c = px(room.centroid)[0]
            cv2.putText(
                img,
                room.name,
                (int(c[0]) - 30, int(c[1])),
                cv2.FONT_HERSHEY_SIMPLEX,
                0.45,
                (255, 255, 255),
                1,
                cv2.LINE_AA,
            )
        for obj in layout.objects:
            c = px(obj.position[:2])[0]
            cv2.putText(
                img,
                str(obj.id),
                (int(c[0]) - 6, int(c[1]) + 4),
                cv2.FONT_HERSHEY_SIMPLEX,
                0.35,
                (255, 255, 0),
                1,
                cv2.LINE_AA,
            )
    return img
