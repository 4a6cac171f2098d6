"""`GaussianSet`: a structure-of-arrays of 3D Gaussians with the moments needed to merge them."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from glmap_tools.errors import InvalidInputError

DEFAULT_OPACITY = 0.8  # the paper's fixed opacity
COVARIANCE_EPSILON = 1e-6  # m^2, the paper's eps*I regulariser


@dataclass(frozen=True)
class GaussianSet:
    """N 3D Gaussians (mu, Sigma, c, alpha) plus the point count each was fitted from.

    `covs` includes the +eps*I regulariser. Counts make merging exact: combining two
    Gaussians by counts and second moments equals fitting the union of their points.

    Attributes:
        means: [N, 3] float32, metres (world).
        covs: [N, 3, 3] float32, m^2, symmetric positive definite.
        colors: [N, 3] float32, RGB in [0, 1].
        opacities: [N] float32 in (0, 1].
        counts: [N] uint32, number of points behind each Gaussian.
    """

    means: np.ndarray  # [N, 3]
    covs: np.ndarray  # [N, 3, 3]
    colors: np.ndarray  # [N, 3]
    opacities: np.ndarray  # [N]
    counts: np.ndarray  # [N]

    def __post_init__(self) -> None:
        for name in ("means", "covs", "colors", "opacities", "counts"):
            arr = getattr(self, name)
            if not isinstance(arr, np.ndarray) or arr.dtype.kind not in "biuf" or arr.ndim == 0:
                shown = (
                    f"a {arr.dtype} array"
                    if isinstance(arr, np.ndarray)
                    else f"of type {type(arr).__name__}"
                )
                raise InvalidInputError(
                    f"GaussianSet.{name} is {shown}; pass a numeric numpy array "
                    "(the class docstring gives each shape)."
                )
        n = self.means.shape[0]
        shapes = {
            "means": (self.means, (n, 3)),
            "covs": (self.covs, (n, 3, 3)),
            "colors": (self.colors, (n, 3)),
            "opacities": (self.opacities, (n,)),
            "counts": (self.counts, (n,)),
        }
        for name, (arr, shape) in shapes.items():
            if arr.shape != shape:
                raise InvalidInputError(f"GaussianSet.{name} has shape {arr.shape}, not {shape}.")
        object.__setattr__(self, "means", np.ascontiguousarray(self.means, dtype=np.float32))
        object.__setattr__(self, "covs", np.ascontiguousarray(self.covs, dtype=np.float32))
        object.__setattr__(self, "colors", np.ascontiguousarray(self.colors, dtype=np.float32))
        object.__setattr__(
            self, "opacities", np.ascontiguousarray(self.opacities, dtype=np.float32)
        )
        object.__setattr__(self, "counts", np.ascontiguousarray(self.counts, dtype=np.uint32))

    def __len__(self) -> int:
        return int(self.means.shape[0])

    @classmethod
    def empty(cls) -> GaussianSet:
        return cls(
            np.zeros((0, 3)), np.zeros((0, 3, 3)), np.zeros((0, 3)), np.zeros(0), np.zeros(0)
        )

    @classmethod
    def concat(cls, sets: list[GaussianSet]) -> GaussianSet:
        """All Gaussians of `sets`, in order."""
        sets = [s for s in sets if len(s)]
        if not sets:
            return cls.empty()
        return cls(
            np.concatenate([s.means for s in sets]),
            np.concatenate([s.covs for s in sets]),
            np.concatenate([s.colors for s in sets]),
            np.concatenate([s.opacities for s in sets]),
            np.concatenate([s.counts for s in sets]),
        )

    def subset(self, index: np.ndarray) -> GaussianSet:
        """The Gaussians selected by an integer or boolean index (a copy)."""
        arrays = (self.means, self.covs, self.colors, self.opacities, self.counts)
        index = np.asarray(index)
        if index.dtype == bool and index.shape == (len(self),):  # compress: 3x boolean indexing
            return GaussianSet(*(np.compress(index, a, axis=0) for a in arrays))
        if index.dtype.kind in "iu" and index.ndim == 1:  # take: 3x integer indexing
            return GaussianSet(*(np.take(a, index, axis=0) for a in arrays))
        return GaussianSet(*(a[index] for a in arrays))

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(means, covs, colors, opacities, counts), as numba kernels take a set."""
        return self.means, self.covs, self.colors, self.opacities, self.counts

    @classmethod
    def allocate(cls, n: int) -> GaussianSet:
        """N Gaussians of uninitialised memory, for a kernel to fill before anyone reads them."""
        f32 = np.float32
        return cls(
            np.empty((n, 3), f32), np.empty((n, 3, 3), f32), np.empty((n, 3), f32),
            np.empty(n, f32), np.empty(n, np.uint32),
        )  # fmt: skip

    @property
    def nbytes(self) -> int:
        return int(
            self.means.nbytes
            + self.covs.nbytes
            + self.colors.nbytes
            + self.opacities.nbytes
            + self.counts.nbytes
        )

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Axis-aligned ([3] min, [3] max) of the means; raises on an empty set.

        Computed once per set (a set's arrays are never changed in place; the nav policy
        asks each unit's bounds many times a step) and returned as fresh copies.
        """
        if len(self) == 0:
            raise InvalidInputError("an empty GaussianSet has no bounds.")
        cached = self.__dict__.get("_bounds")
        if cached is None:
            cached = (self.means.min(axis=0), self.means.max(axis=0))
            object.__setattr__(self, "_bounds", cached)
        return cached[0].copy(), cached[1].copy()

    def equals(self, other: GaussianSet) -> bool:
        """Bit-exact equality of every array."""
        return all(
            np.array_equal(getattr(self, f), getattr(other, f))
            for f in ("means", "covs", "colors", "opacities", "counts")
        )
