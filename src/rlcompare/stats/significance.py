"""Tests over seeds and the labels they lead to: rank tests, two one-sided tests of a margin (Schuirmann 1987, "A
comparison of the two one-sided tests procedure and the power approach for assessing the equivalence of average
bioavailability", J. Pharmacokinet. Biopharm. 15(6)), Holm's step-down correction of a family (Holm 1979, "A simple
sequentially rejective multiple test procedure", Scand. J. Statist. 6(2)), noise floors and censoring.

The verdict labels (``docs/why.md``, "Verdicts"):

- ``supported`` / ``contradicted``: the test of the claim, or of its opposite, rejects at the family-wise level;
- ``not resolved``: neither does, and more seeds (or, for runs that never converged, more episodes) could settle it;
- ``undecidable here``: the quantity the claim reads lies below its own noise floor, so more seeds will not settle it;
- ``no data``: nothing to test (e.g. every seed censored: nothing converged).

Every study compares A against B the same way and says what it found in one vocabulary read off :func:`verdict`
(:mod:`rlcompare.stats.compare`).
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Literal, NamedTuple

import numpy as np

from rlcompare.formatting import distinct_numbers
from rlcompare.stats.intervals import NO_ESTIMATE, Estimate, per_seed_values
from rlcompare.stats.power import ALPHA as ALPHA

Verdict = Literal["supported", "contradicted", "not resolved", "undecidable here", "no data"]
SUPPORTED: Verdict = "supported"
CONTRADICTED: Verdict = "contradicted"
NOT_RESOLVED: Verdict = "not resolved"
UNDECIDABLE: Verdict = "undecidable here"
NO_DATA: Verdict = "no data"
VERDICTS: tuple[Verdict, ...] = (SUPPORTED, CONTRADICTED, NOT_RESOLVED, UNDECIDABLE, NO_DATA)



def rank_test(a: np.ndarray, b: np.ndarray, paired: bool = True) -> float:
    """Two-sided p-value of a rank test that ``a`` and ``b`` come from the same distribution.

    ``paired``: Wilcoxon signed-rank test of the per-seed differences, zero differences split between
    the two signs (Pratt/``zero_method="zsplit"``); all differences zero gives p = 1.
    Otherwise: Mann-Whitney U test of two independent samples; all values equal gives p = 1.
    """
    from scipy import stats  # here, where a number needs it: a plan imports this module

    a, b = per_seed_values(a), per_seed_values(b)
    if paired:
        if a.shape != b.shape:
            raise ValueError(f"paired values need the same seeds: shapes {a.shape} and {b.shape} differ")
        if np.all(a == b):
            return 1.0
        return float(stats.wilcoxon(a, b, zero_method="zsplit").pvalue)
    pooled = np.concatenate([a, b])
    if np.all(pooled == pooled[0]):
        return 1.0
    if exact_work(a.size, b.size) <= EXACT_WORK:
        return exact_rank_sum_p(a, b)
    return float(stats.mannwhitneyu(a, b, alternative="two-sided", method="asymptotic").pvalue)


EXACT_WORK = 10**8
"""Up to this much counting (:func:`exact_work`: a tenth of a second; 64 seeds against 64), the rank-sum test is
exact, ties included: scipy's ``mannwhitneyu`` is exact only without ties and on small samples, and otherwise falls
back to its normal approximation, which gave 0.021 where no design of 4 seeds a side can go below 2 / C(8, 4) =
0.0286 (and, at 10 a side with ties, 6.3e-5 where the exact test gives 1.1e-5). Beyond it, the normal approximation
(tie-corrected, with a continuity correction)."""


def exact_work(a_size: int, b_size: int) -> int:
    """The counting the exact rank-sum test does: pooled seeds, times the smaller side, times the largest rank sum
    of its doubled mid-ranks."""
    total, small = a_size + b_size, min(a_size, b_size)
    return total * small * small * (2 * total - small + 1)


def exact_rank_sum_p(a: np.ndarray, b: np.ndarray) -> float:
    """Two-sided exact p-value of the Mann-Whitney test, ties given their mid-ranks: over the C(n + m, n) equally
    likely splits of the pooled values (the permutation distribution under no difference), counted by the rank sum
    of the smaller side (:func:`rank_sum_counts`), twice the smaller tail beyond its observed rank sum, at most 1
    (scipy's convention for its exact test)."""
    from scipy import stats  # here, where a number needs it: a plan imports this module

    doubled = np.rint(2 * stats.rankdata(np.concatenate([a, b]))).astype(np.int64)  # mid-ranks, as whole numbers
    side = doubled[:a.size] if a.size <= b.size else doubled[a.size:]
    counts = rank_sum_counts(doubled, side.size)
    observed = int(side.sum())
    tail = min(counts[observed:].sum(), counts[:observed + 1].sum()) / counts.sum()
    return float(min(1.0, 2 * tail))


def rank_sum_counts(ranks: np.ndarray, size: int) -> np.ndarray:
    """``counts[s]``: how many of the ways to choose ``size`` of ``ranks`` (whole numbers) sum to ``s``, counted
    one rank at a time (each subset sum either leaves the rank out or adds it)."""
    largest = int(np.sort(ranks)[ranks.size - size:].sum())
    counts = np.zeros((size + 1, largest + 1))
    counts[0, 0] = 1.0
    for rank in map(int, ranks):
        if rank <= largest:
            counts[1:, rank:] += counts[:-1, :largest + 1 - rank].copy()
    return np.asarray(counts[size])


def has_learnt(finals: np.ndarray, floor: float, margin: float, level: float = ALPHA) -> bool:
    """Whether a method has learnt an environment at its budget: its seeds' final scores exceed the random policy's
    mean ``floor`` by more than ``margin``, by a one-sided Wilcoxon signed-rank test (the studies' own test) at
    ``level``. A gate before a comparison, not a claim: failing it withholds a verdict and asserts nothing, so it
    is not Holm-corrected with the claims."""
    from scipy import stats  # here, where a number needs it: a plan imports this module

    above = per_seed_values(finals) - (floor + margin)
    if above.size == 0 or np.all(above == 0):
        return False
    return float(stats.wilcoxon(above, zero_method="zsplit", alternative="greater").pvalue) < level


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


def _one_sided(distance: float, se: float, df: float) -> float:
    """p-value of H0: distance <= 0 against distance > 0, for a mean ``distance`` from a bound (Student t)."""
    from scipy import stats  # here, where a number needs it: a plan imports this module

    if se == 0:
        return 0.0 if distance > 0 else 1.0
    return float(stats.t.sf(distance / se, df))


def _beyond(mean: float, lower: float, upper: float, se: float, df: float) -> float:
    """Twice the one-sided p-value that the mean lies beyond the margin on its estimate's side; 1 inside it."""
    if mean > upper:
        return min(1.0, 2 * _one_sided(mean - upper, se, df))
    if mean < lower:
        return min(1.0, 2 * _one_sided(lower - mean, se, df))
    return 1.0


def tost(values: np.ndarray, lower: float, upper: float, confidence: float = 0.95) -> Equivalence:
    """Whether the mean of ``values`` (e.g. paired differences over seeds) lies within ``[lower, upper]``.

    Two one-sided paired t-tests (Schuirmann 1987): equivalence at level α when both reject, i.e. when
    ``max(p_lower, p_upper) < α``, which is the ``1 - 2α`` t interval lying inside the margin. The estimate
    carries the two-sided ``confidence`` t interval. One seed gives NaN p-values; identical values give
    p = 0 or 1 (a point either inside or outside); a non-finite value gives a NaN estimate.
    """
    from scipy import stats  # here, where a number needs it: a plan imports this module

    if not lower < upper:
        raise ValueError(f"the margin needs lower < upper, got [{lower}, {upper}]")
    values = per_seed_values(values)
    if not np.all(np.isfinite(values)):
        return Equivalence(NO_ESTIMATE, lower, upper, np.nan, np.nan)
    mean, n = float(values.mean()), values.size
    if n < 2:
        return Equivalence(Estimate(mean, np.nan, np.nan), lower, upper, np.nan, np.nan)
    se, df = float(values.std(ddof=1) / np.sqrt(n)), n - 1
    half = float(stats.t.ppf(0.5 + confidence / 2, df)) * se
    p_lower, p_upper = _one_sided(mean - lower, se, df), _one_sided(upper - mean, se, df)
    return Equivalence(Estimate(mean, mean - half, mean + half), lower, upper, max(p_lower, p_upper),
                       _beyond(mean, lower, upper, se, df))


def welch_tost(a: np.ndarray, b: np.ndarray, lower: float, upper: float, confidence: float = 0.95) -> Equivalence:
    """Whether ``mean(a) - mean(b)`` lies within ``[lower, upper]`` for two independent samples: :func:`tost`'s two
    one-sided tests with Welch's standard error and Satterthwaite's degrees of freedom (Welch 1947), as
    ``scipy.stats.ttest_ind(a, b + bound, equal_var=False)`` gives each. Fewer than two values on a side give NaN
    p-values; a non-finite value a NaN estimate."""
    from scipy import stats  # here, where a number needs it: a plan imports this module

    if not lower < upper:
        raise ValueError(f"the margin needs lower < upper, got [{lower}, {upper}]")
    a, b = per_seed_values(a), per_seed_values(b)
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        return Equivalence(NO_ESTIMATE, lower, upper, np.nan, np.nan)
    mean = float(a.mean() - b.mean())
    if a.size < 2 or b.size < 2:
        return Equivalence(Estimate(mean, np.nan, np.nan), lower, upper, np.nan, np.nan)
    va, vb = a.var(ddof=1) / a.size, b.var(ddof=1) / b.size
    se = float(np.sqrt(va + vb))
    df = float((va + vb) ** 2 / (va**2 / (a.size - 1) + vb**2 / (b.size - 1))) if se > 0 else float(a.size + b.size - 2)
    half = float(stats.t.ppf(0.5 + confidence / 2, df)) * se
    p_lower, p_upper = _one_sided(mean - lower, se, df), _one_sided(upper - mean, se, df)
    return Equivalence(Estimate(mean, mean - half, mean + half), lower, upper, max(p_lower, p_upper),
                       _beyond(mean, lower, upper, se, df))


def ratio_tost(numerator: np.ndarray, denominator: np.ndarray, claimed: float, factor: float = 1.25,
               confidence: float = 0.95) -> Equivalence:
    """Whether ``numerator / denominator`` is "about" ``claimed``: within ``[claimed / factor, claimed * factor]``.

    Schuirmann's two one-sided tests on the per-seed log ratios, as bioequivalence tests a ratio of
    geometric means within 80-125% (``factor`` 1.25): the estimate is the ratio of geometric means over
    paired seeds with its t interval, all on the ratio scale. Values must be positive.
    """
    numerator, denominator = per_seed_values(numerator), per_seed_values(denominator)
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
        gap, spread = distinct_numbers(self.gap, self.spread)
        return f"gap {gap} {'<' if self.below else '>='} spread {spread}"


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
    from scipy import stats  # here, where a number needs it: a plan imports this module

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
