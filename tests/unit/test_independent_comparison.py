"""A against B on seeds that share no randomness (runs from two libraries): Welch's equivalence test against
scipy's t tests, the two-sample bootstrap against scipy's, the Mann-Whitney p-value, and degenerate inputs."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from rlcompare.stats.compare import compare_independent
from rlcompare.stats.intervals import independent_difference, paired_difference
from rlcompare.stats.significance import welch_tost

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
