"""Statistics over seeds: one number per seed in, an estimate with its interval out.

Intervals are bootstrap intervals over seeds (Efron and Tibshirani 1993, *An Introduction to the Bootstrap*); the
interquartile mean and the probability of improvement follow Agarwal et al. 2021, "Deep Reinforcement Learning at
the Edge of the Statistical Precipice" (NeurIPS), as implemented in their library rliable. Every resampling
function takes an explicit ``seed`` so tables are reproducible.

Shared conventions for the intervals:

- identical values give a zero-width interval (the bootstrap distribution is a point);
- a single seed gives no interval (NaN bounds), because there is nothing to resample;
- a non-finite value (NaN or ±inf, e.g. a run that never converged) gives a NaN estimate: decide
  explicitly what such runs mean before asking for an interval;
- no seeds at all is a caller error (``ValueError``).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from typing import Literal, NamedTuple

import numpy as np

from rlcompare.compiled import njit

Statistic = Literal["mean", "iqm"]
Method = Literal["BCa", "percentile"]
OverSeeds = Callable[..., "np.ndarray | float"]
"""A statistic over the seeds on ``axis``: one number for one seed's values, an array over resamples."""


class Estimate(NamedTuple):
    """A point estimate with the bounds of its confidence interval."""

    value: float
    low: float
    high: float

    def format(self, digits: int = 1) -> str:
        """``-176.3 [-180.1, -170.2]`` with ``digits`` decimals; the value alone without an interval; ``n/a``
        without a value."""
        if np.isnan(self.value):
            return "n/a"
        if np.isnan(self.low):
            return f"{self.value:.{digits}f}"
        return f"{self.value:.{digits}f} [{self.low:.{digits}f}, {self.high:.{digits}f}]"


NO_ESTIMATE = Estimate(np.nan, np.nan, np.nan)
"""What a statistic of a non-finite value is."""


def iqm(values: np.ndarray, axis: int = -1) -> np.ndarray | float:
    """Interquartile mean: the mean of the middle 50% of values (Agarwal et al. 2021, rliable ``iqm``).

    ``scipy.stats.trim_mean(values, 0.25, axis)``: ``int(0.25 * n)`` values are cut from each end.
    """
    from scipy import stats  # here, where a number needs it: a plan imports this module

    trimmed: np.ndarray | float = stats.trim_mean(values, 0.25, axis=axis)
    return trimmed


def per_seed_values(per_seed: np.ndarray) -> np.ndarray:
    """One float per seed, checked: a 1-d array, not empty."""
    values = np.asarray(per_seed, dtype=np.float64)
    if values.ndim != 1:
        raise ValueError(f"expected one value per seed (a 1-d array), got shape {values.shape}")
    if values.size == 0:
        raise ValueError("no seeds: cannot estimate anything from an empty array")
    return values


def interval(
    per_seed: np.ndarray,
    statistic: Statistic = "mean",
    confidence: float = 0.95,
    n_resamples: int = 10_000,
    seed: int = 0,
) -> Estimate:
    """A statistic over seeds with a bootstrap confidence interval over seeds.

    ``"mean"``: BCa interval (bias-corrected and accelerated; Efron and Tibshirani 1993, ch. 14).
    ``"iqm"``: percentile interval (ch. 13), as rliable reports for the IQM (Agarwal et al. 2021).
    Degenerate inputs follow the module conventions (zero width, NaN bounds, NaN estimate).
    """
    if statistic not in ("mean", "iqm"):
        raise ValueError(f"statistic must be 'mean' or 'iqm', got {statistic!r}")
    values = per_seed_values(per_seed)
    if not np.all(np.isfinite(values)):
        return NO_ESTIMATE
    function: OverSeeds = np.mean if statistic == "mean" else iqm
    value = float(function(values, axis=-1))
    if values.size < 2:
        return Estimate(value, np.nan, np.nan)
    if np.all(values == values[0]):
        return Estimate(value, value, value)
    method: Method = "BCa" if statistic == "mean" else "percentile"
    low, high = _bootstrap((values,), function, method, confidence, n_resamples, seed)
    return Estimate(value, low, high)


