"""Statistics over seeds: one number per seed in, an estimate with its interval out.

Intervals are bootstrap intervals over seeds (Efron and Tibshirani 1993, *An Introduction to the
Bootstrap*); the interquartile mean and the probability of improvement follow Agarwal et al. 2021,
"Deep Reinforcement Learning at the Edge of the Statistical Precipice" (NeurIPS), as implemented in
their library rliable. Every resampling function takes an explicit ``seed`` so tables are reproducible.

Shared conventions for the intervals:

- identical values give a zero-width interval (the bootstrap distribution is a point);
- a single seed gives no interval (NaN bounds), because there is nothing to resample;
- a non-finite value (NaN or ±inf, e.g. a run that never converged) gives a NaN estimate: decide
  explicitly what such runs mean before asking for an interval;
- no seeds at all is a caller error (``ValueError``).
"""

from __future__ import annotations

import warnings
from typing import Literal, NamedTuple

import numpy as np
from scipy import stats

Statistic = Literal["mean", "iqm"]

Verdict = Literal["supported", "contradicted", "not resolved at this number of seeds"]
SUPPORTED: Verdict = "supported"
CONTRADICTED: Verdict = "contradicted"
NOT_RESOLVED: Verdict = "not resolved at this number of seeds"
VERDICTS: tuple[Verdict, ...] = (SUPPORTED, CONTRADICTED, NOT_RESOLVED)


class Estimate(NamedTuple):
    """A point estimate with the bounds of its confidence interval."""

    value: float
    low: float
    high: float

    def format(self, digits: int = 1) -> str:
        if np.isnan(self.low):
            return f"{self.value:.{digits}f}"
        return f"{self.value:.{digits}f} [{self.low:.{digits}f}, {self.high:.{digits}f}]"


_NAN = Estimate(np.nan, np.nan, np.nan)


def iqm(values: np.ndarray, axis: int = -1) -> np.ndarray | float:
    """Interquartile mean: the mean of the middle 50% of values (Agarwal et al. 2021, rliable ``iqm``).

    ``scipy.stats.trim_mean(values, 0.25, axis)``: ``int(0.25 * n)`` values are cut from each end.
    """
    return stats.trim_mean(values, 0.25, axis=axis)


def _per_seed(per_seed: np.ndarray) -> np.ndarray:
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
    values = _per_seed(per_seed)
    if not np.all(np.isfinite(values)):
        return _NAN
    function = np.mean if statistic == "mean" else iqm
    value = float(function(values, axis=-1))
    if values.size < 2:
        return Estimate(value, np.nan, np.nan)
    if np.all(values == values[0]):
        return Estimate(value, value, value)
    method = "BCa" if statistic == "mean" else "percentile"
    low, high = _bootstrap((values,), function, method, confidence, n_resamples, seed)
    return Estimate(value, low, high)


def _bootstrap(data: tuple[np.ndarray, ...], function, method: str, confidence: float, n_resamples: int,
               seed: int) -> tuple[float, float]:
    """``scipy.stats.bootstrap`` bounds; BCa that cannot be computed falls back to the percentile interval.

    BCa is undefined when every resampled statistic lies on one side of the estimate (possible with two
    or three seeds and few resamples); scipy then warns and returns NaN, and the warning is silenced here
    because the NaN is handled.
    """
    if n_resamples < 2:
        raise ValueError(f"n_resamples must be at least 2, got {n_resamples}")
    with warnings.catch_warnings(), np.errstate(invalid="ignore", divide="ignore"):
        warnings.simplefilter("ignore", stats.DegenerateDataWarning)
        result = stats.bootstrap(data, function, n_resamples=n_resamples, confidence_level=confidence,
                                 method=method, vectorized=True, paired=False,
                                 rng=np.random.default_rng(seed))
    low, high = float(result.confidence_interval.low), float(result.confidence_interval.high)
    if method == "BCa" and (np.isnan(low) or np.isnan(high)):
        return _bootstrap(data, function, "percentile", confidence, n_resamples, seed)
    return low, high


def paired_difference(
    a: np.ndarray, b: np.ndarray, confidence: float = 0.95, n_resamples: int = 10_000, seed: int = 0
) -> Estimate:
    """Mean over seeds of ``a - b`` for paired seeds, with a BCa bootstrap interval of that mean.

    ``a[s]`` and ``b[s]`` must come from the same seed ``s`` (common random numbers), so the pairs are
    resampled together: the interval is that of the per-seed differences (Efron and Tibshirani 1993,
    ch. 14). Degenerate inputs follow the module conventions.
    """
    a, b = _per_seed(a), _per_seed(b)
    if a.shape != b.shape:
        raise ValueError(f"paired values need the same seeds: shapes {a.shape} and {b.shape} differ")
    return interval(a - b, "mean", confidence=confidence, n_resamples=n_resamples, seed=seed)


