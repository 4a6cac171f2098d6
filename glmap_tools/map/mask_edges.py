"""Masks that bleed over depth edges: the pixels of an object's mask that lie across a depth
edge from the rest of it are left out before its points are fitted.

A segmenter's mask often takes a rim of pixels past the object's outline; behind a sofa those
pixels see the wall a metre further back, and their points would stretch the instance unit
toward the wall (ConceptGraphs-style pipelines clean them with DBSCAN per object). Here a
pixel is kept when its depth lies near the mean depth of the mask's pixels around it. On a
rim 2-3 pixels wide this drops over 90% of the rim (the rim's corners, mostly rim around
them, stay) and keeps over 90% of the object (a few pixels at its corners go;
`tests/test_map_mask_edges.py`).
"""

from __future__ import annotations

import cv2
import numpy as np

EDGE_ABS_M = 0.2  # a pixel more than this plus EDGE_REL x its depth from its neighbours' mean
EDGE_REL = 0.05  # ... is across a depth edge from them
WINDOW_PER_WIDTH = 0.01  # the neighbourhood's radius: 1% of the image width, at least 3 px


PASSES = 2  # the corners of a rim, mostly rim around them, go in the second pass


def depth_consistent(mask: np.ndarray, depth: np.ndarray) -> np.ndarray:
    """[H, W] bool: the pixels of `mask` whose depth is near the mean of the mask around them
    (`PASSES` times, each on what the previous kept).

    Args:
        mask: [H, W] bool, one object's pixels.
        depth: [H, W] metres (0 or non-finite: no measurement, never kept or counted).
    """
    valid = mask & np.isfinite(depth) & (depth > 0)
    for _ in range(PASSES):
        valid = _near_neighbours(valid, depth)
    return valid


def _near_neighbours(valid: np.ndarray, depth: np.ndarray) -> np.ndarray:
    h, w = valid.shape
    radius = max(3, round(WINDOW_PER_WIDTH * w))
    if not valid.any():
        return valid
    rows = np.nonzero(valid.any(axis=1))[0]
    cols = np.nonzero(valid.any(axis=0))[0]
    r0, r1 = max(int(rows[0]) - radius, 0), min(int(rows[-1]) + radius + 1, h)
    c0, c1 = max(int(cols[0]) - radius, 0), min(int(cols[-1]) + radius + 1, w)
    box = valid[r0:r1, c0:c1]
    v = box.astype(np.float32)
    d = np.where(box, depth[r0:r1, c0:c1], 0.0).astype(np.float32)
    k = (2 * radius + 1, 2 * radius + 1)
    weight = cv2.blur(v, k, borderType=cv2.BORDER_CONSTANT)
    mean = cv2.blur(d, k, borderType=cv2.BORDER_CONSTANT) / np.maximum(weight, 1e-9)
    near = np.abs(d - mean) <= EDGE_ABS_M + EDGE_REL * d
    out = np.zeros_like(valid)
    out[r0:r1, c0:c1] = box & near
    return out
