"""rliable's aggregates over tasks and runs, against scipy and by what a stratified bootstrap must do."""

from __future__ import annotations

import numpy as np
from scipy import stats

from rlcompare.analysis.profiles import (
    average_improvement,
    improvement_interval,
    performance_profile,
    pooled_iqm,
    profile_band,
    stratified_interval,
    stratified_resamples,
)


def test_the_performance_profile_is_the_survival_function_of_the_pooled_scores():
    values = np.random.default_rng(0).normal(size=(5, 7))
    thresholds = np.linspace(-3, 3, 41)
    expected = stats.ecdf(values.ravel()).sf.evaluate(thresholds)
    np.testing.assert_allclose(performance_profile(values, thresholds), expected)


def test_the_pooled_iqm_is_scipys_trimmed_mean_of_every_run():
    values = np.random.default_rng(1).exponential(size=(4, 9))
    assert pooled_iqm(values) == stats.trim_mean(values.ravel(), 0.25)


def test_resamples_draw_each_tasks_runs_from_that_task_alone():
    values = np.arange(12.0).reshape(3, 4) + np.array([[0.0], [100.0], [200.0]])
    resampled = stratified_resamples(values, 50)
    for task in range(3):
        assert set(np.unique(resampled[:, task])) <= set(values[task])
    assert len(np.unique(resampled[:, 0])) > 1


def test_the_stratified_interval_covers_the_true_iqm_about_as_often_as_it_claims():
    rng = np.random.default_rng(2)
    truth = stats.trim_mean(rng.normal(size=2_000_000), 0.25)  # the IQM of a standard normal, 0
    covered = 0
    for repeat in range(200):
        estimate = stratified_interval(rng.normal(size=(3, 10)), resamples=500, seed=repeat)
        covered += estimate.low <= truth <= estimate.high
    assert 0.85 <= covered / 200 <= 0.99
    constant = stratified_interval(np.ones((2, 5)))
    assert (constant.value, constant.low, constant.high) == (1.0, 1.0, 1.0)


def test_the_profile_band_holds_the_profile():
    values = np.random.default_rng(3).normal(size=(3, 8))
    thresholds = np.linspace(-2, 2, 9)
    profile, low, high = profile_band(values, thresholds, resamples=400)
    assert np.all(low <= profile)
    assert np.all(profile <= high)
    assert np.all(np.diff(profile) <= 0)


def test_the_average_probability_of_improvement_is_scipys_mann_whitney_u_averaged_over_tasks():
    rng = np.random.default_rng(4)
    x = rng.normal(size=(3, 6)).round(1)  # rounded: some ties, which count half
    y = rng.normal(0.3, size=(3, 5)).round(1)
    expected = np.mean([stats.mannwhitneyu(x[t], y[t]).statistic / (6 * 5) for t in range(3)])
    assert np.isclose(average_improvement(x, y), expected)
    assert np.isclose(average_improvement(y, x), 1 - expected)
    assert average_improvement(x * 100 + 7, y * 100 + 7) == average_improvement(x, y)  # scale-free per task


def test_the_improvement_interval_separates_a_shift_and_covers_one_half_without_one():
    rng = np.random.default_rng(5)
    better = improvement_interval(rng.normal(1.0, size=(4, 10)), rng.normal(size=(4, 10)))
    assert better.low > 0.5
    assert better.low <= better.value <= better.high
    same = improvement_interval(rng.normal(size=(4, 10)), rng.normal(size=(4, 10)))
    assert same.low < 0.5 < same.high
