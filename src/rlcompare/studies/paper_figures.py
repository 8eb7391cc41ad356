"""The paper study's figures: learning curves (the paper's Figures 3 to 9), greedy actions and values at each stage,
state visits and first actions, each drawn from stored runs."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from rlcompare.algorithms.registry import METHODS
from rlcompare.algorithms.registry import label as method_label
from rlcompare.analysis import plots
from rlcompare.analysis.explain import final_first_action_shares, map_frame
from rlcompare.experiment.results import Results

SMOOTHING = 100


def label(results: Results) -> str:
    c = results.config
    name = method_label(c.algorithm)
    return name if c.algorithm == "random" else f"{name}, ε {c.schedule}"



def curve_figure(runs: list[Results], title: str) -> Figure:
    """Behaviour return (smoothed) beside greedy-evaluation return, mean over seeds with 95% bands."""
    figure = Figure(figsize=(12, 4.2))
    behaviour_ax, greedy_ax = figure.subplots(1, 2, sharey=True)
    plots.fixed_layout(figure, 1, 2, left=0.85, right=0.1, bottom=0.55, top=0.65, column_gap=0.45)
    colors = {label(r): METHODS[r.config.algorithm].color for r in runs}
    episodes = np.arange(1, runs[0].config.episodes + 1)
    plots.plot_return_curves(behaviour_ax, episodes, {label(r): r.records.returns for r in runs},
                             window=SMOOTHING, colors=colors)
    behaviour_ax.set_title(f"behaviour (ε-greedy) return, moving average of {SMOOTHING} episodes")
    if runs[0].records.eval_returns.shape[1]:
        after = np.arange(1, runs[0].config.evaluation_rounds + 1) * runs[0].config.eval_every
        plots.plot_return_curves(greedy_ax, after, {label(r): r.records.eval_returns.mean(axis=2) for r in runs},
                                 window=1, colors=colors, ylabel="greedy return")
        greedy_ax.set_title(f"target policy, {runs[0].config.eval_episodes} episodes every "
                            f"{runs[0].config.eval_every}")
    figure.suptitle(f"{title}  ({len(runs[0].seeds)} seeds, mean and 95% bootstrap band)")
    return figure


def stages_figure(results: Results) -> Figure:
    """Greedy action and state value over position x velocity at each named stage."""
    stage_names = [name for name, _ in results.config.stages]
    episodes = results.config.stage_episodes()
    figure = Figure(figsize=(4.6 * len(stage_names), 7.5))
    axes = figure.subplots(2, len(stage_names), squeeze=False)
    plots.map_layout(figure, 2, len(stage_names))
    floor, frame = float(results.records.snapshots.min()), map_frame(results.config)
    for column, stage in enumerate(stage_names):
        tables = results.records.snapshots[:, column]
        plots.plot_policy_map(axes[0, column], tables, results.config.bins, frame)
        plots.colorbar_beside(axes[0, column], None)  # the maps above keep the width of those below
        axes[0, column].set_title(f"{stage} (episode {episodes[stage]}): greedy action")
        plots.plot_value_map(axes[1, column], tables, results.config.bins, frame, vmin=floor)
        axes[1, column].set_title(f"{stage}: state value")
    figure.suptitle(f"{label(results)}: majority greedy action and mean value over {len(results.seeds)} seeds")
    return figure


def visits_figure(runs: list[Results]) -> Figure:
    figure = Figure(figsize=(4.6 * len(runs), 3.8))
    axes = figure.subplots(1, len(runs), squeeze=False)[0]
    plots.map_layout(figure, 1, len(runs))
    for ax, results in zip(axes, runs, strict=True):
        plots.plot_visits(ax, results.records.visits, results.config.bins, map_frame(results.config))
        ax.set_title(label(results))
    figure.suptitle("Where training spends its steps: state visits over all episodes and seeds")
    return figure


def first_actions_figure(runs: list[Results]) -> Figure:
    figure = Figure(figsize=(7, 4), layout="constrained")
    shares = {}
    for results in runs:
        shares[label(results)] = final_first_action_shares(results).mean(axis=0)
    plots.plot_first_actions(figure.subplots(), shares, runs[0].config.environment.action_names)
    figure.suptitle("First greedy action from the start region (final policies, all seeds)")
    return figure
