"""Statistics over seeds: one number per seed in, an estimate with its interval out."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy import stats


class Estimate(NamedTuple):
    """A point estimate with the bounds of its confidence interval."""

    value: float
    low: float
    high: float

    def format(self, digits: int = 1) -> str:
        if np.isnan(self.low):
            return f"{self.value:.{digits}f}"
        return f"{self.value:.{digits}f} [{self.low:.{digits}f}, {self.high:.{digits}f}]"


def mean_interval(
    per_seed: np.ndarray, confidence: float = 0.95, n_resamples: int = 10_000, seed: int = 0
) -> Estimate:
    """Mean over seeds with a BCa bootstrap interval (Efron and Tibshirani 1993, ch. 14).

    Identical values give a zero-width interval; a single seed gives no interval (NaN bounds).
    """
    values = np.asarray(per_seed, dtype=np.float64)
    mean = float(values.mean())
    if values.size < 2:
        return Estimate(mean, np.nan, np.nan)
    if np.all(values == values[0]):
        return Estimate(mean, mean, mean)
    result = stats.bootstrap((values,), np.mean, confidence_level=confidence, n_resamples=n_resamples,
                             method="BCa", rng=np.random.default_rng(seed))
    return Estimate(mean, float(result.confidence_interval.low), float(result.confidence_interval.high))
