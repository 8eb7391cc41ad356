"""Statistics over seeds: intervals, paired differences, probability of improvement, rank tests, verdicts."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from rlcompare.stats.compare import compare_paired, comparison_label
from rlcompare.stats.intervals import Estimate, interval, iqm, paired_difference, probability_of_improvement
from rlcompare.stats.significance import CONTRADICTED, NOT_RESOLVED, SUPPORTED, VERDICTS, rank_test, verdict

# --- interquartile mean ---------------------------------------------------------------------------


def test_iqm_of_one_to_eight_is_the_mean_of_the_middle_four():
    # n = 8, int(0.25 * 8) = 2 cut from each end: 1, 2 | 3, 4, 5, 6 | 7, 8 -> (3 + 4 + 5 + 6) / 4 = 18 / 4 = 4.5
    assert iqm(np.arange(1.0, 9.0)) == pytest.approx(4.5)


def test_iqm_ignores_outliers_and_order():
    # sorted: 1, 2 | 3, 4, 5, 10 | 100, 1000 -> (3 + 4 + 5 + 10) / 4 = 22 / 4 = 5.5 (the mean would be 140.625)
    values = np.array([10.0, 1.0, 1000.0, 2.0, 3.0, 100.0, 4.0, 5.0])
    assert iqm(values) == pytest.approx(5.5)


def test_iqm_follows_the_axis():
    rows = np.array([np.arange(1.0, 9.0), np.arange(1.0, 9.0) * 2])
    np.testing.assert_allclose(iqm(rows), [4.5, 9.0])
    np.testing.assert_allclose(iqm(rows.T, axis=0), [4.5, 9.0])


# --- bootstrap intervals ----------------------------------------------------------------------------


@pytest.mark.slow("compiles or trains for a second or more")
def test_mean_interval_covers_the_true_mean_of_skewed_data_at_about_the_nominal_rate():
    # Exponential(1), n = 30: true mean 1. BCa covers about 0.93 here (3000 datasets); 500 datasets give
    # a binomial standard error of about 0.011.
    rng = np.random.default_rng(2024)
    hits = [
        (estimate := interval(rng.exponential(1.0, 30), "mean", n_resamples=2000, seed=i)).low <= 1.0 <= estimate.high
        for i in range(500)
    ]
    assert 0.90 <= np.mean(hits) <= 0.985


@pytest.mark.slow("compiles or trains for a second or more")
def test_iqm_interval_covers_the_true_iqm_at_about_the_nominal_rate():
    # Normal(0, 1), n = 40 (10 cut from each end): symmetric, so the population IQM is the mean, 0.
    rng = np.random.default_rng(7)
    hits = [
        (estimate := interval(rng.normal(0.0, 1.0, 40), "iqm", n_resamples=2000, seed=i)).low <= 0.0 <= estimate.high
        for i in range(300)
    ]
    assert 0.90 <= np.mean(hits) <= 0.985


def test_interval_contains_its_estimate_and_is_reproducible():
    values = np.random.default_rng(3).normal(-200.0, 30.0, 30)
    for statistic in ("mean", "iqm"):
        estimate = interval(values, statistic, n_resamples=2000, seed=5)
        assert estimate.low < estimate.value < estimate.high
        assert interval(values, statistic, n_resamples=2000, seed=5) == estimate
        assert interval(values, statistic, n_resamples=2000, seed=6) != estimate
    assert interval(values, "mean", n_resamples=2000).value == pytest.approx(values.mean())
    assert interval(values, "iqm", n_resamples=2000).value == pytest.approx(stats.trim_mean(values, 0.25))


def test_wider_confidence_gives_a_wider_interval():
    values = np.random.default_rng(4).exponential(1.0, 25)
    narrow = interval(values, confidence=0.8, n_resamples=2000)
    wide = interval(values, confidence=0.99, n_resamples=2000)
    assert wide.low < narrow.low < narrow.high < wide.high


def test_degenerate_inputs():
    assert interval(np.full(10, -150.0)) == Estimate(-150.0, -150.0, -150.0)
    assert interval(np.full(10, -150.0), "iqm") == Estimate(-150.0, -150.0, -150.0)
    single = interval(np.array([-170.0]))
    assert single.value == -170.0
    assert np.isnan(single.low)
    assert np.isnan(single.high)
    assert single.format() == "-170.0"
    assert all(np.isnan(interval(np.array([1.0, np.nan, 3.0]), statistic)).all() for statistic in ("mean", "iqm"))
    with pytest.raises(ValueError, match="no seeds"):
        interval(np.array([]))
    with pytest.raises(ValueError, match="1-d"):
        interval(np.ones((3, 2)))
    with pytest.raises(ValueError, match="statistic"):
        interval(np.ones(3), "median")  # type: ignore[arg-type]


def test_two_seeds_and_few_resamples_give_a_finite_interval():
    # With two seeds the bootstrap means are 0, 0.5 or 1; with few resamples BCa can be undefined and the
    # percentile interval is used instead. Either way the bounds lie within the data and no warning escapes.
    for n_resamples in (2, 3, 5, 10_000):
        for seed in range(20):
            estimate = interval(np.array([0.0, 1.0]), n_resamples=n_resamples, seed=seed)
            assert 0.0 <= estimate.low <= estimate.high <= 1.0


def test_format():
    assert Estimate(-150.04, -160.0, -140.55).format() == "-150.0 [-160.0, -140.6]"


# --- paired difference ------------------------------------------------------------------------------


def test_paired_difference_on_a_hand_example():
    a = np.array([3.0, 5.0, 7.0, 9.0])
    b = np.array([1.0, 2.0, 3.0, 4.0])
    # a - b = 2, 3, 4, 5 -> mean 14 / 4 = 3.5; every resampled mean lies in [2, 5]
    estimate = paired_difference(a, b, n_resamples=2000)
    assert estimate.value == pytest.approx(3.5)
    assert 2.0 <= estimate.low < 3.5 < estimate.high <= 5.0
    assert paired_difference(b, a, n_resamples=2000).value == pytest.approx(-3.5)


def test_pairing_removes_the_variation_shared_by_a_seed():
    # Seeds differ a lot (sd 100) but b is a + 5 ± 1 within each seed: the paired interval is about ±0.4,
    # far narrower than anything an unpaired comparison of the two means could give.
    rng = np.random.default_rng(11)
    a = rng.normal(-300.0, 100.0, 30)
    b = a + 5.0 + rng.normal(0.0, 1.0, 30)
    estimate = paired_difference(a, b, n_resamples=2000)
    assert estimate.high < 0
    assert estimate.high - estimate.low < 2.0
    assert -5.5 < estimate.value < -4.5


def test_paired_difference_of_identical_runs_is_exactly_zero():
    a = np.random.default_rng(1).normal(size=10)
    assert paired_difference(a, a.copy()) == Estimate(0.0, 0.0, 0.0)


def test_paired_difference_needs_the_same_seeds():
    with pytest.raises(ValueError, match="same seeds"):
        paired_difference(np.ones(3), np.ones(4))


# --- probability of improvement ---------------------------------------------------------------------


def test_probability_of_improvement_on_hand_arrays():
    assert probability_of_improvement(np.array([1.0, 2.0, 3.0]), np.zeros(3)).value == 1.0
    assert probability_of_improvement(np.zeros(3), np.array([1.0, 2.0, 3.0])).value == 0.0
    # [1, 2] vs [1, 2]: pairs (1,1) tie ½, (1,2) 0, (2,1) 1, (2,2) tie ½ -> 2 / 4 = 0.5
    assert probability_of_improvement(np.array([1.0, 2.0]), np.array([1.0, 2.0])).value == 0.5
    # [1, 3, 5, 7] vs [2, 3]: 1 beats none (0); 3 beats 2, ties 3 (1.5); 5 and 7 beat both (2 + 2)
    # -> (0 + 1.5 + 2 + 2) / (4 * 2) = 5.5 / 8 = 0.6875
    assert probability_of_improvement(np.array([1.0, 3.0, 5.0, 7.0]), np.array([2.0, 3.0])).value == 0.6875


def test_probability_of_improvement_is_mann_whitney_u_over_pairs_and_complementary():
    rng = np.random.default_rng(5)
    a = np.round(rng.normal(0.3, 1.0, 25), 1)  # rounding makes ties
    b = np.round(rng.normal(0.0, 1.0, 18), 1)
    forward = probability_of_improvement(a, b, n_resamples=2000)
    backward = probability_of_improvement(b, a, n_resamples=2000)
    assert forward.value == pytest.approx(stats.mannwhitneyu(a, b).statistic / (25 * 18))
    assert forward.value + backward.value == pytest.approx(1.0)
    assert 0.0 <= forward.low < forward.value < forward.high <= 1.0


def test_probability_of_improvement_interval_separates_clear_differences():
    rng = np.random.default_rng(9)
    better = rng.normal(-150.0, 10.0, 20)
    worse = rng.normal(-190.0, 10.0, 20)
    estimate = probability_of_improvement(better, worse, n_resamples=2000)
    assert estimate.low > 0.8
    noise = probability_of_improvement(rng.normal(size=20), rng.normal(size=20), n_resamples=2000)
    assert noise.low < 0.5 < noise.high


def test_probability_of_improvement_degenerate_inputs():
    assert probability_of_improvement(np.array([2.0, 3.0]), np.ones(5)) == Estimate(1.0, 1.0, 1.0)
    assert probability_of_improvement(np.ones(4), np.ones(5)) == Estimate(0.5, 0.5, 0.5)
    one_seed = probability_of_improvement(np.array([2.0]), np.array([1.0, 3.0, 4.0]))
    assert one_seed.value == pytest.approx(1 / 3)
    assert np.isnan(one_seed.low)
    assert np.isnan(probability_of_improvement(np.array([1.0, np.nan]), np.ones(3)).value)


# --- rank tests -------------------------------------------------------------------------------------


def test_paired_rank_test_finds_a_consistent_shift():
    rng = np.random.default_rng(12)
    a = rng.normal(-300.0, 100.0, 30)
    assert rank_test(a + 5.0 + rng.normal(0.0, 1.0, 30), a) < 1e-6


def test_rank_tests_reject_at_about_the_nominal_rate_under_the_null():
    # Two samples from the same distribution: p < 0.05 in about 5% of 400 datasets (binomial sd 0.011).
    rng = np.random.default_rng(13)
    for paired in (True, False):
        p_values = np.array([rank_test(rng.normal(size=20), rng.normal(size=20), paired=paired) for _ in range(400)])
        assert 0.02 <= np.mean(p_values < 0.05) <= 0.09
        assert np.median(p_values) > 0.3


def test_paired_rank_test_matches_scipy_with_zero_differences_split():
    a = np.array([1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0])
    b = np.array([0.0, 2.0, 1.0, 1.0, 2.0, 6.0, 3.0, 2.0])  # two zero differences
    assert rank_test(a, b) == pytest.approx(stats.wilcoxon(a, b, zero_method="zsplit").pvalue)


def test_unpaired_rank_test_is_mann_whitney():
    a = np.array([1.0, 2.0, 3.0, 4.0, 5.0])
    b = np.array([6.0, 7.0, 8.0, 9.0, 10.0])
    # Completely separated samples of 5 and 5: exact two-sided p = 2 / C(10, 5) = 2 / 252
    assert rank_test(a, b, paired=False) == pytest.approx(2 / 252)


def test_rank_test_degenerate_inputs():
    a = np.array([1.0, 2.0, 3.0])
    assert rank_test(a, a.copy()) == 1.0
    assert rank_test(np.ones(4), np.ones(6), paired=False) == 1.0
    with pytest.raises(ValueError, match="same seeds"):
        rank_test(np.ones(3), np.ones(4))


# --- verdicts ---------------------------------------------------------------------------------------


def test_verdict_outcomes():
    positive = Estimate(5.0, 2.0, 8.0)
    negative = Estimate(-5.0, -8.0, -2.0)
    straddling = Estimate(1.0, -2.0, 4.0)
    assert verdict(positive, 0.001, +1) == SUPPORTED
    assert verdict(negative, 0.001, -1) == SUPPORTED
    assert verdict(positive, 0.001, -1) == CONTRADICTED
    assert verdict(negative, 0.001, +1) == CONTRADICTED
    assert verdict(straddling, 0.001, +1) == NOT_RESOLVED
    assert verdict(positive, 0.2, +1) == NOT_RESOLVED  # interval and test disagree
    assert verdict(positive, 0.03, +1, level=0.01) == NOT_RESOLVED
    assert verdict(Estimate(5.0, np.nan, np.nan), 0.001, +1) == NOT_RESOLVED
    assert verdict(positive, np.nan, +1) == NOT_RESOLVED
    assert verdict(Estimate(0.0, 0.0, 3.0), 0.001, +1) == NOT_RESOLVED  # touching 0 does not exclude it
    assert set(VERDICTS) == {"supported", "contradicted", "not resolved", "undecidable here", "no data"}
    with pytest.raises(ValueError, match="claimed_sign"):
        verdict(positive, 0.001, 0)


def test_verdict_end_to_end_on_paired_seeds():
    rng = np.random.default_rng(21)
    sarsa = rng.normal(-180.0, 30.0, 30)
    q_learning = sarsa - 15.0 + rng.normal(0.0, 5.0, 30)
    difference = paired_difference(sarsa, q_learning, n_resamples=2000)
    p_value = rank_test(sarsa, q_learning)
    assert verdict(difference, p_value, claimed_sign=+1) == SUPPORTED
    assert verdict(difference, p_value, claimed_sign=-1) == CONTRADICTED


@pytest.mark.parametrize(("shift", "margin", "label"), [
    (+5.0, None, "A better"),
    (-5.0, None, "B better"),
    (0.0, None, "not resolved"),
    (0.0, 1.0, "equivalent (within ±1)"),  # no direction, but the margin is declared and shown
    (0.05, 0.01, "not resolved"),  # too small to show a direction, too spread to sit inside a tiny margin
])
def test_one_comparison_says_what_it_found_in_one_vocabulary(shift, margin, label):
    rng = np.random.default_rng(3)
    b = rng.normal(0.0, 1.0, 20)
    a = b + shift + rng.normal(0.0, 0.2, 20)
    paired = compare_paired(a, b, margin)
    assert paired.seeds == 20
    assert paired.difference == paired_difference(a, b)
    assert paired.p_value == rank_test(a, b)
    assert comparison_label(paired.difference, paired.p_value, ("A", "B"), paired.equivalence) == label
    # the label is the claim "A - B > 0" judged by verdict, the one rule
    direction = verdict(paired.difference, paired.p_value, +1)
    assert (direction == "supported") == (label == "A better")
    assert (direction == "contradicted") == (label == "B better")


def test_a_comparison_without_an_estimate_has_no_data():
    paired = compare_paired(np.array([1.0, np.nan, 2.0]), np.array([0.0, 0.0, 0.0]))
    assert np.isnan(paired.p_value)
    assert comparison_label(paired.difference, paired.p_value, ("A", "B")) == "no data"


def test_improvement_share_counts_pairs_to_the_same_bits_as_mid_ranks(monkeypatch: pytest.MonkeyPatch) -> None:
    """Counting pairs in compiled code and summing mid-ranks give U exactly, so the same bits, ties and resampled
    rows included; more pairs than :data:`PAIRS_COUNTED`, or a NaN, take the ranks."""
    from rlcompare.stats import intervals as module

    rng = np.random.default_rng(5)
    cases = [(rng.integers(0, 4, 30).astype(float), rng.integers(0, 4, 30).astype(float)),
             (rng.normal(size=(200, 30)), rng.normal(size=(200, 30))),
             (np.round(rng.normal(size=(50, 3, 10))), np.round(rng.normal(size=(50, 3, 12)))),
             (rng.normal(size=7), rng.normal(size=1))]
    counted = [module.improvement_share(a, b) for a, b in cases]
    monkeypatch.setattr(module, "PAIRS_COUNTED", 0)
    ranked = [module.improvement_share(a, b) for a, b in cases]
    for c, r in zip(counted, ranked, strict=True):
        assert np.shape(c) == np.shape(r)
        assert np.array_equal(c, r)
    with_nan = np.array([1.0, np.nan, 3.0])
    assert np.isnan(module.improvement_share(with_nan, np.array([2.0, 2.0])))


def test_a_joint_interval_resamples_the_seeds_together_across_quantities():
    """Two quantities 3 apart on every seed: their difference of means is 3 on every joint resample, so the interval
    is [3, 3] (resampled apart it would be wide); a concave function of the means is not the mean of its values."""
    from rlcompare.stats.intervals import joint_interval

    first = np.array([1.0, 5.0, 9.0, 2.0, 7.0])
    difference = joint_interval(lambda x, y, axis=-1: np.mean(x, axis=axis) - np.mean(y, axis=axis),
                                (first, first - 3.0))
    assert (difference.value, difference.low, difference.high) == pytest.approx((3.0, 3.0, 3.0))
    root = joint_interval(lambda x, axis=-1: np.sqrt(np.mean(x, axis=axis)), (first,))
    assert root.value == pytest.approx(np.sqrt(4.8))
    assert root.value != pytest.approx(np.mean(np.sqrt(first)))
    assert root.low < root.value < root.high
    with pytest.raises(ValueError, match="the same seeds"):
        joint_interval(lambda x, y, axis=-1: np.mean(x, axis=axis), (first, first[:3]))
    assert np.isnan(joint_interval(lambda x, axis=-1: np.mean(x, axis=axis), (np.array([1.0, np.inf]),)).value)
