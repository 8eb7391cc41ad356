"""A against B on seeds that share no randomness (runs from two libraries): Welch's equivalence test against
scipy's t tests, the two-sample bootstrap against scipy's, the Mann-Whitney p-value, and degenerate inputs."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy import stats

from rlcompare.stats.compare import compare_independent
from rlcompare.stats.intervals import independent_difference, paired_difference, probability_of_improvement
from rlcompare.stats.significance import EXACT_WORK, exact_work, rank_test, welch_tost

RNG = np.random.default_rng(11)
A, B = RNG.normal(10.0, 2.0, size=7), RNG.normal(9.0, 5.0, size=5)


@pytest.mark.parametrize("margin", [0.5, 3.0, 12.0])
def test_welchs_equivalence_test_is_scipys_two_one_sided_welch_tests(margin):
    test = welch_tost(A, B, -margin, margin)
    above = stats.ttest_ind(A, B - margin, equal_var=False, alternative="greater").pvalue
    below = stats.ttest_ind(A, B + margin, equal_var=False, alternative="less").pvalue
    assert test.p_equivalent == pytest.approx(max(above, below), rel=1e-12)
    interval = stats.ttest_ind(A, B, equal_var=False).confidence_interval(0.95)
    assert (test.estimate.low, test.estimate.high) == pytest.approx((interval.low, interval.high), rel=1e-12)
    assert test.estimate.value == pytest.approx(A.mean() - B.mean())


def test_the_difference_of_means_resamples_each_side_apart():
    estimate = independent_difference(A, B, n_resamples=2_000, seed=3)
    reference = stats.bootstrap((A, B), lambda x, y, axis=-1: x.mean(axis) - y.mean(axis), n_resamples=2_000,
                                method="BCa", paired=False, vectorized=True, rng=np.random.default_rng(3))
    assert estimate.value == pytest.approx(A.mean() - B.mean())
    assert (estimate.low, estimate.high) == pytest.approx(
        (reference.confidence_interval.low, reference.confidence_interval.high), rel=1e-12)
    # on correlated pairs the paired interval is the narrower: the two answer different questions
    shared = RNG.normal(0.0, 10.0, size=8)
    a, b = shared + RNG.normal(1.0, 0.5, size=8), shared + RNG.normal(0.0, 0.5, size=8)
    unpaired, paired = independent_difference(a, b), paired_difference(a, b)
    assert unpaired.high - unpaired.low > 4 * (paired.high - paired.low)


def test_the_comparison_takes_mann_whitneys_p_and_the_smaller_side_as_its_seeds():
    compared = compare_independent(A, B, margin=2.0)
    assert compared.p_value == pytest.approx(stats.mannwhitneyu(A, B, alternative="two-sided").pvalue)
    assert compared.seeds == 5
    assert compared.spread == pytest.approx(np.sqrt(A.var(ddof=1) + B.var(ddof=1)))
    assert compared.improvement.value == pytest.approx(np.mean(A[:, None] > B[None, :]))
    assert compared.equivalence is not None
    assert compared.equivalence.upper == 2.0


def test_degenerate_inputs_give_no_bounds_rather_than_an_error():
    one = independent_difference(np.array([1.0]), B)
    assert one.value == pytest.approx(1.0 - B.mean())
    assert np.isnan(one.low)
    assert np.isnan(welch_tost(np.array([1.0]), B, -1, 1).p_equivalent)
    assert np.isnan(independent_difference(np.array([np.nan, 1.0]), B).value)
    constant = independent_difference(np.full(3, 2.0), np.full(4, 1.0))
    assert (constant.low, constant.value, constant.high) == (1.0, 1.0, 1.0)


def every_split_p(a: np.ndarray, b: np.ndarray) -> float:
    """The exact two-sided rank-sum p by brute force: every way of drawing len(a) of the pooled mid-ranks."""
    ranks = stats.rankdata(np.concatenate([a, b]))
    sums = np.array([ranks[list(c)].sum() for c in itertools.combinations(range(ranks.size), a.size)])
    observed = ranks[:a.size].sum()
    return min(1.0, 2 * min(np.mean(sums >= observed - 1e-9), np.mean(sums <= observed + 1e-9)))


@pytest.mark.parametrize(("a", "b"), [
    ([3, 3, 5, 7, 7], [1, 3, 3, 5, 5, 5, 9]),
    ([500, 500, 500, 480, 500, 500], [500, 420, 500, 300, 500, 250]),
    ([1, 1, 2], [1, 2, 2, 2, 3, 3, 3, 3, 4]),
])
def test_the_rank_sum_p_with_ties_is_every_splits_count(a, b):
    a, b = np.asarray(a, float), np.asarray(b, float)
    assert rank_test(a, b, paired=False) == pytest.approx(every_split_p(a, b), rel=1e-12)
    assert rank_test(b, a, paired=False) == pytest.approx(every_split_p(a, b), rel=1e-12)


def test_the_rank_sum_p_without_ties_is_scipys_exact_one():
    a, b = RNG.normal(0.0, 1.0, size=9), RNG.normal(0.8, 1.0, size=11)
    exact = stats.mannwhitneyu(a, b, alternative="two-sided", method="exact").pvalue
    assert rank_test(a, b, paired=False) == pytest.approx(exact, rel=1e-12)


def test_ten_seeds_a_side_at_a_cap_reach_two_over_c_20_10_where_scipys_approximation_does_not():
    """A at the cap of 500 on 10 seeds, B below it with two tied: every seed of A above every one of B is one split
    in C(20, 10) = 184,756 each way, so p = 2 / 184,756 = 1.08e-5; scipy falls back to its normal approximation on
    ties (6.3e-5), which fails Holm's 0.05 / 1225 = 4.1e-5 of a family of 50 methods, where the exact test passes."""
    a, b = np.full(10, 500.0), np.array([10, 10, 30, 40, 50, 60, 70, 80, 90, 100], float)
    assert rank_test(a, b, paired=False) == pytest.approx(2 / 184_756, rel=1e-12)
    assert stats.mannwhitneyu(a, b).pvalue > 0.05 / 1225 > rank_test(a, b, paired=False)


