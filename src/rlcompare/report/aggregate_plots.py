"""rliable's aggregate figures, drawn here on our own statistics (:mod:`rlcompare.stats.aggregates`): interval
estimates of the median, IQM, mean and optimality gap, the probability of improvement between methods, IQM
sample-efficiency curves and performance profiles, each with its 95% stratified bootstrap interval or band (Agarwal
et al. 2021, "Deep Reinforcement Learning at the Edge of the Statistical Precipice", NeurIPS; rliable's
``plot_utils``: ``plot_interval_estimates``, ``plot_probability_of_improvement``, ``plot_sample_efficiency_curve``
and ``plot_performance_profiles``). rliable itself no longer imports with pandas 3.

``scores`` maps each method's label (what the figure writes) to its ``(tasks, runs)`` normalised scores, every
method over the same tasks. Each function returns a :class:`~matplotlib.figure.Figure` and touches no pyplot state;
a method keeps one colour in every figure drawn with the same ``scores`` (:func:`method_colors`).
:func:`draw_aggregates` draws them all for a report and saves them.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from functools import partial
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from rlcompare.report.page import Section, save_figure
from rlcompare.stats.aggregates import (
    curve_band,
    every_pair,
    improvement_estimates,
    improvement_table,
    interval_estimates,
    interval_table,
    profile_band,
)

NORMALISED = "normalised score"
BAR = 0.6
"""Height of an interval's bar, in rows (rliable's ``interval_height``)."""


def method_colors(methods: Sequence[str]) -> dict[str, str]:
    """Matplotlib's colour cycle in the order of ``methods``: the same method the same colour in every figure."""
    return {method: f"C{index % 10}" for index, method in enumerate(methods)}


def _interval_row(ax: Axes, row: int, value: float, low: float, high: float, color: str) -> None:
    """rliable's interval estimate: a bar over the interval and a black tick at the point estimate."""
    if np.isfinite(low) and np.isfinite(high):
        ax.barh(row, high - low, height=BAR, left=low, color=color, alpha=0.75)
    ax.vlines(value, row - BAR * 7.5 / 16, row + BAR * 6 / 16, color="k", alpha=0.6)


def interval_figure(scores: Mapping[str, np.ndarray], xlabel: str = NORMALISED, *,
                    estimates: pd.DataFrame | None = None, resamples: int = 2000) -> Figure:
    """One panel per aggregate metric (median, IQM, mean, optimality gap), one row per method: the 95% stratified
    bootstrap interval as a bar, the point estimate as a tick (rliable's ``plot_interval_estimates``).
    ``estimates``: :func:`~rlcompare.stats.aggregates.interval_estimates` of ``scores``, where already computed."""
    if estimates is None:
        estimates = interval_estimates(scores, resamples=resamples)
    methods, metrics = list(scores), list(dict.fromkeys(estimates["metric"]))
    colors = method_colors(methods)
    figure = Figure(figsize=(3.1 * len(metrics), 1.3 + 0.42 * len(methods)), layout="constrained")
    axes = figure.subplots(1, len(metrics), squeeze=False)[0]
    for ax, metric in zip(axes, metrics, strict=True):
        chosen = estimates[estimates["metric"] == metric].set_index("method")
        for row, method in enumerate(methods):
            estimate = chosen.loc[method]
            _interval_row(ax, row, estimate["value"], estimate["low"], estimate["high"], colors[method])
        ax.set_yticks(range(len(methods)), methods) if ax is axes[0] else ax.set_yticks([])
        ax.set_ylim(len(methods) - 0.5, -0.5)  # the first method on top
        ax.set_title(metric + (" (lower is better)" if metric == "optimality gap" else ""), fontsize="medium")
        ax.xaxis.get_major_locator().set_params(nbins=4)
        ax.tick_params(axis="y", length=0)
        ax.grid(axis="x", alpha=0.3)
        ax.spines[["left", "top", "right"]].set_visible(False)
    figure.supxlabel(f"{xlabel} (95% stratified bootstrap intervals)", fontsize="medium")
    return figure


