"""Aggregates over many tasks (games) and runs (seeds), as rliable defines them (Agarwal et al. 2021, "Deep
Reinforcement Learning at the Edge of the Statistical Precipice", NeurIPS; github.com/google-research/rliable):
the mean, median, interquartile mean and optimality gap of normalised scores with stratified bootstrap intervals
(``metrics.py`` and ``library.get_interval_estimates``), performance profiles (``create_performance_profile``), the
average probability of improvement, and IQM sample-efficiency curves, all from the stratified bootstrap that
resamples runs within each task (``StratifiedBootstrap``).

``values`` is ``(tasks, runs)``: one score per run of each task, normalised so that tasks can be pooled (a
sample-efficiency curve's are ``(tasks, runs, points)``). ``scores`` maps each method's label to its ``values``, the
same tasks in the same order for every method. rliable arranges its arrays ``(runs, tasks)``; here tasks come first.
Intervals are percentile intervals, rliable's default; fewer than two runs of a task give no interval (NaN bounds),
as everywhere in :mod:`rlcompare.stats.intervals`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from itertools import permutations
from typing import Any

import numpy as np
import pandas as pd

from rlcompare.stats.intervals import Estimate, improvement_share, iqm

Aggregate = Callable[[np.ndarray], "np.ndarray | float"]
"""A metric over the last two axes of ``values``: one number for ``(tasks, runs)``, an array for resamples."""


def stratified_resamples(values: np.ndarray, resamples: int, seed: int = 0) -> np.ndarray:
    """``(resamples, tasks, runs, ...)``: each task's runs drawn again with replacement, tasks kept apart (rliable's
    ``StratifiedBootstrap``); a run keeps whatever follows it on the trailing axes (its whole learning curve)."""
    values = np.asarray(values)
    tasks, runs = values.shape[:2]
    draws = np.random.default_rng(seed).integers(0, runs, (resamples, tasks, runs))
    return values[np.arange(tasks)[:, None], draws]


def _percentiles(resampled: np.ndarray | float, confidence: float) -> tuple[np.ndarray, np.ndarray]:
    low, high = np.percentile(resampled, [50 * (1 - confidence), 50 * (1 + confidence)], axis=0)
    return low, high


def pooled_iqm(values: np.ndarray) -> np.ndarray | float:
    """IQM of every run of every task pooled, over the last two axes (rliable's ``aggregate_iqm``)."""
    return iqm(values.reshape(*values.shape[:-2], -1), axis=-1)


def aggregate_mean(values: np.ndarray) -> np.ndarray | float:
    """The mean over tasks of each task's mean over runs, over the last two axes (rliable's ``aggregate_mean``)."""
    mean: np.ndarray | float = np.asarray(values).mean(axis=-1).mean(axis=-1)
    return mean


def aggregate_median(values: np.ndarray) -> np.ndarray | float:
    """The median over tasks of each task's mean over runs, over the last two axes (rliable's ``aggregate_median``:
    a median of task means, not of runs)."""
    median: np.ndarray | float = np.median(np.asarray(values).mean(axis=-1), axis=-1)
    return median


def optimality_gap(values: np.ndarray, gamma: float = 1.0) -> np.ndarray | float:
    """How far runs fall short of ``gamma``: the mean of ``max(gamma - x, 0)`` over every run of every task, over
    the last two axes (rliable's ``aggregate_optimality_gap``, ``gamma - mean(min(x, gamma))``); lower is better."""
    gap: np.ndarray | float = np.maximum(gamma - np.asarray(values), 0.0).mean(axis=(-2, -1))
    return gap


AGGREGATES: dict[str, Aggregate] = {"median": aggregate_median, "IQM": pooled_iqm, "mean": aggregate_mean,
                                    "optimality gap": optimality_gap}
"""rliable's four aggregate metrics, in the order of its interval-estimate figures."""


def stratified_interval(values: np.ndarray, statistic: Aggregate = pooled_iqm, confidence: float = 0.95,
                        resamples: int = 2000, seed: int = 0) -> Estimate:
    """``statistic`` of ``values`` with its percentile interval over stratified bootstrap resamples."""
    values = np.asarray(values, np.float64)
    low, high = _percentiles(statistic(stratified_resamples(values, resamples, seed)), confidence)
    return Estimate(float(statistic(values)), float(low), float(high))


def aggregate_estimates(values: np.ndarray, confidence: float = 0.95, resamples: int = 2000, seed: int = 0,
                        metrics: Mapping[str, Aggregate] = AGGREGATES) -> dict[str, Estimate]:
    """Each of ``metrics`` (rliable's median, IQM, mean and optimality gap) of one method's ``(tasks, runs)``
    scores, with its percentile interval over one set of stratified bootstrap resamples (rliable's
    ``get_interval_estimates``)."""
    values = np.asarray(values, np.float64)
    resampled = stratified_resamples(values, resamples, seed) if values.shape[1] > 1 else None
    found: dict[str, Estimate] = {}
    for name, statistic in metrics.items():
        low, high = (np.nan, np.nan) if resampled is None else _percentiles(statistic(resampled), confidence)
        found[name] = Estimate(float(statistic(values)), float(low), float(high))
    return found


def interval_estimates(scores: Mapping[str, np.ndarray], confidence: float = 0.95, resamples: int = 2000,
                       seed: int = 0) -> pd.DataFrame:
    """One row per method and metric: ``method, metric, value, low, high, tasks, runs`` (:func:`aggregate_estimates`
    of each method's scores)."""
    rows = []
    for method, values in scores.items():
        values = np.asarray(values, np.float64)
        for metric, estimate in aggregate_estimates(values, confidence, resamples, seed).items():
            rows.append({"method": method, "metric": metric, **estimate._asdict(), "tasks": values.shape[0],
                         "runs": values.shape[1]})
    return pd.DataFrame(rows, columns=["method", "metric", "value", "low", "high", "tasks", "runs"])


def _shown(row: Any, digits: int) -> str:
    """``value [low, high]``; "no data" where there is no value (a NaN score)."""
    return "no data" if np.isnan(row.value) else Estimate(row.value, row.low, row.high).format(digits)


def interval_table(estimates: pd.DataFrame, digits: int = 2, tasks: str = "tasks") -> pd.DataFrame:
    """:func:`interval_estimates` as a report shows it: one row per method, each metric as ``value [low, high]``
    (``tasks``: what the column of the number of tasks is called)."""
    rows: dict[object, dict[str, Any]] = {}  # by method
    for row in estimates.itertuples():
        entry = rows.setdefault(row.method, {"method": row.method, tasks: row.tasks, "runs each": row.runs})
        entry[f"{row.metric} [95% CI]"] = _shown(row, digits)
    return pd.DataFrame(list(rows.values()))


def performance_profile(values: np.ndarray, thresholds: np.ndarray) -> np.ndarray:
    """The fraction of runs, over every task, whose score is above each threshold (rliable's run-score
    distribution, ``create_performance_profile``); over the last two axes of ``values``."""
    pooled = np.asarray(values).reshape(*np.shape(values)[:-2], -1)
    profile: np.ndarray = (pooled[..., None, :] > np.asarray(thresholds)[:, None]).mean(axis=-1)
    return profile


def profile_band(values: np.ndarray, thresholds: np.ndarray, confidence: float = 0.95, resamples: int = 2000,
                 seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(profile, low, high)`` at each threshold, the band from stratified bootstrap resamples."""
    values = np.asarray(values, np.float64)
    low, high = _percentiles(performance_profile(stratified_resamples(values, resamples, seed), thresholds),
                             confidence)
    return performance_profile(values, thresholds), low, high


def average_improvement(x: np.ndarray, y: np.ndarray) -> np.ndarray | float:
    """P(X > Y): over tasks, the mean of the chance that a run of ``x`` beats a run of ``y`` on the task (ties
    count half; the Mann-Whitney U over ``n m``), over the last two axes (rliable's
    ``probability_of_improvement``). A monotone rescaling of a task changes nothing, so raw scores will do."""
    average: np.ndarray | float = np.mean(improvement_share(np.asarray(x), np.asarray(y)), axis=-1)
    return average


def improvement_interval(x: np.ndarray, y: np.ndarray, confidence: float = 0.95, resamples: int = 2000,
                         seed: int = 0) -> Estimate:
    """:func:`average_improvement` with its percentile interval, the runs of ``x`` and of ``y`` resampled
    within each task, apart from each other (rliable's stratified bootstrap of the two algorithms)."""
    x, y = np.asarray(x, np.float64), np.asarray(y, np.float64)
    resampled = average_improvement(stratified_resamples(x, resamples, seed),
                                    stratified_resamples(y, resamples, seed + 1))
    low, high = _percentiles(resampled, confidence)
    return Estimate(float(average_improvement(x, y)), float(low), float(high))


def every_pair(methods: Sequence[str]) -> list[tuple[str, str]]:
    """Every ordered pair ``(X, Y)`` of two different methods, ``X`` in the order given."""
    return list(permutations(methods, 2))


def improvement_estimates(scores: Mapping[str, np.ndarray], pairs: Sequence[tuple[str, str]] | None = None,
                          confidence: float = 0.95, resamples: int = 2000, seed: int = 0) -> pd.DataFrame:
    """One row per pair ``(X, Y)`` (default: :func:`every_pair`): ``X, Y, value, low, high, tasks`` of
    :func:`improvement_interval`, P(X > Y) averaged over the tasks."""
    rows = [{"X": x, "Y": y, **improvement_interval(scores[x], scores[y], confidence, resamples, seed)._asdict(),
             "tasks": np.shape(scores[x])[0]}
            for x, y in (every_pair(list(scores)) if pairs is None else pairs)]
    return pd.DataFrame(rows, columns=["X", "Y", "value", "low", "high", "tasks"])


def improvement_table(estimates: pd.DataFrame, digits: int = 2, tasks: str = "tasks") -> pd.DataFrame:
    """:func:`improvement_estimates` as a report shows it: ``P(X > Y) [95% CI]`` per pair."""
    return pd.DataFrame({"X": estimates["X"], "Y": estimates["Y"], tasks: estimates["tasks"],
                         "P(X > Y) [95% CI]": [_shown(row, digits) for row in estimates.itertuples()]})


def iqm_curve(curves: np.ndarray) -> np.ndarray:
    """The IQM over every task and run at each point of ``(..., tasks, runs, points)`` curves: ``(..., points)``
    (rliable's sample-efficiency curves, ``aggregate_iqm`` at each frame)."""
    return np.asarray(pooled_iqm(np.moveaxis(np.asarray(curves), -1, -3)))  # an array already: one IQM a point


def curve_band(curves: np.ndarray, confidence: float = 0.95, resamples: int = 2000, seed: int = 0
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(iqm, low, high)`` at each point of ``(tasks, runs, points)`` curves, whole runs resampled within each
    task (one draw for every point, as rliable's ``get_interval_estimates`` does for curves)."""
    curves = np.asarray(curves, np.float64)
    point = iqm_curve(curves)
    if curves.shape[1] < 2:
        return point, np.full_like(point, np.nan), np.full_like(point, np.nan)
    low, high = _percentiles(iqm_curve(stratified_resamples(curves, resamples, seed)), confidence)
    return point, low, high


def score_scales(per_task: Mapping[str, Mapping[str, np.ndarray]], floors: Mapping[str, float] | None = None
                 ) -> dict[str, tuple[float, float]]:
    """Per task, ``(floor, scale)`` that map its ``floor`` to 0 and the best method's mean score to 1 (the floor:
    ``floors``, e.g. a random policy's return, or else the worst method's mean). A best no higher than the floor
    keeps the scale 1, so nothing is divided by zero. ``per_task[task][method]``: that method's runs on the task."""
    scales = {}
    for task, methods in per_task.items():
        means = [float(np.mean(values)) for values in methods.values()]
        floor = float(floors[task]) if floors is not None else min(means)
        scales[task] = (floor, max(means) - floor if max(means) > floor else 1.0)
    return scales


def by_method(per_task: Mapping[str, Mapping[str, np.ndarray]],
              scales: Mapping[str, tuple[float, float]] | None = None) -> dict[str, np.ndarray]:
    """``per_task[task][method]`` (runs, or runs x points) as ``scores[method]``, ``(tasks, runs, ...)``, each task
    normalised by ``scales`` (:func:`score_scales`) where given. Only the tasks that two or more methods ran, and
    only the methods that ran every one of those with as many runs on each, enter: every method over the same
    tasks, in the order of ``per_task``."""
    tasks = [task for task, methods in per_task.items() if len(methods) > 1]
    methods = dict.fromkeys(method for task in tasks for method in per_task[task])
    kept = [method for method in methods
            if all(method in per_task[task] for task in tasks)
            and len({np.shape(per_task[task][method]) for task in tasks}) == 1]

    def scaled(task: str, values: np.ndarray) -> np.ndarray:
        floor, scale = scales[task] if scales is not None else (0.0, 1.0)
        return (np.asarray(values, np.float64) - floor) / scale

    return {method: np.stack([scaled(task, per_task[task][method]) for task in tasks]) for method in kept}
