"""The four situated views with their direction written on them, and the heat-map image.

Paper §3.2: images from front, back, left and right of (l_a, theta) with their direction
annotations {(I_k, d_k)} go to the MLLM. Each view here carries its direction as a caption
band, so a model cannot mix them up, and the same words go into the text beside them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import cv2
import numpy as np

from glmap_tools.views.common import encode_png
from glmap_tools.views.topdown import draw_topdown

if TYPE_CHECKING:
    from glmap_tools.map.glmap import GLMap
    from glmap_tools.sqa.situate import Situation
    from glmap_tools.views.topdown import TopDownImage

# Imports inside functions stay there: gaussians, numba load on first use.

ORDER = ("front", "left", "back", "right")  # as a person turns: the captions read this way
CAPTION = 22  # px of the caption band


@dataclass(frozen=True)
class LabelledView:
    """One view: its direction d_k, the camera heading, and the captioned image."""

    direction: str
    heading_deg: float
    rgb: np.ndarray  # [H + CAPTION, W, 3] uint8

    def to_png(self) -> bytes:
        return encode_png(self.rgb)


def caption(rgb: np.ndarray, text: str) -> np.ndarray:
    """`rgb` [H, W, 3] with a dark band on top holding `text` in white."""
    h, w = rgb.shape[:2]
    out = np.zeros((h + CAPTION, w, 3), dtype=np.uint8)
    out[:CAPTION] = (32, 32, 32)
    out[CAPTION:] = rgb
    cv2.putText(
        out, text, (6, CAPTION - 7), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (255, 255, 255), 1, cv2.LINE_AA
    )
    return out


def labelled_views(
    glmap: GLMap, x: float, y: float, heading: float, *, structure: bool = True
) -> list[LabelledView]:
    """Render and caption the four situated views at (x, y) facing `heading` (radians)."""
    from glmap_tools.views.situated import situated_views

    views = situated_views(glmap, x, y, heading, structure=structure).by_direction()
    turn = {"front": 0.0, "left": 90.0, "back": 180.0, "right": -90.0}
    out = []
    for d in ORDER:
        h = math.degrees(heading) + turn[d]
        h = (h + 180.0) % 360.0 - 180.0
        out.append(LabelledView(d, h, caption(views[d].rgb, f"{d.upper()}  (heading {h:.0f} deg)")))
    return out


def views_sheet(views: list[LabelledView]) -> np.ndarray:
    """The four captioned views as one 2x2 image [2H, 2W, 3] (front, left / back, right)."""
    top = np.concatenate([views[0].rgb, views[1].rgb], axis=1)
    bottom = np.concatenate([views[2].rgb, views[3].rgb], axis=1)
    return np.concatenate([top, bottom], axis=0)


def heat_image(glmap: GLMap, situation: Situation, size: int = 512) -> np.ndarray:
    """Top-down image of H_r (red) and H_o (blue) with the situated pose as an arrow.

    Args:
        size: pixels of the longer side (the memory depends on it, not on the map's extent).
    """
    h_r = situation.h_r
    values = h_r.values
    rows, cols = values.shape
    scale = size / max(rows, cols, 1)
    w, h = max(1, round(cols * scale)), max(1, round(rows * scale))
    img = np.full((h, w, 3), 245, dtype=np.float32)
    occ = glmap.occupancy.to_dense()

    def resample(grid: np.ndarray, origin: tuple[int, int]) -> np.ndarray:
        # Nearest cell of `grid` for every pixel of the H_r window (rows grow with y).
        ys = (np.arange(h) + 0.5) / scale
        xs = (np.arange(w) + 0.5) / scale
        r = (ys.astype(int) + h_r.origin[1] - origin[1])[:, None]
        c = (xs.astype(int) + h_r.origin[0] - origin[0])[None, :]
        ok = (r >= 0) & (r < grid.shape[0]) & (c >= 0) & (c < grid.shape[1])
        out = np.zeros((h, w), dtype=grid.dtype)
        rr, cc = np.broadcast_arrays(r, c)
        out[ok] = grid[rr[ok], cc[ok]]
        return out

    state = resample(occ.state, occ.origin)
    img[state == 1] = (225, 225, 225)
    img[state == 2] = (90, 90, 90)
    hr = resample(values, h_r.origin)
    img = img * (1 - 0.7 * hr[..., None]) + 0.7 * hr[..., None] * np.array([230, 40, 40])
    if situation.h_o is not None:
        ho = resample(situation.h_o.values, situation.h_o.origin)
        img = img * (1 - 0.7 * ho[..., None]) + 0.7 * ho[..., None] * np.array([40, 60, 230])
    out = np.clip(img, 0, 255).astype(np.uint8)

    def px(xw: float, yw: float) -> tuple[int, int]:
        c = (xw / h_r.cell_size - h_r.origin[0]) * scale
        r = (yw / h_r.cell_size - h_r.origin[1]) * scale
        return int(round(c)), int(round(r))

    tail = px(situation.x, situation.y)
    length = 0.6 / h_r.cell_size * scale
    tip = (
        int(round(tail[0] + length * math.cos(situation.heading))),
        int(round(tail[1] + length * math.sin(situation.heading))),
    )
    cv2.arrowedLine(out, tail, tip, (0, 140, 0), 2, cv2.LINE_AA, tipLength=0.35)
    cv2.circle(out, tail, 4, (0, 140, 0), -1, cv2.LINE_AA)
    return np.ascontiguousarray(out[::-1])  # north (+y) up


CROP_RADIUS = 3.0  # m around the agent in the top-down crop


def topdown_crop(
    glmap: GLMap, x: float, y: float, heading: float, radius: float = CROP_RADIUS, size: int = 384
) -> TopDownImage:
    """A top-down crop around the situated pose with instance ids as markers (GPT4Scene-
    style): the map's footprints within `radius` m, ids at their centroids, the agent as a
    red arrow along `heading`, north (+y) up, metre ticks; at most size x size pixels."""

    window = (x - radius, y - radius, x + radius, y + radius)
    return draw_topdown(
        glmap,
        agent=(x, y, heading),
        max_side=size,
        regions=False,
        trajectory=False,
        window=window,
    )
