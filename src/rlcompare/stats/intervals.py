"""Statistics over seeds: one number per seed in, an estimate with its interval out, and verdicts on claims.

Intervals are bootstrap intervals over seeds (Efron and Tibshirani 1993, *An Introduction to the
Bootstrap*); the interquartile mean and the probability of improvement follow Agarwal et al. 2021,
"Deep Reinforcement Learning at the Edge of the Statistical Precipice" (NeurIPS), as implemented in
their library rliable. Every resampling function takes an explicit ``seed`` so tables are reproducible.
Equivalence is tested with two one-sided tests (Schuirmann 1987, "A comparison of the two one-sided tests
procedure and the power approach for assessing the equivalence of average bioavailability", J.
Pharmacokinet. Biopharm. 15(6)); a family of claims is corrected with Holm's step-down procedure (Holm 1979,
"A simple sequentially rejective multiple test procedure", Scand. J. Statist. 6(2)).

Shared conventions for the intervals:

- identical values give a zero-width interval (the bootstrap distribution is a point);
- a single seed gives no interval (NaN bounds), because there is nothing to resample;
- a non-finite value (NaN or ±inf, e.g. a run that never converged) gives a NaN estimate: decide
  explicitly what such runs mean before asking for an interval;
- no seeds at all is a caller error (``ValueError``).

Every study compares A against B the same way and says what it found in one vocabulary read off :func:`verdict`
(:mod:`rlcompare.stats.compare`).

The verdict labels (``docs/why.md``, "Verdicts"):

- ``supported`` / ``contradicted``: the test of the claim, or of its opposite, rejects at the family-wise level;
- ``not resolved``: neither does, and more seeds (or, for runs that never converged, more episodes) could settle it;
- ``undecidable here``: the quantity the claim reads lies below its own noise floor, so more seeds will not settle it;
- ``no data``: nothing to test (e.g. every seed censored: nothing converged).
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable
from typing import Literal, NamedTuple

import numpy as np
from scipy import stats

from rlcompare.compiled import njit

Statistic = Literal["mean", "iqm"]

Verdict = Literal["supported", "contradicted", "not resolved", "undecidable here", "no data"]
SUPPORTED: Verdict = "supported"
CONTRADICTED: Verdict = "contradicted"
NOT_RESOLVED: Verdict = "not resolved"
UNDECIDABLE: Verdict = "undecidable here"
NO_DATA: Verdict = "no data"
VERDICTS: tuple[Verdict, ...] = (SUPPORTED, CONTRADICTED, NOT_RESOLVED, UNDECIDABLE, NO_DATA)
ALPHA = 0.05
"""Family-wise error rate of one report's claims."""


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


def mean_interval(per_seed: np.ndarray, confidence: float = 0.95) -> Estimate:
    """The mean over seeds with its Student t interval, for thousands of seeds: there the mean's sampling
    distribution is normal to any precision a table shows, while the bootstrap would resample an array of
    seeds x resamples (and BCa's jackknife one of seeds x seeds: 20 GB for 50,000 seeds). Degenerate inputs
    follow the module conventions."""
    values = _per_seed(per_seed)
    if not np.all(np.isfinite(values)):
        return _NAN
    mean = float(values.mean())
    if values.size < 2:
        return Estimate(mean, np.nan, np.nan)
    if np.all(values == values[0]):
        return Estimate(mean, mean, mean)
    half = float(stats.t.ppf(0.5 + confidence / 2, values.size - 1) * values.std(ddof=1) / np.sqrt(values.size))
    return Estimate(mean, mean - half, mean + half)


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