def joint_interval(function: Callable[..., np.ndarray | float], per_seed: tuple[np.ndarray, ...],
                   confidence: float = 0.95, n_resamples: int = 10_000, seed: int = 0) -> Estimate:
    """``function(*per_seed, axis=-1)`` of several quantities measured on the same seeds (one array each, in the
    same order of seeds), with a percentile bootstrap interval that resamples the seeds together across them
    (Efron and Tibshirani 1993, ch. 13): a statistic of means, such as a score model over games, is taken of the
    resample's means, not averaged over seeds."""
    arrays = tuple(per_seed_values(values) for values in per_seed)
    if not all(np.all(np.isfinite(values)) for values in arrays):
        return NO_ESTIMATE
    if len({values.size for values in arrays}) != 1:
        raise ValueError(f"each quantity needs the same seeds: sizes {[values.size for values in arrays]}")
    value = float(function(*arrays, axis=-1))
    if arrays[0].size < 2:
        return Estimate(value, np.nan, np.nan)
    return Estimate(value, *_bootstrap(arrays, function, "percentile", confidence, n_resamples, seed, paired=True))


def mean_interval(per_seed: np.ndarray, confidence: float = 0.95) -> Estimate:
    """The mean over seeds with its Student t interval, for thousands of seeds: there the mean's sampling
    distribution is normal to any precision a table shows, while the bootstrap would resample an array of
    seeds x resamples (and BCa's jackknife one of seeds x seeds: 20 GB for 50,000 seeds). Degenerate inputs
    follow the module conventions."""
    from scipy import stats  # here, where a number needs it: a plan imports this module

    values = per_seed_values(per_seed)
    if not np.all(np.isfinite(values)):
        return NO_ESTIMATE
    mean = float(values.mean())
    if values.size < 2:
        return Estimate(mean, np.nan, np.nan)
    if np.all(values == values[0]):
        return Estimate(mean, mean, mean)
    half = float(stats.t.ppf(0.5 + confidence / 2, values.size - 1) * values.std(ddof=1) / np.sqrt(values.size))
    return Estimate(mean, mean - half, mean + half)


def _bootstrap(data: tuple[np.ndarray, ...], function: OverSeeds, method: Method,
               confidence: float, n_resamples: int, seed: int, paired: bool = False) -> tuple[float, float]:
    """``scipy.stats.bootstrap`` bounds (``paired``: the arrays' seeds resampled together); BCa that cannot be
    computed falls back to the percentile interval.

    BCa is undefined when every resampled statistic lies on one side of the estimate (possible with two
    or three seeds and few resamples); scipy then warns and returns NaN, and the warning is silenced here
    because the NaN is handled.
    """
    from scipy import stats  # here, where a number needs it: a plan imports this module

    if n_resamples < 2:
        raise ValueError(f"n_resamples must be at least 2, got {n_resamples}")
    with warnings.catch_warnings(), np.errstate(invalid="ignore", divide="ignore"):
        warnings.simplefilter("ignore", stats.DegenerateDataWarning)
        # scipy-stubs take a statistic typed to return numbers or one typed to return arrays, not one typed to
        # return either (vectorized, as here, it returns the array of the resamples' statistics)
        result = stats.bootstrap(data, function,  # type: ignore[arg-type]
                                 n_resamples=n_resamples, confidence_level=confidence, method=method,
                                 vectorized=True, paired=paired, rng=np.random.default_rng(seed))
    low, high = float(result.confidence_interval.low), float(result.confidence_interval.high)
    if method == "BCa" and (np.isnan(low) or np.isnan(high)):
        return _bootstrap(data, function, "percentile", confidence, n_resamples, seed, paired)
    return low, high


