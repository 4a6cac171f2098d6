"""Percentile bootstrap intervals over episodes, and paired differences between agents.

The interval of a mean is the percentile bootstrap: resample the episodes with replacement
`resamples` times, take each resample's mean, and report the (1 - c)/2 and (1 + c)/2
quantiles (numpy's 'linear' rule) of those means. A paired difference resamples episodes,
not agents: both agents' values of a drawn episode move together, so the interval is that of
the mean per-episode difference. The generator is seeded, so an interval is reproducible.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from statistics import NormalDist

import numpy as np

from glmap_tools.errors import InvalidInputError

DEFAULT_RESAMPLES = 2000
MAX_RESAMPLES = 100_000  # past this the intervals do not move; 1e8 ran for minutes
DEFAULT_CONFIDENCE = 0.95
_CHUNK = 256  # resamples drawn at once; bounds memory at 256 x n indices


@dataclass(frozen=True)
class Interval:
    """A mean over episodes with its bootstrap interval."""

    mean: float
    low: float
    high: float
    n: int

    def apart_from(self, other: Interval) -> bool:
        """True when the two intervals do not overlap."""
        return self.low > other.high or other.low > self.high


def check_resamples(resamples: int) -> None:
    """Raise unless 1 <= resamples <= MAX_RESAMPLES (a run checks it before playing)."""
    if not 1 <= resamples <= MAX_RESAMPLES:
        raise InvalidInputError(
            f"resamples={resamples} must be 1 to {MAX_RESAMPLES:,} (2000 is usual)."
        )


def _check(values: np.ndarray, resamples: int, confidence: float) -> np.ndarray:
    v = np.asarray(values, dtype=np.float64)
    if v.ndim != 1 or v.size == 0:
        raise InvalidInputError(
            f"bootstrap needs a non-empty 1D array of per-episode values, got shape {v.shape}."
        )
    if not np.isfinite(v).all():
        raise InvalidInputError(
            "bootstrap values contain NaN or inf; drop or clamp non-finite episodes first."
        )
    check_resamples(resamples)
    if not 0.0 < confidence < 1.0:
        raise InvalidInputError(f"confidence={confidence} must lie in (0, 1), e.g. 0.95.")
    return v


def bootstrap_mean(
    values: np.ndarray,
    *,
    resamples: int = DEFAULT_RESAMPLES,
    confidence: float = DEFAULT_CONFIDENCE,
    seed: int = 0,
) -> Interval:
    """The mean of `values` and its percentile bootstrap interval.

    Args:
        values: per-episode values, [N] float.
        resamples: bootstrap resamples B.
        confidence: interval coverage, e.g. 0.95.
        seed: seed of the resampling generator.

    Returns:
        Interval(mean, low, high, n=N).

    Raises:
        InvalidInputError: empty or non-finite values, B < 1, confidence outside (0, 1).
    """
    v = _check(values, resamples, confidence)
    n = v.size
    rng = np.random.default_rng(seed)
    means = np.empty(resamples)
    for start in range(0, resamples, _CHUNK):
        b = min(_CHUNK, resamples - start)
        idx = rng.integers(0, n, size=(b, n))  # [b, N]
        means[start : start + b] = v[idx].mean(axis=1)
    alpha = (1.0 - confidence) / 2.0
    low, high = np.quantile(means, [alpha, 1.0 - alpha])
    return Interval(float(v.mean()), float(low), float(high), n)


def bootstrap_mean_reference(
    values: np.ndarray,
    *,
    resamples: int = DEFAULT_RESAMPLES,
    confidence: float = DEFAULT_CONFIDENCE,
    seed: int = 0,
) -> Interval:
    """Slow reference of `bootstrap_mean`: one resample at a time, quantiles by hand."""
    v = _check(values, resamples, confidence)
    n = v.size
    rng = np.random.default_rng(seed)
    means = []
    for _ in range(resamples):
        idx = rng.integers(0, n, size=n)
        means.append(math.fsum(float(v[i]) for i in idx) / n)
    means.sort()

    def quantile(q: float) -> float:  # linear interpolation between order statistics
        h = (len(means) - 1) * q
        lo = math.floor(h)
        hi = min(lo + 1, len(means) - 1)
        return means[lo] + (h - lo) * (means[hi] - means[lo])

    alpha = (1.0 - confidence) / 2.0
    return Interval(math.fsum(v) / n, quantile(alpha), quantile(1.0 - alpha), n)


def paired_difference(
    a: np.ndarray,
    b: np.ndarray,
    *,
    resamples: int = DEFAULT_RESAMPLES,
    confidence: float = DEFAULT_CONFIDENCE,
    seed: int = 0,
) -> Interval:
    """Mean of a - b over the same episodes, with its paired bootstrap interval.

    Args:
        a: one agent's per-episode values, [N].
        b: the other agent's values on the same N episodes, in the same order, [N].

    Raises:
        InvalidInputError: the arrays differ in length (the episodes are not paired).
    """
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    if a.shape != b.shape:
        raise InvalidInputError(
            f"paired values must cover the same episodes, got {a.shape} and {b.shape}; "
            "keep only the episodes both agents finished."
        )
    return bootstrap_mean(a - b, resamples=resamples, confidence=confidence, seed=seed)


def episodes_needed(discordance: float, difference: float, power: float = 0.8) -> int:
    """Paired episodes for a success-rate difference to show at 95% with the given power.

    A paired difference of two success rates is the mean of per-episode values in {-1, 0, 1};
    its variance is d - D^2 with d the share of episodes where the agents disagree
    (`discordance`) and D the difference, so n = (z_0.975 + z_power)^2 (d - D^2) / D^2.

    Raises:
        InvalidInputError: a share outside (0, 1], a difference not in (0, discordance].
    """

    if not (0.0 < discordance <= 1.0):
        raise InvalidInputError(f"discordance={discordance!r} must be a share in (0, 1].")
    if not (0.0 < abs(difference) <= discordance):
        raise InvalidInputError(
            f"difference={difference!r} must be non-zero and at most the discordance "
            f"{discordance} (agents can differ only where they disagree)."
        )
    if not (0.5 <= power < 1.0):
        raise InvalidInputError(f"power={power!r} must be in [0.5, 1).")
    z = NormalDist().inv_cdf(0.975) + NormalDist().inv_cdf(power)
    return math.ceil(z * z * (discordance - difference**2) / difference**2)