def improvement_share(a: np.ndarray, b: np.ndarray, axis: int = -1) -> np.ndarray:
    """P(X_a > X_b) + ½ P(X_a = X_b) over all pairs, as the Mann-Whitney U of ``a`` over ``n·m``.

    Vectorised over leading axes (bootstrap resamples). Up to :data:`PAIRS_COUNTED` pairs the pairs are counted
    in compiled code (ten times as fast as ranking 10,000 resamples of 30 against 30); beyond that, or with a
    value that is not finite, U comes from the mid-ranks of the pooled sample (``U = Σ ranks of a − n(n+1)/2``),
    in O(n + m) memory per resample. Both give U exactly (a whole number or a half), so the same bits.
    """
    a, b = np.moveaxis(np.asarray(a), axis, -1), np.moveaxis(np.asarray(b), axis, -1)
    n, m = a.shape[-1], b.shape[-1]
    if 0 < n * m <= PAIRS_COUNTED and np.isfinite(a).all() and np.isfinite(b).all():
        lead = np.broadcast_shapes(a.shape[:-1], b.shape[:-1])
        rows_a = np.ascontiguousarray(np.broadcast_to(a, (*lead, n)), dtype=np.float64).reshape(-1, n)
        rows_b = np.ascontiguousarray(np.broadcast_to(b, (*lead, m)), dtype=np.float64).reshape(-1, m)
        u = (_twice_u(rows_a, rows_b) * 0.5).reshape(lead)
        return u / (n * m) if lead else np.float64(u / (n * m))
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
    value = float(improvement_share(a, b))
    if a.size < 2 or b.size < 2:
        return Estimate(value, np.nan, np.nan)
    if np.all(a == a[0]) and np.all(b == b[0]):
        return Estimate(value, value, value)
    low, high = _bootstrap((a, b), improvement_share, "percentile", confidence, n_resamples, seed)
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


def verdict(difference: Estimate, p_value: float, claimed_sign: int, level: float = ALPHA) -> Verdict:
    """Whether the seeds support a claimed direction of a difference.

    ``claimed_sign``: +1 if the claim is that the difference is positive, -1 if negative; ``p_value``: a
    two-sided p-value, Holm-adjusted where the claim belongs to a family.
    Supported: the interval excludes 0 on the claimed side and ``p_value < level``.
    Contradicted: the interval excludes 0 on the opposite side and ``p_value < level``.
    No data: no estimate (NaN). Otherwise (including NaN bounds or p-value): not resolved.
    """
    if claimed_sign not in (1, -1):
        raise ValueError(f"claimed_sign must be +1 or -1, got {claimed_sign!r}")
    if np.isnan(difference.value):
        return NO_DATA
    if not p_value < level:
        return NOT_RESOLVED
    if difference.low > 0:
        observed = 1
    elif difference.high < 0:
        observed = -1
    else:
        return NOT_RESOLVED
    return SUPPORTED if observed == claimed_sign else CONTRADICTED


class Equivalence(NamedTuple):
    """Two one-sided tests of a mean against an equivalence margin ``[lower, upper]`` (Schuirmann 1987).

    ``p_equivalent``: the larger of the two one-sided p-values (H0: mean <= lower, H0: mean >= upper).
    ``p_beyond``: twice the one-sided p-value that the mean lies beyond the margin on the estimate's side
    (1 when the estimate lies inside): below ``level`` exactly when the two-sided ``1 - level`` interval lies
    wholly outside the margin.
    """

    estimate: Estimate
    lower: float
    upper: float
    p_equivalent: float
    p_beyond: float

    @property
    def inside(self) -> bool:
        return bool(self.lower <= self.estimate.value <= self.upper)

    @property
    def p(self) -> float:
        """The p-value of the test the estimate points to: equivalence inside the margin, beyond it outside."""
        return self.p_equivalent if self.inside or np.isnan(self.estimate.value) else self.p_beyond


def _one_sided(distance: float, se: float, df: int) -> float:
    """p-value of H0: distance <= 0 against distance > 0, for a mean ``distance`` from a bound (Student t)."""
    if se == 0:
        return 0.0 if distance > 0 else 1.0
    return float(stats.t.sf(distance / se, df))


