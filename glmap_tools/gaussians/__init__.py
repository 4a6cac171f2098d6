"""3D Gaussians: the set type, the Gaussian Estimator, merging, splatting, PLY I/O."""

from glmap_tools.gaussians.types import COVARIANCE_EPSILON, DEFAULT_OPACITY, GaussianSet

__all__ = ["COVARIANCE_EPSILON", "DEFAULT_OPACITY", "GaussianSet"]