def improvement_figure(scores: Mapping[str, np.ndarray], pairs: Sequence[tuple[str, str]] | None = None, *,
                       estimates: pd.DataFrame | None = None, resamples: int = 2000) -> Figure:
    """One row per pair of methods ``(X, Y)`` (default: every ordered pair): P(X > Y), the chance that a run of X
    beats a run of Y on a task, averaged over the tasks, its 95% stratified bootstrap interval as a bar and a dashed
    line at 0.5, X named on the left and Y on the right (rliable's ``plot_probability_of_improvement``).
    ``estimates``: :func:`~rlcompare.stats.aggregates.improvement_estimates`, where already computed."""
    if estimates is None:
        estimates = improvement_estimates(scores, pairs, resamples=resamples)
    colors = method_colors(list(scores))
    rows = len(estimates)
    figure = Figure(figsize=(7, 1.2 + 0.36 * rows), layout="constrained")
    ax = figure.subplots()
    shown = zip(estimates["X"], estimates["value"], estimates["low"], estimates["high"], strict=True)
    for row, (x, value, low, high) in enumerate(shown):
        _interval_row(ax, row, value, low, high, colors[x])
    ax.axvline(0.5, color="0.4", linestyle="--", linewidth=1)
    ax.set_xlim(0, 1)
    ax.set_ylim(rows - 0.5, -0.5)
    ax.set_yticks(range(rows), list(estimates["X"]))
    ax.set_ylabel("X")
    twin = ax.twinx()
    twin.set_ylim(ax.get_ylim())
    twin.set_yticks(range(rows), list(estimates["Y"]))
    twin.set_ylabel("Y")
    ax.set_xlabel("P(X > Y), averaged over tasks (95% stratified bootstrap interval)")
    ax.grid(axis="x", alpha=0.3)
    return figure


def sample_efficiency_figure(x: np.ndarray, curves: Mapping[str, np.ndarray], xlabel: str, *,
                             ylabel: str = f"IQM of {NORMALISED}", resamples: int = 2000) -> Figure:
    """IQM over every task and run of each method's ``(tasks, runs, points)`` curves at each ``x`` (frames, steps,
    episodes), with its 95% stratified bootstrap band, one line per method (rliable's
    ``plot_sample_efficiency_curve``)."""
    colors = method_colors(list(curves))
    figure = Figure(figsize=(7, 4.2), layout="constrained")
    ax = figure.subplots()
    for method, values in curves.items():
        point, low, high = curve_band(values, resamples=resamples)
        ax.plot(x, point, color=colors[method], marker="o", markersize=3, linewidth=1.5, label=method)
        ax.fill_between(x, low, high, color=colors[method], alpha=0.2, linewidth=0)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small")
    return figure


def profile_figure(scores: Mapping[str, np.ndarray], xlabel: str = NORMALISED, *,
                   thresholds: np.ndarray | None = None, resamples: int = 2000) -> Figure:
    """Performance profiles: the fraction of runs, over every task, whose score is above each threshold τ, with a
    95% stratified bootstrap band (rliable's ``plot_performance_profiles``; Agarwal et al. 2021, Figure 5).
    ``thresholds``: by default from the lower of 0 and the lowest score to the higher of 1 and the highest."""
    if thresholds is None:
        pooled = np.concatenate([np.ravel(values) for values in scores.values()])
        finite = pooled[np.isfinite(pooled)]
        thresholds = np.linspace(finite.min(initial=0.0), finite.max(initial=1.0), 81)
    colors = method_colors(list(scores))
    figure = Figure(figsize=(7, 4.2), layout="constrained")
    ax = figure.subplots()
    for method, values in scores.items():
        profile, low_band, high_band = profile_band(values, thresholds, resamples=resamples)
        ax.plot(thresholds, profile, color=colors[method], linewidth=1.5, label=method)
        ax.fill_between(thresholds, low_band, high_band, color=colors[method], alpha=0.2, linewidth=0)
    ax.set_xlabel(f"{xlabel} τ")
    ax.set_ylabel("fraction of runs with score > τ")
    ax.set_ylim(-0.02, 1.02)
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small")
    return figure


MAX_PAIRED = 6
"""Up to this many methods, the probability of improvement is drawn for every ordered pair (30 rows); beyond, for
the best method by IQM against each other one."""


class Aggregates(NamedTuple):
    """What a report shows of rliable's aggregates: two tables and the figures saved, with their captions."""

    intervals: pd.DataFrame
    """:func:`~rlcompare.stats.aggregates.interval_table`: median, IQM, mean, optimality gap per method."""
    improvements: pd.DataFrame
    """:func:`~rlcompare.stats.aggregates.improvement_table`: P(X > Y) per pair."""
    figures: list[tuple[str, str]]
    """(path relative to the study directory, caption), as :class:`~rlcompare.report.page.Section` takes them."""


