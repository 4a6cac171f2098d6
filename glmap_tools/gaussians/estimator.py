"""The Gaussian Estimator f_GE (paper §3.1): analytic Gaussians from a coloured point cloud.

The cloud is voxelised; every occupied voxel v fits one Gaussian to the points of its
27-voxel Chebyshev neighbourhood (mean, 1/n covariance + eps*I, mean colour, fixed
opacity), and the curvature-aware merge then unites similar neighbours so flat areas keep
few Gaussians and curved ones many. See `design.md` beside this file for every decision.
"""

from __future__ import annotations

from typing import Literal, get_args

import numpy as np

from glmap_tools.errors import InvalidInputError, did_you_mean
from glmap_tools.gaussians.config import EstimatorConfig
from glmap_tools.gaussians.types import GaussianSet

# Imports inside functions stay there: gaussians, numba, scipy load on first use.

Backend = Literal["fast", "reference"]
BACKENDS: tuple[str, ...] = get_args(Backend)
MAX_VOXEL_SPAN = (1 << 21) - 3  # voxels per axis the fast path's 21-bit packed keys can hold
# voxels from the origin: beyond, a coordinate's float64 step passes 1/4096 voxel and the
# voxel index leaves the int64 the fast path casts it to (at 2 cm, 2.2e10 m)
MAX_VOXEL_INDEX = float(1 << 40)


class GaussianEstimator:
    """f_GE: fits 3D Gaussians to a coloured point cloud (paper §3.1), then merges them.

    Args:
        config: estimator settings.
        backend: "fast" (numba) or "reference" (plain Python, slow; for tests).
    """

    def __init__(self, config: EstimatorConfig | None = None, backend: Backend = "fast") -> None:
        if config is None:
            config = EstimatorConfig()
        if not isinstance(config, EstimatorConfig):
            raise InvalidInputError(
                f"config is a {type(config).__name__}; pass an EstimatorConfig."
            )
        if backend not in BACKENDS:
            raise InvalidInputError(
                f"backend={backend!r} is unknown.{did_you_mean(str(backend), BACKENDS)} "
                f"Choose from {list(BACKENDS)}."
            )
        self.config = config
        self.backend: Backend = backend

    def fit(self, points: np.ndarray, colors: np.ndarray) -> GaussianSet:
        """Fit (and merge) Gaussians to a coloured point cloud.

        Args:
            points: [N, 3] float, metres (world).
            colors: [N, 3] float RGB in [0, 1].

        Returns:
            The Gaussians, ordered by the packed key of the smallest voxel of each;
            empty when N = 0 or no neighbourhood holds `min_points` points.

        Raises:
            InvalidInputError: NaN/inf points, mismatched shapes, colours outside [0, 1],
                or a cloud wider than the voxel grid can index.
        """
        pts, cols, lo = validate_cloud(points, colors, self.config.voxel_size)
        if len(pts) == 0:
            return GaussianSet.empty()
        if self.backend == "reference":
            from glmap_tools.gaussians._estimator_reference import fit_reference

            return fit_reference(pts, cols.astype(np.float64), self.config).gaussians
        from glmap_tools.gaussians._estimator_fast import fit_fast

        return fit_fast(pts, cols, self.config, lo)

    def fit_with_support(
        self, points: np.ndarray, colors: np.ndarray
    ) -> tuple[GaussianSet, list[np.ndarray]]:
        """Reference fit that also returns, per Gaussian, the indices of its points.

        Always runs the slow reference algorithm, whatever the backend; for tests.

        Returns:
            (gaussians, support) where support[k] is a sorted int64 array of the indices
            into `points` that Gaussian k was fitted from (the set union of its members'
            neighbourhoods).
        """
        from glmap_tools.gaussians._estimator_reference import fit_reference

        pts, cols, _ = validate_cloud(points, colors, self.config.voxel_size)
        if len(pts) == 0:
            return GaussianSet.empty(), []
        fit = fit_reference(pts, cols.astype(np.float64), self.config)
        return fit.gaussians, fit.support


def validate_cloud(
    points: np.ndarray, colors: np.ndarray, voxel_size: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Check a coloured cloud in one pass.

    Returns:
        (points [N, 3] float64, colors [N, 3] float32, [3] smallest point coordinate per
        axis), contiguous.

    Raises:
        InvalidInputError: naming the bad value and the fix.
    """
    from glmap_tools.gaussians._estimator_fast import scan

    pts = np.ascontiguousarray(_as_float_array(points, "points"), dtype=np.float64)
    cols = _as_float_array(colors, "colors")
    cols = np.ascontiguousarray(cols, dtype=np.float32)
    if pts.size == 0 and cols.size == 0:
        return np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(3)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise InvalidInputError(f"points has shape {pts.shape}; pass an [N, 3] array of xyz.")
    if cols.ndim != 2 or cols.shape[1] != 3:
        raise InvalidInputError(f"colors has shape {cols.shape}; pass an [N, 3] array of RGB.")
    if len(pts) != len(cols):
        raise InvalidInputError(
            f"points has {len(pts)} rows but colors has {len(cols)}; pass one colour per point."
        )
    finite, in_range, lo, hi = scan(pts, cols)
    if not finite:
        bad = ~np.isfinite(pts).all(axis=1)
        k = int(np.argmax(bad))
        raise InvalidInputError(
            f"points[{k}] = {pts[k].tolist()} is not finite ({int(bad.sum())} such rows); "
            "drop NaN/inf points first (e.g. points[np.isfinite(points).all(axis=1)])."
        )
    if not in_range:
        bad = ~((cols >= 0.0) & (cols <= 1.0)).all(axis=1)
        k = int(np.argmax(bad))
        hint = " (uint8 colours: divide by 255)" if np.nanmax(cols) > 1.0 else ""
        raise InvalidInputError(
            f"colors[{k}] = {cols[k].tolist()} is outside [0, 1] ({int(bad.sum())} such rows); "
            f"pass finite RGB in [0, 1]{hint}."
        )
    far = float(max(np.abs(lo).max(), np.abs(hi).max()))
    if far / voxel_size >= MAX_VOXEL_INDEX:
        k = int(np.argmax(np.abs(pts).max(axis=1)))
        raise InvalidInputError(
            f"points[{k}] = {pts[k].tolist()} lies {far:.4g} m from the origin, "
            f"{far / voxel_size:.4g} voxels, more than 2^40; shift the cloud near the origin "
            "first (e.g. points - points.mean(axis=0), and add it back to the Gaussians' means)."
        )
    span = float((hi - lo).max()) / voxel_size
    if span >= MAX_VOXEL_SPAN:
        raise InvalidInputError(
            f"the cloud spans {span * voxel_size:.4g} m = {span:.4g} voxels along one axis, "
            f"more than {MAX_VOXEL_SPAN}; crop the cloud or use a larger voxel_size."
        )
    return pts, cols, lo


def _as_float_array(value: np.ndarray, name: str) -> np.ndarray:
    try:
        arr = np.asarray(value)
    except Exception as exc:  # ragged lists and the like
        raise InvalidInputError(f"{name} is not an array ({exc}); pass an [N, 3] array.") from exc
    if arr.dtype.kind not in "fiub":
        raise InvalidInputError(
            f"{name} has dtype {arr.dtype}; pass an [N, 3] array of real numbers."
        )
    return arr if arr.dtype.kind == "f" else arr.astype(np.float64)
