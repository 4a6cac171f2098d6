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
store writes, only the chunks it touched (0.8 m chunks write ~3x the voxels a 320 x 240
frame sees, 1.6 m ones ~4x). It never enters the index grid or any query.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from glmap_tools.gaussians.merge import combine
from glmap_tools.gaussians.types import COVARIANCE_EPSILON, GaussianSet

CHUNK = 16  # voxels per chunk side (x, y): 0.8 m at 5 cm; fixed by store schema 2
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


def _row_order(rows: np.ndarray) -> np.ndarray:  # [K, C] int64 -> [K]
    """`np.lexsort(rows.T[::-1])`: rows in lexicographic order, stable (one argsort of a
    mixed-radix key over the rows' ranges, unless that key would overflow)."""
    from glmap_tools.map._structure_numba import row_order

    rows = np.ascontiguousarray(rows, dtype=np.int64)
    order = row_order(rows)
    if len(order) != len(rows):
        return np.lexsort(rows.T[::-1])
    return order


_NO_CHUNK = (np.zeros((0, 3), np.int64), GaussianSet.allocate(0))


class StructureLayer:
    """All structure Gaussians of a map, in chunks keyed by (ci, cj).

    Args:
        voxel_size: the coarse voxel edge (m) the structure is fitted and merged at.
    """

    def __init__(self, voxel_size: float) -> None:
        self.voxel_size = float(voxel_size)
        self.chunks: dict[ChunkKey, StructureChunk] = {}
        self._all: GaussianSet | None = None
        self._means: np.ndarray | None = None
        self._count = 0  # Gaussians in all chunks, kept by `apply` (a house has ~1000 chunks)

    def __len__(self) -> int:
        return self._count

    def gaussians(self) -> GaussianSet:
        """Every structure Gaussian in one set (chunks in key order), cached until `apply`."""
        if self._all is None:
            self._all = GaussianSet.concat([self.chunks[k].gaussians for k in sorted(self.chunks)])
        return self._all

    def means(self) -> np.ndarray:  # -> [N, 3] float32
        """The means of `gaussians()`, in its order, without gathering the rest (cached until
        `apply`): the walls a step plans with read only these."""
        if self._all is not None:
            return self._all.means
        if self._means is None:
            self._means = np.concatenate(
                [self.chunks[k].gaussians.means for k in sorted(self.chunks)]
                or [GaussianSet.empty().means]
            )
        return self._means

    def voxel_keys(self, gaussians: GaussianSet) -> np.ndarray:  # -> [N, 3] int64
        """The voxel of each Gaussian's mean."""
        return np.floor(gaussians.means.astype(np.float64) / self.voxel_size).astype(np.int64)

    def compute_update(self, fitted: GaussianSet) -> dict[ChunkKey, StructureChunk]:
        """New chunks for the chunks that one frame's structure Gaussians touch.

        Gaussians sharing a voxel (stored or new) are combined into one by their counts and
        moments, as `merge.combine` combines them (the stored one first); stored Gaussians
        in voxels the frame did not see are kept as they are. The layer itself is not
        changed (see `apply`).

        Args:
            fitted: the frame's structure Gaussians (one per coarse voxel, merge off).
        """
        if len(fitted) == 0:
            return {}
        from glmap_tools.map._structure_numba import chunk_runs, frame_rows, merge_chunk

        rows = frame_rows(fitted.means, self.voxel_size, CHUNK)
        order = _row_order(rows)  # stable: a voxel's Gaussians in frame order
        runs = chunk_runs(rows, order).tolist()
        new = fitted.arrays()
        chunks: dict[ChunkKey, StructureChunk] = {}
        for start, stop in zip(runs[:-1], runs[1:], strict=True):
            first = int(order[start])
            key = (int(rows[first, 0]), int(rows[first, 1]))
            stored = self.chunks.get(key)
            keys, gaussians = (stored.keys, stored.gaussians) if stored else _NO_CHUNK
            status, *merged = merge_chunk(
                np.ascontiguousarray(keys, dtype=np.int64),  # one compiled signature
                gaussians.arrays(),
                rows,
                order[start:stop],
                new,
                COVARIANCE_EPSILON,
            )
            if status < 0:  # stored keys out of order or a crowded voxel: not from this layer
                return self.compute_update_reference(fitted)
            chunks[key] = StructureChunk(merged[0], GaussianSet(*merged[1:]))
        return chunks

    def compute_update_reference(self, fitted: GaussianSet) -> dict[ChunkKey, StructureChunk]:
        """`compute_update` the slow, plain way (a dict of voxels); for tests."""
        voxels: dict[tuple[int, int, int], tuple[list[GaussianSet], list[GaussianSet]]] = {}
        new_keys = self.voxel_keys(fitted)
        touched = {(int(k[0]) // CHUNK, int(k[1]) // CHUNK) for k in new_keys}
        for c in touched & set(self.chunks):
            chunk = self.chunks[c]
            for row, k in enumerate(chunk.keys.tolist()):
                one = chunk.gaussians.subset(np.array([row]))
                voxels.setdefault(tuple(k), ([], []))[0].append(one)
        for row, k in enumerate(new_keys.tolist()):
            voxels.setdefault(tuple(k), ([], []))[1].append(fitted.subset(np.array([row])))
        out: dict[ChunkKey, tuple[list[tuple[int, int, int]], list[GaussianSet]]] = {}
        for k in sorted(voxels):
            stored, new = voxels[k]
            keys, sets = out.setdefault((k[0] // CHUNK, k[1] // CHUNK), ([], []))
            if not new:  # not seen by this frame: kept as stored
                keys += [k] * len(stored)
                sets += stored
                continue
            members = GaussianSet.concat(stored + new)
            keys.append(k)
            sets.append(combine(members, np.zeros(len(members), dtype=np.int64)))
        return {
            c: StructureChunk(np.array(keys, dtype=np.int64), GaussianSet.concat(sets))
            for c, (keys, sets) in sorted(out.items())
        }

    def apply(self, chunks: dict[ChunkKey, StructureChunk]) -> None:
        """Make chunks from `compute_update` (or a loaded store) current."""
        if chunks:
            for key, chunk in chunks.items():
                stored = self.chunks.get(key)
                self._count += len(chunk) - (0 if stored is None else len(stored))
            self.chunks.update(chunks)
            self._all = None
            self._means = None

    def equals(self, other: StructureLayer) -> bool:
        """Bit-exact equality of voxel size, chunk keys, voxel keys and Gaussians."""
        if self.voxel_size != other.voxel_size or set(self.chunks) != set(other.chunks):
            return False
        return all(
            np.array_equal(c.keys, other.chunks[k].keys)
            and c.gaussians.equals(other.chunks[k].gaussians)
            for k, c in self.chunks.items()
        )
