"""`EstimatorConfig`: the settings of the Gaussian Estimator and its curvature-aware merge
(shared by the estimator, its fast and reference paths and the merge)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.gaussians.types import COVARIANCE_EPSILON, DEFAULT_OPACITY


@dataclass(frozen=True)
class EstimatorConfig:
    """Settings of the Gaussian Estimator (paper §3.1) and its curvature-aware merge.

    Attributes:
        voxel_size: voxel edge in metres (the paper used 0.01).
        min_points: fewest points in a voxel's 27-neighbourhood that still emit a Gaussian.
        opacity: the fixed opacity alpha of every Gaussian.
        epsilon: the eps*I covariance regulariser, m^2.
        tau: curvature scaling in the merge threshold 2*voxel*(1 + tau*(kappa_i + kappa_j)).
        lambda_cov: weight of ||Sigma_i - Sigma_j||_F (m^2 read as m) in the distance D.
        lambda_color: weight of ||c_i - c_j|| (RGB in [0, 1] read as m) in the distance D.
        max_merge_sigma: size cap in voxels: a union is refused when the merged Gaussian
            would have sqrt(trace(Sigma)) > max_merge_sigma * voxel_size; None = no cap.
        remerge_sigma: the same cap (voxels) for `merge.remerge`, which unites Gaussians
            fitted in different frames; a little larger than `max_merge_sigma` so a capped
            tile can absorb its re-observation.
        merge: run the curvature-aware merge (False = one Gaussian per voxel).
    """

    voxel_size: float = 0.02
    min_points: int = 5
    opacity: float = DEFAULT_OPACITY
    epsilon: float = COVARIANCE_EPSILON
    tau: float = -5.0  # DESIGN.md said -20; see design.md "tau and real depth noise"
    lambda_cov: float = 0.6
    lambda_color: float = 0.4
    max_merge_sigma: float | None = 1.5
    remerge_sigma: float | None = 2.0
    merge: bool = True

    def __post_init__(self) -> None:
        _check_number(self, "voxel_size", self.voxel_size, "a positive edge in metres, e.g. 0.02")
        if not self.voxel_size > 0:
            raise InvalidInputError(
                f"EstimatorConfig.voxel_size={self.voxel_size!r} must be positive; pass the "
                "voxel edge in metres, e.g. 0.02."
            )
        if isinstance(self.min_points, bool) or not isinstance(self.min_points, int | np.integer):
            raise InvalidInputError(
                f"EstimatorConfig.min_points={self.min_points!r} must be an integer >= 1."
            )
        if self.min_points < 1:
            raise InvalidInputError(
                f"EstimatorConfig.min_points={self.min_points!r} must be >= 1, e.g. 5."
            )
        _check_number(self, "opacity", self.opacity, "a value in (0, 1], e.g. 0.8")
        if not 0 < self.opacity <= 1:
            raise InvalidInputError(
                f"EstimatorConfig.opacity={self.opacity!r} must lie in (0, 1], e.g. 0.8."
            )
        _check_number(self, "epsilon", self.epsilon, "a small positive m^2, e.g. 1e-6")
        if not self.epsilon > 0:
            raise InvalidInputError(
                f"EstimatorConfig.epsilon={self.epsilon!r} must be positive (m^2), e.g. 1e-6, "
                "so every covariance stays invertible."
            )
        _check_number(self, "tau", self.tau, "a negative factor, e.g. -5")
        for name in ("lambda_cov", "lambda_color"):
            value = getattr(self, name)
            _check_number(self, name, value, "a weight >= 0")
            if value < 0:
                raise InvalidInputError(f"EstimatorConfig.{name}={value!r} must be >= 0.")
        for name in ("max_merge_sigma", "remerge_sigma"):
            value = getattr(self, name)
            if value is None:
                continue
            _check_number(self, name, value, "a size in voxels, e.g. 2.5, or None for no cap")
            if not value > 0:
                raise InvalidInputError(
                    f"EstimatorConfig.{name}={value!r} must be a positive size in voxels "
                    "(e.g. 2.5) or None for no cap."
                )
        if not isinstance(self.merge, bool | np.bool_):
            raise InvalidInputError(f"EstimatorConfig.merge={self.merge!r} must be True or False.")
        for name, high in _HIGHEST.items():
            value = getattr(self, name)
            if value is not None and abs(value) > high:
                raise InvalidInputError(
                    f"EstimatorConfig.{name}={value!r} is past {high:g}; check its units "
                    f"(the default is {getattr(EstimatorConfig, name)!r})."
                )
        for name in _HIGHEST:  # plain Python numbers from here on (numpy scalars, big ints)
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, float(value))
        object.__setattr__(self, "min_points", int(self.min_points))
        object.__setattr__(self, "merge", bool(self.merge))

    @property
    def merge_cap_trace(self) -> float:
        """Largest trace(Sigma) (m^2) a union inside one fit may produce; inf = no cap."""
        return _cap_trace(self.max_merge_sigma, self.voxel_size)

    @property
    def remerge_cap_trace(self) -> float:
        """Largest trace(Sigma) (m^2) a union in `merge.remerge` may produce; inf = no cap."""
        return _cap_trace(self.remerge_sigma, self.voxel_size)

    @property
    def candidate_radius(self) -> float:
        """Means closer than this (m) are candidate merge pairs: one voxel."""
        return float(self.voxel_size)


# The largest magnitude each number may have: past these a setting is a units slip, and
# squares or products of it leave float64.
_HIGHEST = {
    "voxel_size": 100.0,
    "opacity": 1.0,
    "epsilon": 1.0,
    "tau": 1e6,
    "lambda_cov": 1e6,
    "lambda_color": 1e6,
    "max_merge_sigma": 1e4,
    "remerge_sigma": 1e4,
}


def _cap_trace(sigma_voxels: float | None, voxel_size: float) -> float:
    return math.inf if sigma_voxels is None else float((sigma_voxels * voxel_size) ** 2)


def _check_number(config: EstimatorConfig, name: str, value: object, hint: str) -> None:
    del config
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise InvalidInputError(f"EstimatorConfig.{name}={value!r} must be {hint}.")
    if not math.isfinite(float(value)):
        raise InvalidInputError(f"EstimatorConfig.{name}={value!r} must be finite; pass {hint}.")
