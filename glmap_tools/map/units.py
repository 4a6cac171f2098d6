"""Semantic units of a GLMap: `InstanceUnit` (Gaussians + text) and `RegionUnit` (ids + text)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from glmap_tools.gaussians.types import GaussianSet


@dataclass(frozen=True, eq=False)
class InstanceUnit:
    """An instance o = (G, T_o): 3D Gaussians and a language description buffer.

    Units are immutable; an update builds a new unit, so a failed update changes nothing.
    Equality is identity (the arrays make field-wise == ambiguous).

    Attributes:
        id: stable global id (shared id space with regions, never reused).
        label: the most recent short category label.
        text: T_o, descriptions joined by the text-buffer delimiter.
        embedding: [D] float32 unit vector: normalised sum of the descriptions' embeddings.
        gaussians: the instance's 3D Gaussians.
        observations: number of frames that observed it.
        first_frame: index of the first frame that observed it.
        last_frame: index of the last frame that observed it.
    """

    id: int
    label: str
    text: str
    embedding: np.ndarray  # [D]
    gaussians: GaussianSet
    observations: int
    first_frame: int
    last_frame: int

    @property
    def kind(self) -> str:
        return "instance"

    @property
    def centroid(self) -> np.ndarray:
        """[3] point-count-weighted mean of the Gaussians (m)."""
        w = self.gaussians.counts.astype(np.float64)
        return (self.gaussians.means.astype(np.float64) * w[:, None]).sum(0) / w.sum()

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Axis-aligned bounds ([3] min, [3] max) of the Gaussian means (m)."""
        return self.gaussians.bounds()


@dataclass(frozen=True, eq=False)
class RegionUnit:
    """A region r = (I_r, T_r): a set of instance ids and a description buffer.

    Attributes:
        id: stable global id (shared id space with instances).
        text: T_r.
        embedding: [D] float32 unit vector.
        instance_ids: I_r, sorted global instance ids.
        observations: number of frames that observed it.
        first_frame: index of the first frame that observed it.
        last_frame: index of the last frame that observed it.
    """

    id: int
    text: str
    embedding: np.ndarray  # [D]
    instance_ids: tuple[int, ...]
    observations: int
    first_frame: int
    last_frame: int

    @property
    def kind(self) -> str:
        return "region"
