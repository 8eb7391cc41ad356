"""The paper study's figures: learning curves (the paper's Figures 3 to 9), greedy actions and values at each stage,
state visits and first actions, each drawn from stored runs."""

from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from rlcompare.algorithms.registry import METHODS
from rlcompare.algorithms.registry import label as method_label
from rlcompare.report import plots
from rlcompare.stats.metrics import returns_per_seed
from rlcompare.studies.start_region import final_first_action_shares, map_of
from rlcompare.tabular.config import ExperimentConfig
from rlcompare.tabular.results import Results

SMOOTHING = 100


def label(results: Results) -> str:
    c = results.config
    name = method_label(c.algorithm)
    return name if c.algorithm == "random" else f"{name}, ε {c.schedule}"



DIFFERENCE_COLOR = "#333333"


def sarsa_and_q_learning(runs: list[Results]) -> tuple[Results, Results] | None:
    """``(SARSA, Q-Learning)`` where ``runs`` are exactly those two, run on the same seeds and episodes (the
    paper's Figures 6 and 9): their seeds are paired. None otherwise."""
    by_algorithm = {r.config.algorithm: r for r in runs}
    if len(runs) != 2 or set(by_algorithm) != {"sarsa", "q_learning"}:
        return None
    sarsa, q_learning = by_algorithm["sarsa"], by_algorithm["q_learning"]
    if (sarsa.seeds != q_learning.seeds or sarsa.config.episodes != q_learning.config.episodes
            or sarsa.records.eval_returns.shape != q_learning.records.eval_returns.shape):
        return None
    return sarsa, q_learning


def curve_figure(runs: list[Results], title: str) -> Figure:
    """Behaviour return (smoothed) beside greedy-evaluation return, mean over seeds with 95% bands. When the runs
    are SARSA and Q-Learning on the same seeds (:func:`sarsa_and_q_learning`), a second row draws their paired
    difference, SARSA minus Q-Learning seed by seed, smoothed alike, with its band and a line at 0: the curves
    span hundreds of reward, the difference tens."""
    pair = sarsa_and_q_learning(runs)
    rows = 2 if pair else 1
    figure = Figure(figsize=(12, 4.2 + 3.6 * (rows - 1)))
    axes = figure.subplots(rows, 2, squeeze=False)
    behaviour_ax, greedy_ax = axes[0]
    greedy_ax.sharey(behaviour_ax)
    greedy_ax.tick_params(labelleft=bool(pair))  # the panels below have their own scales, and room for labels
    plots.fixed_layout(figure, rows, 2, left=0.85, right=0.1, bottom=0.55, top=0.65,
                       column_gap=0.95 if pair else 0.45, row_gap=0.85)
    colors = {label(r): color for r in runs if (color := METHODS[r.config.algorithm].color) is not None}
    config, seeds = runs[0].config, len(runs[0].seeds)
    episodes = np.arange(1, config.episodes + 1)
    plots.plot_return_curves(behaviour_ax, episodes, {label(r): r.records.returns for r in runs},
                             window=SMOOTHING, colors=colors, ylabel="behaviour return per episode")
    behaviour_ax.set_title(f"behaviour (ε-greedy) return, moving average of {SMOOTHING} episodes")
    evaluated = runs[0].records.eval_returns.shape[1] > 0
    after = np.arange(1, config.evaluation_rounds + 1) * config.eval_every
    if evaluated:
        plots.plot_return_curves(greedy_ax, after, {label(r): r.records.eval_returns.mean(axis=2) for r in runs},
                                 window=1, colors=colors, ylabel="greedy return per episode")
        greedy_ax.set_title(f"target policy, {config.eval_episodes} episodes every {config.eval_every}")
    if pair:
        sarsa, q_learning = pair
        name = f"SARSA - Q-Learning, mean of {seeds} paired seeds"
        difference_ax, greedy_difference_ax = axes[1]
        plots.plot_return_curves(difference_ax, episodes, {name: sarsa.records.returns - q_learning.records.returns},
                                 window=SMOOTHING, colors={name: DIFFERENCE_COLOR},
                                 ylabel="SARSA - Q-Learning, behaviour return")
        difference_ax.set_title(f"paired difference: behaviour return, moving average of {SMOOTHING}")
        if evaluated:
            greedy = sarsa.records.eval_returns.mean(axis=2) - q_learning.records.eval_returns.mean(axis=2)
            plots.plot_return_curves(greedy_difference_ax, after, {name: greedy}, window=1,
                                     colors={name: DIFFERENCE_COLOR}, ylabel="SARSA - Q-Learning, greedy return")
            greedy_difference_ax.set_title(f"paired difference: greedy return, {config.eval_episodes} episodes "
                                           f"every {config.eval_every}")
        else:
            greedy_difference_ax.set_axis_off()
        for ax in axes[1]:
            ax.axhline(0, color="black", linewidth=0.8, zorder=1)
            if ax.get_legend() is not None:
                ax.legend(loc="best", fontsize="small")  # the difference crosses the corners the curves leave free
    figure.suptitle(f"{title}  ({seeds} seeds, mean and 95% bootstrap band)")
    return figure