def improvement_pairs(methods: Sequence[str], estimates: pd.DataFrame) -> list[tuple[str, str]]:
    """Every ordered pair of up to :data:`MAX_PAIRED` methods; beyond, the best by IQM (``estimates``:
    :func:`~rlcompare.stats.aggregates.interval_estimates`) against each other one."""
    if len(methods) <= MAX_PAIRED:
        return every_pair(methods)
    iqms = estimates[estimates["metric"] == "IQM"].set_index("method")["value"]
    best = max(methods, key=lambda method: iqms[method])
    return [(best, method) for method in methods if method != best]


def draw_aggregates(scores: Mapping[str, np.ndarray], directory: Path, *, xlabel: str = NORMALISED,
                    tasks: str = "tasks", curves: Mapping[str, np.ndarray] | None = None, x: np.ndarray | None = None,
                    curve_xlabel: str = "", prefix: str = "", resamples: int = 2000,
                    figure: Callable[[Path, Callable[[Path], str]], str] | None = None) -> Aggregates:
    """Every aggregate of ``scores`` (``(tasks, runs)`` per method): the interval estimates and the probability of
    improvement as tables, and the interval-estimate, probability-of-improvement, performance-profile and (with
    ``curves``, ``(tasks, runs, points)`` per method at ``x``) sample-efficiency figures saved as PNG files in
    ``directory`` (names begin with ``prefix``). ``tasks`` names the tasks in the captions (environments, games).
    ``figure(path, draw)``: where given, what saves each figure (``draw(path)`` saves it and returns its relative
    path), e.g. :meth:`rlcompare.report.drawn.Drawn.figure`, which keeps one whose inputs have not changed."""
    intervals = interval_estimates(scores, resamples=resamples)
    pairs = improvement_pairs(list(scores), intervals)
    improvements = improvement_estimates(scores, pairs, resamples=resamples)
    shape = next(iter(scores.values())).shape
    over = f"{shape[0]} {tasks} x {shape[1]} runs"
    paired = ("every ordered pair of methods" if len(pairs) == len(scores) * (len(scores) - 1)
              else f"the best method by IQM ({pairs[0][0]}) against each other one")
    drawn: list[tuple[Callable[[], Figure], str, str]] = [
        (lambda: interval_figure(scores, xlabel, estimates=intervals), "aggregate-intervals",
         f"Median and mean of the {tasks}' mean scores, IQM and optimality gap (γ = 1: the mean shortfall below 1) "
         f"of every run, over {over}: bars are 95% stratified bootstrap intervals, ticks the estimates"),
        (lambda: improvement_figure(scores, estimates=improvements), "probability-of-improvement",
         f"Probability of improvement, {paired}: the chance that a run of X beats a run of Y on one of the {tasks}, "
         f"averaged over the {tasks}, with its 95% stratified bootstrap interval; 0.5 is no difference"),
        (lambda: profile_figure(scores, xlabel, resamples=resamples), "performance-profiles",
         f"Performance profiles: the fraction of runs, over every one of the {tasks}, with a score above τ (95% "
         "stratified bootstrap bands)"),
    ]
    if curves:
        if x is None:
            raise ValueError("curves need x: the step or episode of each of their points")
        drawn.append((lambda: sample_efficiency_figure(x, curves, curve_xlabel, resamples=resamples),
                      "sample-efficiency",
                      f"Sample efficiency: the IQM of every run's {xlabel} over the {tasks} at each point of training, "
                      "with a 95% stratified bootstrap band"))
    save = figure or _drawn_anew
    figures = [(save(Path(directory) / f"{prefix}{name}.png", partial(_saved, make)), caption)
               for make, name, caption in drawn]
    return Aggregates(interval_table(intervals, tasks=tasks), improvement_table(improvements, tasks=tasks), figures)


def _drawn_anew(path: Path, draw: Callable[[Path], str]) -> str:
    """The figure at ``path`` drawn and saved, whatever is there already."""
    return draw(path)


def _saved(make: Callable[[], Figure], path: Path) -> str:
    """``make()``'s figure saved at ``path`` (:func:`~rlcompare.report.page.save_figure`)."""
    return save_figure(make(), path)


def across_section(title: str, words: str, aggregates: Aggregates | None, files: Mapping[str, str], intervals: str,
                   missing: str) -> Section:
    """rliable's aggregates as a report's section: ``words``, the interval estimates (captioned ``intervals``) and
    the probability of improvement with their files, and the figures; ``missing`` alone where none were drawn."""
    if aggregates is None:
        return Section(title, [missing])
    return Section(title, [words], [(intervals, aggregates.intervals, files["aggregates"]),
                                    ("Probability of improvement", aggregates.improvements, files["improvement"])],
                   aggregates.figures)