def paired_difference(
    a: np.ndarray, b: np.ndarray, confidence: float = 0.95, n_resamples: int = 10_000, seed: int = 0
) -> Estimate:
    """Mean over seeds of ``a - b`` for paired seeds, with a BCa bootstrap interval of that mean.

    ``a[s]`` and ``b[s]`` must come from the same seed ``s`` (common random numbers), so the pairs are
    resampled together: the interval is that of the per-seed differences (Efron and Tibshirani 1993,
    ch. 14). Degenerate inputs follow the module conventions.
    """
    a, b = per_seed_values(a), per_seed_values(b)
    if a.shape != b.shape:
        raise ValueError(f"paired values need the same seeds: shapes {a.shape} and {b.shape} differ")
    return interval(a - b, "mean", confidence=confidence, n_resamples=n_resamples, seed=seed)


def independent_difference(
    a: np.ndarray, b: np.ndarray, confidence: float = 0.95, n_resamples: int = 10_000, seed: int = 0
) -> Estimate:
    """Mean of ``a`` minus mean of ``b`` for seeds that share no randomness (two libraries' runs), with a BCa
    bootstrap interval that resamples each side apart (Efron and Tibshirani 1993, ch. 8.3, two samples).
    Fewer than two seeds on either side gives NaN bounds; a non-finite value gives a NaN estimate."""
    a, b = per_seed_values(a), per_seed_values(b)
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        return NO_ESTIMATE
    value = float(a.mean() - b.mean())
    if a.size < 2 or b.size < 2:
        return Estimate(value, np.nan, np.nan)
    if np.all(a == a[0]) and np.all(b == b[0]):
        return Estimate(value, value, value)

    def difference(x: np.ndarray, y: np.ndarray, axis: int = -1) -> np.ndarray:
        return np.asarray(np.mean(x, axis=axis) - np.mean(y, axis=axis))

    low, high = _bootstrap((a, b), difference, "BCa", confidence, n_resamples, seed)
    return Estimate(value, low, high)


PAIRS_COUNTED = 4096
"""Up to this many pairs of values (``n·m``) :func:`improvement_share` counts the pairs directly; above, it ranks."""


