"""Intervals over an ensemble of runs (seeds): the mean with its Student-t interval and the percentile range."""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import scipy.stats


@lru_cache(maxsize=1024)
def t_quantile(p: float, df: int) -> float:
    """Student t's quantile p at ``df`` degrees of freedom (``scipy.stats.t.ppf``, its value; remembered, since
    reports ask for the same few thousands of times)."""
    return float(scipy.stats.t.ppf(p, df))


@dataclass(frozen=True)
class EnsembleInterval:
    """Mean and intervals of a quantity over an ensemble (seeds); arrays of shape ``values.shape[1:]``.

    Attributes:
        mean: Sample mean.
        std: Sample standard deviation (ddof = 1; NaN for n = 1).
        n: Ensemble size.
        mean_low: Lower end of the Student-t interval of the mean, mean − t_{(1+level)/2, n−1}·std/√n.
        mean_high: Upper end (both NaN for n = 1).
        low: Lower percentile (1 − level)/2 of the values (where a single run falls; linear interpolation).
        high: Upper percentile (1 + level)/2.
        median: Median of the values.
        level: Level of both intervals.
    """

    mean: np.ndarray | float
    std: np.ndarray | float
    n: int
    mean_low: np.ndarray | float
    mean_high: np.ndarray | float
    low: np.ndarray | float
    high: np.ndarray | float
    median: np.ndarray | float
    level: float


def ensemble_interval(values: np.ndarray, level: float = 0.95) -> EnsembleInterval:
    """Mean with a t-interval and the central percentile interval over an ensemble of runs (seeds).

    Two intervals answer two questions: [mean_low, mean_high] is where the ensemble mean lies (Student t,
    exact for normally distributed values, shrinking as 1/√n); [low, high] is where one run's value falls
    (empirical percentiles, needs many seeds to mean much). A validation row quotes the mean with its
    t-interval; the percentile range shows the spread between seeds.

    Args:
        values: Shape (n,) or (n, ...): one value per seed along axis 0; finite.
        level: Level of both intervals, in (0, 1).

    Returns:
        An :class:`EnsembleInterval` (floats for 1-D input).
    """
    v = np.asarray(values, dtype=np.float64)
    if v.ndim == 0 or v.shape[0] == 0:
        raise ValueError("ensemble_interval needs at least one value along axis 0")
    if not np.all(np.isfinite(v)):
        raise ValueError("ensemble values must be finite (drop failed runs first)")
    if not 0.0 < level < 1.0:
        raise ValueError(f"level must lie in (0, 1), got {level}")
    n = v.shape[0]
    mean = v.mean(axis=0)
    if n > 1:
        std = v.std(axis=0, ddof=1)
        half = t_quantile(0.5 + level / 2.0, n - 1) * std / np.sqrt(n)
    else:
        std = half = np.full(v.shape[1:], np.nan)
    low, high = np.percentile(v, [50.0 * (1.0 - level), 50.0 * (1.0 + level)], axis=0)

    def out(a: np.ndarray) -> np.ndarray | float:
        return float(a) if np.ndim(a) == 0 else a

    return EnsembleInterval(
        mean=out(mean),
        std=out(std),
        n=n,
        mean_low=out(mean - half),
        mean_high=out(mean + half),
        low=out(low),
        high=out(high),
        median=out(np.median(v, axis=0)),
        level=level,
    )
