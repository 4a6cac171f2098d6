"""The structure background layer: walls, floor and everything no object mask covers.

DESIGN.md: structure "may be kept as a background layer of Gaussians: rendered and
occluding, never a semantic unit". Every frame's valid depth pixels outside all object
masks are fitted by the Gaussian Estimator at a coarse voxel (`MapConfig.structure_voxel`,
5 cm by default: a wall only has to occlude and look plausible, and at 5 cm a 10 x 10 m
apartment's floor and walls take ~80k Gaussians, 5.4 MB, instead of ~500k at 2 cm) with
the curvature merge off, so each Gaussian belongs to one voxel: the voxel of its mean.

A re-observed voxel merges with what is stored there (exact count-weighted moments, as
`merge.combine` unites Gaussians), so a wall seen a hundred times still holds one Gaussian
per voxel: the layer grows with the observed surface, never with the number of frames.
It is kept in sparse chunks of CHUNK x CHUNK voxel columns, so a frame replaces, and the
store writes, only the chunks it touched. It never enters the index grid or any query.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from glmap_tools.gaussians.merge import combine
from glmap_tools.gaussians.types import GaussianSet

CHUNK = 32  # voxels per chunk side (x and y): 1.6 m at the default 5 cm voxel
ChunkKey = tuple[int, int]


@dataclass(frozen=True, eq=False)
class StructureChunk:
    """The structure Gaussians whose voxels fall in one CHUNK x CHUNK column of voxels.

    Immutable: an update builds a new chunk, so a failed frame changes nothing.

    Attributes:
        keys: [K, 3] int64 voxel index (floor(mean / voxel) when fitted) of each Gaussian,
            unique, in lexicographic (x, y, z) order.
        gaussians: the K Gaussians, in the order of `keys`.
    """

    keys: np.ndarray  # [K, 3]
    gaussians: GaussianSet

    def __len__(self) -> int:
        return len(self.gaussians)


def chunk_of_keys(keys: np.ndarray) -> np.ndarray:  # [K, 3] -> [K, 2]
    """The chunk (ci, cj) of each voxel key."""
    return np.floor_divide(keys[:, :2], CHUNK)


def _group_sorted(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(order, labels): a lexicographic sort of [N, 3] keys and a label per sorted row,
    equal labels for equal keys, increasing with the key."""
    order = np.lexsort((keys[:, 2], keys[:, 1], keys[:, 0]))
    sorted_keys = keys[order]
    new = np.ones(len(keys), dtype=bool)
    new[1:] = np.any(np.diff(sorted_keys, axis=0) != 0, axis=1)
    return order, np.cumsum(new) - 1


class StructureLayer:
    """All structure Gaussians of a map, in chunks keyed by (ci, cj).

    Args:
        voxel_size: the coarse voxel edge (m) the structure is fitted and merged at.
    """

    def __init__(self, voxel_size: float) -> None:
        self.voxel_size = float(voxel_size)
        self.chunks: dict[ChunkKey, StructureChunk] = {}
        self._all: GaussianSet | None = None

    def __len__(self) -> int:
        return sum(len(c) for c in self.chunks.values())

    def gaussians(self) -> GaussianSet:
        """Every structure Gaussian in one set (chunks in key order), cached until `apply`."""
        if self._all is None:
            self._all = GaussianSet.concat([self.chunks[k].gaussians for k in sorted(self.chunks)])
        return self._all

    def voxel_keys(self, gaussians: GaussianSet) -> np.ndarray:  # -> [N, 3] int64
        """The voxel of each Gaussian's mean."""
        return np.floor(gaussians.means.astype(np.float64) / self.voxel_size).astype(np.int64)

    def compute_update(self, fitted: GaussianSet) -> dict[ChunkKey, StructureChunk]:
        """New chunks for the chunks that one frame's structure Gaussians touch.

        Gaussians sharing a voxel (stored or new) are combined into one by their counts and
        moments; the layer itself is not changed (see `apply`).

        Args:
            fitted: the frame's structure Gaussians (one per coarse voxel, merge off).
        """
        if len(fitted) == 0:
            return {}
        new_keys = self.voxel_keys(fitted)
        touched = {tuple(map(int, c)) for c in np.unique(chunk_of_keys(new_keys), axis=0)}
        old = [self.chunks[c] for c in sorted(touched) if c in self.chunks]
        keys = np.concatenate([*(c.keys for c in old), new_keys])
        g = GaussianSet.concat([*(c.gaussians for c in old), fitted])
        order, labels = _group_sorted(keys)
        merged = combine(g.subset(order), labels)
        first = np.flatnonzero(np.r_[True, np.diff(labels) != 0])
        merged_keys = keys[order][first]
        chunk = chunk_of_keys(merged_keys)
        by_chunk = np.lexsort((chunk[:, 1], chunk[:, 0]))  # stable: keys stay sorted within
        chunk, merged_keys = chunk[by_chunk], merged_keys[by_chunk]
        merged = merged.subset(by_chunk)
        bounds = np.flatnonzero(np.r_[True, np.any(np.diff(chunk, axis=0) != 0, axis=1), True])
        out: dict[ChunkKey, StructureChunk] = {}
        for start, stop in zip(bounds[:-1], bounds[1:], strict=True):
            key = (int(chunk[start, 0]), int(chunk[start, 1]))
            rows = np.arange(start, stop)
            out[key] = StructureChunk(merged_keys[rows].copy(), merged.subset(rows))
        return out

    def apply(self, chunks: dict[ChunkKey, StructureChunk]) -> None:
        """Make chunks from `compute_update` (or a loaded store) current."""
        if chunks:
            self.chunks.update(chunks)
            self._all = None

    def equals(self, other: StructureLayer) -> bool:
        """Bit-exact equality of voxel size, chunk keys, voxel keys and Gaussians."""
        if self.voxel_size != other.voxel_size or set(self.chunks) != set(other.chunks):
            return False
        return all(
            np.array_equal(c.keys, other.chunks[k].keys)
            and c.gaussians.equals(other.chunks[k].gaussians)
            for k, c in self.chunks.items()
        )