def tost(values: np.ndarray, lower: float, upper: float, confidence: float = 0.95) -> Equivalence:
    """Whether the mean of ``values`` (e.g. paired differences over seeds) lies within ``[lower, upper]``.

    Two one-sided paired t-tests (Schuirmann 1987): equivalence at level α when both reject, i.e. when
    ``max(p_lower, p_upper) < α``, which is the ``1 - 2α`` t interval lying inside the margin. The estimate
    carries the two-sided ``confidence`` t interval. One seed gives NaN p-values; identical values give
    p = 0 or 1 (a point either inside or outside); a non-finite value gives a NaN estimate.
    """
    if not lower < upper:
        raise ValueError(f"the margin needs lower < upper, got [{lower}, {upper}]")
    values = _per_seed(values)
    if not np.all(np.isfinite(values)):
        return Equivalence(_NAN, lower, upper, np.nan, np.nan)
    mean, n = float(values.mean()), values.size
    if n < 2:
        return Equivalence(Estimate(mean, np.nan, np.nan), lower, upper, np.nan, np.nan)
    se, df = float(values.std(ddof=1) / np.sqrt(n)), n - 1
    half = float(stats.t.ppf(0.5 + confidence / 2, df)) * se
    p_lower, p_upper = _one_sided(mean - lower, se, df), _one_sided(upper - mean, se, df)
    if mean > upper:
        p_beyond = 2 * _one_sided(mean - upper, se, df)
    elif mean < lower:
        p_beyond = 2 * _one_sided(lower - mean, se, df)
    else:
        p_beyond = 1.0
    return Equivalence(Estimate(mean, mean - half, mean + half), lower, upper, max(p_lower, p_upper),
                       min(1.0, p_beyond))


def ratio_tost(numerator: np.ndarray, denominator: np.ndarray, claimed: float, factor: float = 1.25,
               confidence: float = 0.95) -> Equivalence:
    """Whether ``numerator / denominator`` is "about" ``claimed``: within ``[claimed / factor, claimed * factor]``.

    Schuirmann's two one-sided tests on the per-seed log ratios, as bioequivalence tests a ratio of
    geometric means within 80-125% (``factor`` 1.25): the estimate is the ratio of geometric means over
    paired seeds with its t interval, all on the ratio scale. Values must be positive.
    """
    numerator, denominator = _per_seed(numerator), _per_seed(denominator)
    if numerator.shape != denominator.shape:
        raise ValueError(f"paired values need the same seeds: shapes {numerator.shape} and {denominator.shape} differ")
    if not (claimed > 0 and factor > 1):
        raise ValueError(f"need a positive claimed ratio and a factor above 1, got {claimed} and {factor}")
    if np.any(numerator <= 0) or np.any(denominator <= 0):
        raise ValueError("a ratio on the log scale needs positive values")
    logs = tost(np.log(numerator / denominator), np.log(claimed / factor), np.log(claimed * factor), confidence)
    estimate = Estimate(*(float(v) for v in np.exp(logs.estimate)))
    return Equivalence(estimate, claimed / factor, claimed * factor, logs.p_equivalent, logs.p_beyond)


def equivalence_verdict(test: Equivalence, p_value: float | None = None, level: float = ALPHA) -> Verdict:
    """Supported when ``p_value`` (default ``test.p``; Holm-adjusted in a family) is below ``level`` with the
    estimate inside the margin (equivalence shown); contradicted when it is below ``level`` with the estimate
    outside (the difference lies beyond the margin); no data without an estimate; otherwise not resolved."""
    if np.isnan(test.estimate.value):
        return NO_DATA
    p = test.p if p_value is None else p_value
    if not p < level:
        return NOT_RESOLVED
    return SUPPORTED if test.inside else CONTRADICTED


def holm(p_values: Iterable[float]) -> np.ndarray:
    """Holm's step-down adjusted p-values (Holm 1979): with the ``m`` p-values sorted ascending,
    ``adjusted_(i) = max_{j <= i} min(1, (m - j + 1) p_(j))``; rejecting where ``adjusted < α`` keeps the
    family-wise error rate at α. NaN (nothing tested) stays NaN and is not counted in ``m``."""
    p = np.asarray(list(p_values), dtype=np.float64)
    if np.any((p < 0) | (p > 1)):
        raise ValueError(f"p-values must lie in [0, 1], got {p}")
    order = _ascending_tested(p)
    adjusted = np.full(p.shape, np.nan)
    adjusted[order] = np.minimum(1.0, np.maximum.accumulate(holm_factors(p)[order] * p[order]))
    return adjusted


