"""A contact sheet of a frame's segments: the frame with numbered outlines, then one tile each.

What a vision model (the MCP client's, or an MLLM backend) looks at to name segments.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from PIL import Image, ImageDraw
from scipy import ndimage

from glmap_tools.perception.geometric import Segment

TILE = 112  # pixels per tile side (crop + its id)
OVERVIEW_WIDTH = 448
COLUMNS = 4
PALETTE = np.array(
    [
        (230, 25, 75),
        (60, 180, 75),
        (255, 225, 25),
        (0, 130, 200),
        (245, 130, 48),
        (145, 30, 180),
        (70, 240, 240),
        (240, 50, 230),
        (210, 245, 60),
        (250, 190, 212),
        (0, 128, 128),
        (170, 110, 40),
    ],
    dtype=np.uint8,
)


def segment_color(segment_id: int) -> tuple[int, int, int]:
    """The outline colour of a segment id."""
    r, g, b = PALETTE[(segment_id - 1) % len(PALETTE)]
    return int(r), int(g), int(b)


def _overview(rgb: np.ndarray, segments: Sequence[Segment]) -> Image.Image:
    scale = OVERVIEW_WIDTH / rgb.shape[1]
    size = (OVERVIEW_WIDTH, max(1, round(rgb.shape[0] * scale)))
    picture = rgb.copy()
    for seg in segments:
        edge = seg.mask & ~ndimage.binary_erosion(seg.mask, iterations=max(1, round(1 / scale)))
        picture[edge] = segment_color(seg.id)
    image = Image.fromarray(picture).resize(size, Image.Resampling.BILINEAR)
    draw = ImageDraw.Draw(image)
    for seg in segments:
        rows, cols = np.nonzero(seg.mask)
        k = len(rows) // 2
        order = np.lexsort((cols, rows))  # a mask pixel near the middle of the segment
        y, x = rows[order[k]] * scale, cols[order[k]] * scale
        draw.rectangle((x - 2, y - 7, x + 6 * len(str(seg.id)) + 2, y + 6), fill=(0, 0, 0))
        draw.text((x, y - 6), str(seg.id), fill=segment_color(seg.id))
    return image


def segment_sheet(rgb: np.ndarray, segments: Sequence[Segment]) -> np.ndarray:
    """[H', W', 3] uint8: the frame with numbered segment outlines above one tile per segment.

    Args:
        rgb: [H, W, 3] uint8 colour image of the frame.
        segments: its segments (crops and masks).
    """
    overview = _overview(rgb, segments)
    rows = (len(segments) + COLUMNS - 1) // COLUMNS
    width = max(overview.width, COLUMNS * TILE)
    sheet = Image.new("RGB", (width, overview.height + rows * TILE), (24, 24, 24))
    sheet.paste(overview, (0, 0))
    draw = ImageDraw.Draw(sheet)
    for k, seg in enumerate(segments):
        x0 = (k % COLUMNS) * TILE
        y0 = overview.height + (k // COLUMNS) * TILE
        crop = Image.fromarray(seg.crop)
        crop.thumbnail((TILE - 8, TILE - 20))
        sheet.paste(crop, (x0 + 4, y0 + 16))
        draw.text((x0 + 4, y0 + 2), f"{seg.id}", fill=segment_color(seg.id))
        draw.rectangle((x0 + 1, y0 + 1, x0 + TILE - 2, y0 + TILE - 2), outline=(70, 70, 70))
    return np.asarray(sheet)