def _improvement(a: np.ndarray, b: np.ndarray, axis: int = -1) -> np.ndarray:
    """P(X_a > X_b) + ½ P(X_a = X_b) over all pairs, as the Mann-Whitney U of ``a`` over ``n·m``.

    Computed from mid-ranks of the pooled sample (``U = Σ ranks of a − n(n+1)/2``), which is
    vectorised over leading axes and uses O(n + m) memory per resample instead of O(n·m).
    """
    a, b = np.moveaxis(a, axis, -1), np.moveaxis(b, axis, -1)
    n, m = a.shape[-1], b.shape[-1]
    ranks = stats.rankdata(np.concatenate([a, b], axis=-1), axis=-1)
    u = ranks[..., :n].sum(axis=-1) - n * (n + 1) / 2
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
    a, b = _per_seed(a), _per_seed(b)
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        return _NAN
    value = float(_improvement(a, b))
    if a.size < 2 or b.size < 2:
        return Estimate(value, np.nan, np.nan)
    if np.all(a == a[0]) and np.all(b == b[0]):
        return Estimate(value, value, value)
    low, high = _bootstrap((a, b), _improvement, "percentile", confidence, n_resamples, seed)
    return Estimate(value, low, high)


def rank_test(a: np.ndarray, b: np.ndarray, paired: bool = True) -> float:
    """Two-sided p-value of a rank test that ``a`` and ``b`` come from the same distribution.

    ``paired``: Wilcoxon signed-rank test of the per-seed differences, zero differences split between
    the two signs (Pratt/``zero_method="zsplit"``); all differences zero gives p = 1.
    Otherwise: Mann-Whitney U test of two independent samples; all values equal gives p = 1.
    """
    a, b = _per_seed(a), _per_seed(b)
    if paired:
        if a.shape != b.shape:
            raise ValueError(f"paired values need the same seeds: shapes {a.shape} and {b.shape} differ")
        if np.all(a == b):
            return 1.0
        return float(stats.wilcoxon(a, b, zero_method="zsplit").pvalue)
    pooled = np.concatenate([a, b])
    if np.all(pooled == pooled[0]):
        return 1.0
    return float(stats.mannwhitneyu(a, b, alternative="two-sided").pvalue)


def verdict(difference: Estimate, p_value: float, claimed_sign: int, level: float = 0.05) -> Verdict:
    """Whether the seeds support a claimed direction of a difference.

    ``claimed_sign``: +1 if the claim is that the difference is positive, -1 if negative.
    Supported: the interval excludes 0 on the claimed side and ``p_value < level``.
    Contradicted: the interval excludes 0 on the opposite side and ``p_value < level``.
    Otherwise (including NaN bounds or p-value): not resolved at this number of seeds.
    """
    if claimed_sign not in (1, -1):
        raise ValueError(f"claimed_sign must be +1 or -1, got {claimed_sign!r}")
    if not p_value < level:
        return NOT_RESOLVED
    if difference.low > 0:
        observed = 1
    elif difference.high < 0:
        observed = -1
    else:
        return NOT_RESOLVED
    return SUPPORTED if observed == claimed_sign else CONTRADICTED


def ratio_of_means(
    a: np.ndarray, b: np.ndarray, confidence: float = 0.95, n_resamples: int = 10_000, seed: int = 0
) -> Estimate:
    """``mean(a) / mean(b)`` over paired seeds, with a percentile bootstrap interval resampling pairs."""
    a, b = _per_seed(a), _per_seed(b)
    if a.shape != b.shape:
        raise ValueError(f"paired values need the same seeds: shapes {a.shape} and {b.shape} differ")
    ratio = float(a.mean() / b.mean())
    if a.size < 2:
        return Estimate(ratio, np.nan, np.nan)
    picks = np.random.default_rng(seed).integers(0, a.size, size=(n_resamples, a.size))
    resampled = a[picks].mean(axis=1) / b[picks].mean(axis=1)
    tail = (1 - confidence) / 2
    low, high = np.quantile(resampled, [tail, 1 - tail])
    return Estimate(ratio, float(low), float(high))


def equivalence_verdict(difference: Estimate, margin: float) -> Verdict:
    """Whether two methods are the same within ``margin``: supported when the whole interval of the
    difference lies inside ``[-margin, margin]`` (two one-sided tests at the interval's level),
    contradicted when it lies wholly outside, otherwise not resolved."""
    if np.isnan(difference.low) or np.isnan(difference.high):
        return NOT_RESOLVED
    if -margin < difference.low and difference.high < margin:
        return SUPPORTED
    if difference.low > margin or difference.high < -margin:
        return CONTRADICTED
    return NOT_RESOLVED


def ratio_verdict(ratio: Estimate, claimed: float) -> Verdict:
    """Whether a ratio is "about" ``claimed``: supported when its interval holds ``claimed`` and excludes
    1 (no difference), contradicted when it excludes ``claimed``, otherwise not resolved."""
    if np.isnan(ratio.low) or np.isnan(ratio.high):
        return NOT_RESOLVED
    if not ratio.low <= claimed <= ratio.high:
        return CONTRADICTED
    return SUPPORTED if not ratio.low <= 1.0 <= ratio.high else NOT_RESOLVED
