"""Aggregates over many tasks (games) and runs (seeds), as rliable defines them (Agarwal et al. 2021, "Deep
Reinforcement Learning at the Edge of the Statistical Precipice"): the interquartile mean of every task's runs
together, performance profiles, the average probability of improvement, and the stratified bootstrap that
resamples runs within each task.

``values`` is ``(tasks, runs)``: one score per run of each task, normalised so that tasks can be pooled.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from rlcompare.analysis.stats import Estimate, improvement_share, iqm


def stratified_resamples(values: np.ndarray, resamples: int, seed: int = 0) -> np.ndarray:
    """``(resamples, tasks, runs)``: each task's runs drawn again with replacement, tasks kept apart (rliable's
    ``StratifiedBootstrap``)."""
    tasks, runs = values.shape
    draws = np.random.default_rng(seed).integers(0, runs, (resamples, tasks, runs))
    return np.take_along_axis(np.broadcast_to(values, (resamples, tasks, runs)), draws, axis=2)


def pooled_iqm(values: np.ndarray) -> np.ndarray:
    """IQM of every run of every task pooled, over the last two axes (rliable's ``aggregate_iqm``)."""
    return iqm(values.reshape(*values.shape[:-2], -1), axis=-1)


def stratified_interval(values: np.ndarray, statistic: Callable[[np.ndarray], np.ndarray] = pooled_iqm,
                        confidence: float = 0.95, resamples: int = 2000, seed: int = 0) -> Estimate:
    """``statistic`` of ``values`` with its percentile interval over stratified bootstrap resamples."""
    values = np.asarray(values, np.float64)
    low, high = np.percentile(statistic(stratified_resamples(values, resamples, seed)),
                              [50 * (1 - confidence), 50 * (1 + confidence)])
    return Estimate(float(statistic(values)), float(low), float(high))


def performance_profile(values: np.ndarray, thresholds: np.ndarray) -> np.ndarray:
    """The fraction of runs, over every task, whose score is above each threshold (rliable's run-score
    distribution, ``create_performance_profile``); over the last two axes of ``values``."""
    pooled = np.asarray(values).reshape(*np.shape(values)[:-2], -1)
    return (pooled[..., None, :] > np.asarray(thresholds)[:, None]).mean(axis=-1)


def profile_band(values: np.ndarray, thresholds: np.ndarray, confidence: float = 0.95, resamples: int = 2000,
                 seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(profile, low, high)`` at each threshold, the band from stratified bootstrap resamples."""
    values = np.asarray(values, np.float64)
    resampled = performance_profile(stratified_resamples(values, resamples, seed), thresholds)
    low, high = np.percentile(resampled, [50 * (1 - confidence), 50 * (1 + confidence)], axis=0)
    return performance_profile(values, thresholds), low, high


def average_improvement(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """P(X > Y): over tasks, the mean of the chance that a run of ``x`` beats a run of ``y`` on the task (ties
    count half; the Mann-Whitney U over ``n m``), over the last two axes (rliable's
    ``probability_of_improvement``). A monotone rescaling of a task changes nothing, so raw scores will do."""
    return improvement_share(np.asarray(x), np.asarray(y)).mean(axis=-1)


def improvement_interval(x: np.ndarray, y: np.ndarray, confidence: float = 0.95, resamples: int = 2000,
                         seed: int = 0) -> Estimate:
    """:func:`average_improvement` with its percentile interval, the runs of ``x`` and of ``y`` resampled
    within each task, apart from each other (rliable's stratified bootstrap of the two algorithms)."""
    x, y = np.asarray(x, np.float64), np.asarray(y, np.float64)
    resampled = average_improvement(stratified_resamples(x, resamples, seed),
                                    stratified_resamples(y, resamples, seed + 1))
    low, high = np.percentile(resampled, [50 * (1 - confidence), 50 * (1 + confidence)])
    return Estimate(float(average_improvement(x, y)), float(low), float(high))