def few_visits_of(results: Results) -> float:
    """Visits a seed below which a cell's values still mostly hold their initial 0: after ``n`` updates of step
    size α the initial value keeps the weight (1 - α)^n, above 1/e while ``n`` < 1/α (20 at the paper's α)."""
    return 1 / results.config.alpha if results.config.alpha > 0 else 0.0


def stages_figure(results: Results) -> Figure:
    """Greedy action and state value over position x velocity at each named stage. Cells no seed visited in all
    of training stay white, cells visited only later are grey, cells visited fewer than 1/α times a seed
    (:func:`few_visits_of`) are hatched; one key for the figure."""
    stage_names = [name for name, _ in results.config.stages]
    episodes = results.config.stage_episodes()
    figure = Figure(figsize=(4.6 * len(stage_names), 7.9))
    axes = figure.subplots(2, len(stage_names), squeeze=False)
    plots.fixed_layout(figure, 2, len(stage_names), left=0.8, right=0.65, bottom=0.5, top=1.05, column_gap=1.4,
                       row_gap=0.8)  # map_layout's, with room for the key under the title
    floor, (frame, bins) = float(results.records.snapshots.min()), map_of(results.config)
    visits, few_visits = results.records.visits, few_visits_of(results)
    for column, stage in enumerate(stage_names):
        tables = results.records.snapshots[:, column]
        plots.plot_policy_map(axes[0, column], tables, bins, frame, visits=visits, few_visits=few_visits, legend=False)
        plots.colorbar_beside(axes[0, column], None)  # the maps above keep the width of those below
        axes[0, column].set_title(f"{stage} (episode {episodes[stage]}): greedy action")
        plots.plot_value_map(axes[1, column], tables, bins, frame, vmin=floor, visits=visits,
                             few_visits=few_visits, legend=False)
        axes[1, column].set_title(f"{stage}: state value")
    figure.suptitle(f"{label(results)}: majority greedy action and mean value over {len(results.seeds)} seeds",
                    y=1 - 0.12 / 7.9)
    figure.legend(handles=plots.action_handles(frame) + plots.visit_handles(few_visits), loc="upper center",
                  bbox_to_anchor=(0.5, 1 - 0.42 / 7.9), ncols=6, fontsize="small", frameon=False)
    return figure


def visits_figure(runs: list[Results]) -> Figure:
    figure = Figure(figsize=(4.6 * len(runs), 3.8))
    axes = figure.subplots(1, len(runs), squeeze=False)[0]
    plots.map_layout(figure, 1, len(runs))
    for ax, results in zip(axes, runs, strict=True):
        frame, bins = map_of(results.config)
        plots.plot_visits(ax, results.records.visits, bins, frame)
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


PAIRS = (("constant", "sarsa-constant", "q_learning-constant"), ("decay", "sarsa-decay", "q_learning-decay"))
"""The schedules of the paper study, each with its SARSA and Q-Learning configurations (run directories)."""
RETURN_PANELS = {
    "behaviour_return": "behaviour return: mean ε-greedy return over all {episodes} training episodes",
    "greedy_return": "greedy return: the final greedy policy, mean of {eval_episodes} episodes",
}


