"""rliable's aggregates over tasks and runs, against scipy and by what a stratified bootstrap must do."""

from __future__ import annotations

import numpy as np
from scipy import stats

from rlcompare.stats.aggregates import (
    AGGREGATES,
    aggregate_estimates,
    aggregate_mean,
    aggregate_median,
    average_improvement,
    by_method,
    curve_band,
    every_pair,
    improvement_estimates,
    improvement_interval,
    improvement_table,
    interval_estimates,
    interval_table,
    iqm_curve,
    optimality_gap,
    performance_profile,
    pooled_iqm,
    profile_band,
    score_scales,
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


# --- rliable's four aggregates, their intervals, probability of improvement between methods, curves -----------

def test_the_four_aggregates_are_rliables_definitions():
    values = np.array([[0.5, 1.2, 0.2], [0.9, -0.1, 0.4], [3.0, 2.0, 2.5]])  # (tasks, runs)
    assert np.isclose(aggregate_mean(values), np.mean(values.mean(axis=1)))
    assert np.isclose(aggregate_median(values), np.median(values.mean(axis=1)))  # the median of task means, 0.63
    assert not np.isclose(aggregate_median(values), np.median(values))  # not of the pooled runs (0.9)
    assert np.isclose(pooled_iqm(values), stats.trim_mean(values.ravel(), 0.25))
    gaps = [0.5, 0, 0.8, 0.1, 1.1, 0.6, 0, 0, 0]  # max(1 - x, 0), by hand
    assert np.isclose(optimality_gap(values), np.mean(gaps))
    assert np.isclose(optimality_gap(values, gamma=2.0), 2.0 - np.mean(np.minimum(values, 2.0)))
    resampled = stratified_resamples(values, 7)
    for name, statistic in AGGREGATES.items():  # vectorised over resamples: each as if computed alone
        np.testing.assert_allclose(statistic(resampled), [statistic(r) for r in resampled], err_msg=name)


def test_aggregate_estimates_share_one_set_of_resamples_and_hold_their_points():
    values = np.random.default_rng(6).normal(0.7, 0.3, size=(4, 10))
    found = aggregate_estimates(values, resamples=200, seed=3)
    assert list(found) == ["median", "IQM", "mean", "optimality gap"]
    for name, estimate in found.items():
        assert estimate == stratified_interval(values, AGGREGATES[name], resamples=200, seed=3)
        assert estimate.low <= estimate.value <= estimate.high
        assert estimate.low < estimate.high


def test_aggregate_intervals_narrow_with_more_runs():
    rng = np.random.default_rng(7)
    few = aggregate_estimates(rng.normal(size=(3, 5)), resamples=200)
    many = aggregate_estimates(rng.normal(size=(3, 80)), resamples=200)
    for name in AGGREGATES:
        assert many[name].high - many[name].low < (few[name].high - few[name].low) / 2, name


def test_one_run_a_task_gives_points_without_intervals():
    found = aggregate_estimates(np.array([[0.2], [0.6]]), resamples=200)
    assert found["mean"].value == 0.4
    assert all(np.isnan(e.low) and np.isnan(e.high) for e in found.values())


def test_interval_estimates_tabulate_every_method_and_metric():
    rng = np.random.default_rng(8)
    scores = {"a": rng.normal(size=(2, 6)), "b": rng.normal(1.0, size=(2, 6))}
    estimates = interval_estimates(scores, resamples=200)
    assert len(estimates) == 8
    iqm_b = estimates[(estimates["method"] == "b") & (estimates["metric"] == "IQM")].iloc[0]
    assert np.isclose(iqm_b["value"], stats.trim_mean(scores["b"].ravel(), 0.25))
    assert (iqm_b["tasks"], iqm_b["runs"]) == (2, 6)
    table = interval_table(estimates)
    assert table["method"].tolist() == ["a", "b"]
    assert table.loc[1, "IQM [95% CI]"].startswith(f"{iqm_b['value']:.2f} [")


def test_improvement_estimates_cover_every_ordered_pair_and_complement_each_other():
    rng = np.random.default_rng(9)
    scores = {name: rng.normal(shift, size=(3, 6)) for name, shift in (("a", 0.0), ("b", 0.5), ("c", 2.0))}
    estimates = improvement_estimates(scores, resamples=200)
    assert list(zip(estimates["X"], estimates["Y"], strict=True)) == every_pair(["a", "b", "c"])
    assert len(estimates) == 6
    by_pair = estimates.set_index(["X", "Y"])["value"]
    assert np.isclose(by_pair["a", "b"] + by_pair["b", "a"], 1.0)
    assert np.isclose(by_pair["c", "a"], average_improvement(scores["c"], scores["a"]))
    assert estimates.set_index(["X", "Y"]).loc[("c", "a"), "low"] > 0.5
    assert (estimates["low"] <= estimates["value"]).all()
    assert (estimates["value"] <= estimates["high"]).all()
    assert improvement_table(estimates)["P(X > Y) [95% CI]"].str.contains(r"\[").all()


def test_resampled_curves_keep_each_run_whole():
    curves = np.random.default_rng(10).normal(size=(2, 5, 4))  # (tasks, runs, points)
    resampled = stratified_resamples(curves, 30)
    assert resampled.shape == (30, 2, 5, 4)
    for task in range(2):
        for run in resampled[:, task].reshape(-1, 4):
            assert any(np.array_equal(run, original) for original in curves[task])


def test_the_iqm_curve_is_the_trimmed_mean_of_every_run_at_each_point_with_a_band_around_it():
    rng = np.random.default_rng(11)
    curves = np.linspace(0, 1, 6) + rng.normal(0, 0.2, size=(3, 8, 6))
    expected = [stats.trim_mean(curves[..., point].ravel(), 0.25) for point in range(6)]
    np.testing.assert_allclose(iqm_curve(curves), expected)
    point, low, high = curve_band(curves, resamples=200)
    np.testing.assert_allclose(point, expected)
    assert np.all(low <= point)
    assert np.all(point <= high)
    assert np.all(low < high)
    _, one_low, _ = curve_band(curves[:, :1], resamples=200)
    assert np.isnan(one_low).all()


def test_scores_are_normalised_per_task_and_only_shared_tasks_enter():
    per_task = {"easy": {"a": np.array([10.0, 14.0]), "b": np.array([4.0, 6.0])},
                "hard": {"a": np.array([-90.0, -110.0]), "b": np.array([-60.0, -80.0]), "c": np.array([0.0, 1.0])},
                "alone": {"c": np.array([3.0, 4.0])}}
    scales = score_scales(per_task, {"easy": 0.0, "hard": -200.0, "alone": 0.0})
    assert scales["easy"] == (0.0, 12.0)
    assert scales["hard"] == (-200.0, 200.5)  # c's mean 0.5 is the best
    assert score_scales(per_task)["hard"] == (-100.0, 100.5)  # no floors: the worst method's mean
    scores = by_method(per_task, scales)
    assert list(scores) == ["a", "b"]  # c ran "hard" alone among the shared tasks; "alone" has one method
    np.testing.assert_allclose(scores["a"], [[10 / 12, 14 / 12], [110 / 200.5, 90 / 200.5]])
    assert by_method({"only": {"a": np.ones(3), "b": np.zeros(3)}})["a"].shape == (1, 3)
    assert by_method({"one": {"a": np.ones(3)}}) == {}
    flat = {"t": {"a": np.array([5.0]), "b": np.array([5.0])}}
    assert score_scales(flat, {"t": 5.0})["t"] == (5.0, 1.0)  # nothing beat the floor: no division by zero