def test_large_samples_take_the_normal_approximation():
    a, b = RNG.integers(0, 5, size=80).astype(float), RNG.integers(0, 5, size=90).astype(float)
    assert exact_work(80, 90) > EXACT_WORK
    assert rank_test(a, b, paired=False) == pytest.approx(
        stats.mannwhitneyu(a, b, alternative="two-sided", method="asymptotic").pvalue, rel=1e-12)


def test_p_of_improvement_keeps_an_interval_when_every_seed_of_a_beats_every_one_of_b():
    """5 seeds a side, every A above every B: the stratified bootstrap's interval is 1.00 [1.00, 1.00] (no
    resample can lose a pair). Newcombe's score interval: its upper end 1, its lower end the θ where
    1 - θ = (z² / 25) θ [1 + 4 (1 - θ) / (2 - θ) + 4 θ / (1 + θ)] (Hanley and McNeil's variance, N* - 1 = 4), solved
    here apart: 0.643."""
    from scipy.optimize import brentq

    a, b = np.arange(5.0) + 10.0, np.arange(5.0)
    assert probability_of_improvement(a, b) == (1.0, 1.0, 1.0)
    z = stats.norm.ppf(0.975)
    lowest = brentq(lambda t: 1 - t - z**2 / 25 * t * (1 + 4 * (1 - t) / (2 - t) + 4 * t / (1 + t)), 0.01, 0.99)
    assert lowest == pytest.approx(0.6427, abs=1e-4)
    found = compare_independent(a, b).improvement
    assert (found.value, found.high) == (1.0, 1.0)
    assert found.low == pytest.approx(lowest, rel=1e-9)
    mirrored = compare_independent(b, a).improvement
    assert (mirrored.low, mirrored.value) == (0.0, 0.0)
    assert mirrored.high == pytest.approx(1 - lowest, rel=1e-9)


def test_p_of_improvement_s_interval_on_unequal_sides_solves_newcombes_equation():
    """3 seeds against 7, 3 + 4 + 6 = 13 of the 21 pairs won: each end θ solves (θ - 13/21)² = z² V(θ), V Hanley and
    McNeil's variance with N* = 5 on both sides and the 21 pairs below."""
    a, b = np.array([4.0, 6.0, 9.0]), np.array([1.0, 2.0, 3.0, 5.0, 7.0, 8.0, 10.0])
    found = compare_independent(a, b).improvement
    assert found.value == pytest.approx(13 / 21)
    z = stats.norm.ppf(0.975)
    for end in (found.low, found.high):
        variance = end * (1 - end) / 21 * (1 + 4 * (1 - end) / (2 - end) + 4 * end / (1 + end))
        assert (end - 13 / 21) ** 2 == pytest.approx(z**2 * variance, rel=1e-6)
    assert found.low < 13 / 21 < found.high