def schedule_text(config: ExperimentConfig) -> str:
    if config.schedule == "constant":
        return f"ε constant at {config.epsilon:g}"
    return f"ε decaying {config.epsilon_start:g} → {config.epsilon_end:g}"


def paired_differences(runs: dict[str, Results], metrics: dict[str, pd.DataFrame] | None = None
                       ) -> dict[str, pd.DataFrame]:
    """For each schedule whose SARSA and Q-Learning both loaded (:data:`PAIRS`): one row per seed both ran, with
    SARSA minus Q-Learning in ``behaviour_return`` and ``greedy_return`` (the numbers of Table II and the
    verdicts: :func:`~rlcompare.stats.metrics.returns_per_seed`). ``metrics``: the per-seed metrics the report
    already holds, by configuration (computed from the runs where absent)."""
    differences = {}
    for schedule, sarsa_name, q_name in PAIRS:
        if sarsa_name not in runs or q_name not in runs:
            continue
        sarsa, q = (_returns(runs, metrics, name).set_index("seed") for name in (sarsa_name, q_name))
        seeds = [seed for seed in sarsa.index if seed in q.index]
        if seeds:
            columns = list(RETURN_PANELS)
            differences[schedule] = (sarsa.loc[seeds, columns] - q.loc[seeds, columns]).reset_index()
    return differences


def _returns(runs: dict[str, Results], metrics: dict[str, pd.DataFrame] | None, name: str) -> pd.DataFrame:
    if metrics is not None and name in metrics:
        return metrics[name]
    records = runs[name].records
    return returns_per_seed(runs[name].seeds, records.returns, records.eval_returns)


def paired_difference_figure(runs: dict[str, Results], metrics: dict[str, pd.DataFrame] | None = None
                             ) -> Figure | None:
    """The study's answer in one picture: SARSA minus Q-Learning seed by seed (dots) with the mean and its 95%
    BCa interval (a bar, :func:`~rlcompare.stats.intervals.interval`, as the verdicts use), for each schedule,
    the behaviour return beside the greedy return. None when no schedule has both runs.

    ``runs`` by configuration name (``load_study``); ``metrics`` as for :func:`paired_differences`."""
    differences = paired_differences(runs, metrics)
    return differences_figure(runs, differences) if differences else None


def differences_figure(runs: dict[str, Results], differences: dict[str, pd.DataFrame]) -> Figure:
    """:func:`paired_difference_figure` of the ``differences`` of ``runs`` (:func:`paired_differences`, not
    empty)."""
    first = runs[next(name for s, name, _ in PAIRS if s in differences)].config
    panels = [m for m in RETURN_PANELS if any(np.isfinite(d[m]).all() for d in differences.values())]
    figure = Figure(figsize=(5.6 * len(panels), 4.6))
    axes = figure.subplots(1, len(panels), squeeze=False)[0]
    plots.fixed_layout(figure, 1, len(panels), left=0.9, right=0.15, bottom=0.75, top=0.9, column_gap=0.9)
    for ax, metric in zip(axes, panels, strict=True):
        plots.plot_paired_differences(
            ax, {schedule: frame[metric].to_numpy(dtype=np.float64) for schedule, frame in differences.items()},
            {s: f"{schedule_text(runs[f'sarsa-{s}'].config)}\n{len(d)} seeds" for s, d in differences.items()})
        ax.set_ylabel("SARSA - Q-Learning (reward per episode)")
        ax.set_title(RETURN_PANELS[metric].format(episodes=first.episodes, eval_episodes=first.eval_episodes),
                     fontsize="medium")
        ax.legend(loc="best", fontsize="small")
    seeds = sorted({len(d) for d in differences.values()})
    figure.suptitle("SARSA minus Q-Learning on the same seeds, in mean cumulative reward per episode\n"
                    f"each dot one seed's difference ({' or '.join(map(str, seeds))} seeds), the bar their mean "
                    "with its 95% BCa bootstrap interval")
    return figure
