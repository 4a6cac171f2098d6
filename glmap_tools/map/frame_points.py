"""A frame's points: the valid depth pixels an update reads, back-projected once.

Occupancy, structure and every instance mask read points of the same frame. `FramePoints`
back-projects the pixels any of them needs in one pass and hands each a cloud indexed by
its mask, in the row-major pixel order `geometry.backproject` gives, so a part's cloud is
exactly the cloud `backproject` would give for that mask (a test holds the two equal).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from glmap_tools.geometry.backproject import PointCloud, backproject
from glmap_tools.geometry.frame import RGBDFrame


def lattice(shape: tuple[int, int], stride: int) -> np.ndarray:
    """[H, W] bool: every `stride`-th row and column (all pixels for stride 1)."""
    out = np.zeros(shape, dtype=bool)
    out[::stride, ::stride] = True
    return out


@dataclass(frozen=True)
class FramePoints:
    """World points of a frame's back-projected pixels.

    Attributes:
        valid: [H, W] bool, usable depth (finite, positive, within max_range).
        index: [H, W] int64, the row in `points` of each back-projected pixel, -1 elsewhere.
        points: [N, 3] float64 world metres.
        colors: [N, 3] float32 RGB in [0, 1].
    """

    valid: np.ndarray  # [H, W]
    index: np.ndarray  # [H, W]
    points: np.ndarray  # [N, 3]
    colors: np.ndarray  # [N, 3]

    def cloud(self, mask: np.ndarray | None = None, stride: int = 1) -> PointCloud:
        """The valid pixels in `mask` on the `stride` lattice, as `backproject` gives them.

        Args:
            mask: [H, W] bool, or None for every valid pixel.
            stride: use every `stride`-th row and column.
        """
        keep = self.valid if mask is None else self.valid & mask
        if stride > 1:
            keep = keep & lattice(keep.shape, stride)
        rows = np.compress(keep.ravel(), self.index.ravel())  # index[keep], ~4x faster
        assert np.all(rows >= 0), "a part asked for pixels that were not back-projected"
        # np.take: points[rows], ~3x faster for [N, 3]
        return PointCloud(np.take(self.points, rows, axis=0), np.take(self.colors, rows, axis=0))


def frame_points(frame: RGBDFrame, max_range: float, needed: np.ndarray) -> FramePoints:
    """Back-project the valid pixels of `frame` in `needed` once.

    Args:
        frame: the posed RGB-D frame.
        max_range: metres; farther depth is not valid.
        needed: [H, W] bool, the pixels any part of the update will ask for.
    """
    valid = frame.valid_depth(max_range)
    cloud = backproject(frame.depth, frame.intrinsics, frame.pose, frame.rgb, needed, max_range)
    index = np.full(valid.shape, -1, dtype=np.int64)
    np.put(index, np.flatnonzero(valid & needed), np.arange(len(cloud)))  # 2D mask assignment
    return FramePoints(valid, index, cloud.points, cloud.colors)