@njit(cache=True)
def _twice_u(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Each row's 2U: twice the pairs with ``a > b`` plus those with ``a == b`` (whole numbers, so exact)."""
    rows, n, m = a.shape[0], a.shape[1], b.shape[1]
    out = np.empty(rows)
    for row in range(rows):
        twice = 0
        for i in range(n):
            x = a[row, i]
            for j in range(m):
                twice += 2 * (x > b[row, j]) + (x == b[row, j])
        out[row] = twice
    return out


def improvement_share(a: np.ndarray, b: np.ndarray, axis: int = -1) -> np.ndarray | float:
    """P(X_a > X_b) + ½ P(X_a = X_b) over all pairs, as the Mann-Whitney U of ``a`` over ``n·m``.

    Vectorised over leading axes (bootstrap resamples). Up to :data:`PAIRS_COUNTED` pairs the pairs are counted
    in compiled code (ten times as fast as ranking 10,000 resamples of 30 against 30); beyond that, or with a
    value that is not finite, U comes from the mid-ranks of the pooled sample (``U = Σ ranks of a − n(n+1)/2``),
    in O(n + m) memory per resample. Both give U exactly (a whole number or a half), so the same bits.
    """
    from scipy import stats  # here, where a number needs it: a plan imports this module

    a, b = np.moveaxis(np.asarray(a), axis, -1), np.moveaxis(np.asarray(b), axis, -1)
    n: int = a.shape[-1]
    m: int = b.shape[-1]
    if 0 < n * m <= PAIRS_COUNTED and np.isfinite(a).all() and np.isfinite(b).all():
        lead = np.broadcast_shapes(a.shape[:-1], b.shape[:-1])
        rows_a = np.ascontiguousarray(np.broadcast_to(a, (*lead, n)), dtype=np.float64).reshape(-1, n)
        rows_b = np.ascontiguousarray(np.broadcast_to(b, (*lead, m)), dtype=np.float64).reshape(-1, m)
        counted = (_twice_u(rows_a, rows_b) * 0.5).reshape(lead)
        return counted / (n * m) if lead else np.float64(counted / (n * m))
    ranks = stats.rankdata(np.concatenate([a, b], axis=-1), axis=-1)
    u: np.ndarray | float = ranks[..., :n].sum(axis=-1) - n * (n + 1) / 2
    return u / (n * m)


def probability_of_improvement(
    a: np.ndarray, b: np.ndarray, confidence: float = 0.95, n_resamples: int = 10_000, seed: int = 0
) -> Estimate:
    """Probability that a seed of ``a`` beats a seed of ``b``, with a stratified bootstrap interval.

    P(X_a > X_b) + ½ P(X_a = X_b) over all pairs of seeds (Agarwal et al. 2021, rliable
    ``probability_of_improvement``); equal to the Mann-Whitney U statistic of ``a`` divided by
    ``len(a) * len(b)``. Seeds are *not* paired here: the seeds of ``a`` and of ``b`` are resampled
    independently (rliable's stratified bootstrap) and the interval is the percentile interval.
    Fewer than two seeds on either side gives NaN bounds; a non-finite value gives a NaN estimate.
    """
    a, b = per_seed_values(a), per_seed_values(b)
    unbounded = _improvement_without_bounds(a, b)
    if unbounded is not None:
        return unbounded
    value = float(improvement_share(a, b))
    if np.all(a == a[0]) and np.all(b == b[0]):
        return Estimate(value, value, value)
    low, high = _bootstrap((a, b), improvement_share, "percentile", confidence, n_resamples, seed)
    return Estimate(value, low, high)


def _improvement_without_bounds(a: np.ndarray, b: np.ndarray) -> Estimate | None:
    """P(A > B) where it has no interval: NaN where a value is not finite, NaN bounds with fewer than two seeds on
    either side; None where an interval can be drawn."""
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        return NO_ESTIMATE
    if a.size < 2 or b.size < 2:
        return Estimate(float(improvement_share(a, b)), np.nan, np.nan)
    return None


def improvement_score_interval(a: np.ndarray, b: np.ndarray, confidence: float = 0.95) -> Estimate:
    """P(a seed of ``a`` beats one of ``b``) (ties count half), with Newcombe's score interval (2006, "Confidence
    intervals for an effect size measure based on the Mann-Whitney statistic. Part 2", Stat. Med. 25, his method 5):
    the values θ within z standard errors of the estimate, the error taken at θ itself
    (:func:`newcombe_variance`). Where every seed of ``a`` beats every one of ``b`` its upper end is 1 and its lower
    end stays below, where a bootstrap of 5 seeds a side shrinks to 1.00 [1.00, 1.00]. Fewer than two seeds on
    either side gives NaN bounds; a non-finite value gives a NaN estimate."""
    from scipy import stats  # here, where a number needs it: a plan imports this module
    from scipy.optimize import brentq

    a, b = per_seed_values(a), per_seed_values(b)
    unbounded = _improvement_without_bounds(a, b)
    if unbounded is not None:
        return unbounded
    value = float(improvement_share(a, b))
    z = float(stats.norm.ppf(0.5 + confidence / 2))

    def beyond(theta: float) -> float:
        return (theta - value) ** 2 - z**2 * newcombe_variance(theta, a.size, b.size)

    inner = 1e-9  # at an estimate of 0 or 1 the variance vanishes there too: the other root lies inside
    low = 0.0 if value == 0.0 else float(brentq(beyond, 0.0, min(value, 1.0 - inner)))
    high = 1.0 if value == 1.0 else float(brentq(beyond, max(value, inner), 1.0))
    return Estimate(value, low, high)


def newcombe_variance(theta: float, a_size: int, b_size: int) -> float:
    """The variance of the share of pairs one side wins at its true value ``theta``: Hanley and McNeil's (1982, with
    their approximations θ / (2 - θ) and 2θ² / (1 + θ)) with each side's size less one taken as N* - 1, N* the mean
    of the two sizes (Newcombe's method 5)."""
    middle = (a_size + b_size) / 2
    return theta * (1 - theta) * (2 * middle - 1 - 3 * (middle - 1) / ((2 - theta) * (1 + theta))) / (a_size * b_size)