def _ascending_tested(p: np.ndarray) -> np.ndarray:
    """The indices of the tested (non-NaN) p-values, smallest first (ties in their given order)."""
    tested = np.flatnonzero(~np.isnan(p))
    return tested[np.argsort(p[tested], kind="stable")]


class NoiseFloor(NamedTuple):
    """The gap between the best and second-best option against the seed-to-seed spread of the options' values."""

    gap: float
    spread: float

    @property
    def below(self) -> bool:
        """The gap is smaller than the spread: which option is best is below the noise floor."""
        return bool(self.gap < self.spread)

    def format(self) -> str:
        """``gap 0.0008 < spread 0.003``, with as many significant digits (2 to 6) as tell the two apart."""
        digits = next((d for d in range(2, 7) if f"{self.gap:.{d}g}" != f"{self.spread:.{d}g}"), 6)
        return f"gap {self.gap:.{digits}g} {'<' if self.below else '>='} spread {self.spread:.{digits}g}"


def holm_factors(p_values: Iterable[float]) -> np.ndarray:
    """What Holm's procedure multiplies each p-value by before the running maximum: ``m - j + 1`` for the ``j``-th
    smallest of the ``m`` tested (NaN where nothing was tested), so ``holm(p) >= p * factor`` for each."""
    p = np.asarray(list(p_values), dtype=np.float64)
    order = _ascending_tested(p)
    factors = np.full(p.shape, np.nan)
    factors[order] = order.size - np.arange(order.size)
    return factors


def noise_floor(values: np.ndarray) -> NoiseFloor:
    """Whether the best of several options stands out from the noise, e.g. greedy actions from Q-values.

    ``values``: ``(seeds, items, options)``, e.g. final action values of the cells a claim reads (repeat an
    item to weight it). ``gap``: mean over items of the best minus the second-best of the seed-mean values.
    ``spread``: mean over items and options of the standard deviation over seeds (ddof 1). A gap below the
    spread is a signal-to-noise ratio under 1: the ranking of the options is set by the seed, not the method.
    One seed gives a NaN spread (never below).
    """
    values = np.asarray(values, dtype=np.float64)
    if values.ndim != 3 or values.shape[2] < 2 or values.shape[1] == 0:
        raise ValueError(f"expected (seeds, items, options >= 2) values, got shape {values.shape}")
    ordered = np.sort(values.mean(axis=0), axis=1)
    gap = float(np.mean(ordered[:, -1] - ordered[:, -2]))
    spread = float(np.mean(values.std(axis=0, ddof=1))) if values.shape[0] > 1 else np.nan
    return NoiseFloor(gap, spread)


def worst_case_sign_p(values: np.ndarray, bound: float, side: int, up: np.ndarray, down: np.ndarray) -> float:
    """One-sided sign test p-value that the median of ``values`` lies on ``side`` of ``bound`` (-1 below, +1
    above), each censored value put at its worst for that conclusion: one that could only be larger (``up``, e.g.
    a run that never converged, counted at the last episode) above the bound when the median is claimed below,
    one that could only be smaller (``down``) below it when the median is claimed above. The test reads only on
    which side of the bound each value lies, so it holds whatever the censored values truly are; values on the
    bound are left out (Dixon and Mood 1946)."""
    if side not in (1, -1):
        raise ValueError(f"side must be +1 or -1, got {side!r}")
    d = np.sign(np.asarray(values, dtype=np.float64) - bound)
    d = np.where(np.asarray(up if side < 0 else down, dtype=bool), -side, d)
    decided = d[d != 0]
    if decided.size == 0:
        return 1.0
    return float(stats.binomtest(int(np.sum(decided == side)), decided.size, 0.5, alternative="greater").pvalue)


def robust_to_censoring(side: int, bias: Iterable[int]) -> bool:
    """Whether a conclusion survives values censored from one side (a run that never converged counts at the
    last episode, a lower bound on its true time).

    ``side``: where the conclusion puts the true value: +1 above a bound, -1 below one, 0 inside a band.
    ``bias``: the directions censoring can move the true value from the observed one (+1 up, -1 down; empty
    when nothing was censored). The conclusion survives when every such move pushes further to its side.
    """
    return all(direction == side for direction in bias)
