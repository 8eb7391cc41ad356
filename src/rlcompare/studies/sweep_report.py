"""A sweep's tables, curves across its swept parameters, and ``report.html``, from its store alone.

- ``tables/configurations.{md,csv}``: one row per configuration, its swept values beside Table II's
  returns (behaviour and greedy, mean with 95% bootstrap intervals, greedy success) and Table I's time to
  converge (censored at the last episode, and how many seeds never converged).
- ``tables/by-<key>.{md,csv}``: the same rows, one table per value of a swept key (``--group-by``).
- ``figures/across-<key>.png``: for each numeric swept key (α, γ, bins, ...), the mean behaviour and greedy
  returns against its value, one line per combination of the other swept keys, one row of panels per
  environment (their returns are on different scales), 95% intervals as bars.
- ``figures/curves-<env>.png``: learning curves of every configuration of an environment (up to 12).
- Over two or more environments, rliable's aggregates (Agarwal et al. 2021) of the configurations that ran on
  every one of them, each configuration a method (named by its swept values but ``env``) and each environment a
  task: scores normalised per environment between the worst and the best configuration's mean (0 and 1), their
  median, IQM, mean and optimality gap with stratified bootstrap intervals (``tables/aggregates``), the probability
  of improvement (``tables/improvement``), performance profiles and IQM sample-efficiency curves
  (``figures/aggregate-*.png`` and beside them).

A deep sweep's configurations (:class:`~rlcompare.deep.results.DeepResults`) have their own columns: the final
greedy return (each seed's mean over the last evaluation round's episodes) and the area under the greedy curve (each
seed's mean over the rounds), mean and IQM with 95% bootstrap intervals. Its figures across a swept key draw those
two, and its learning curves are the greedy return against environment steps.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from rlcompare.experiment import store
from rlcompare.experiment.sweep import swept_value
from rlcompare.experiment.sweep_store import engine_of, is_finished, load_configurations, read_manifest, trial_path
from rlcompare.report import plots
from rlcompare.report.aggregate_plots import draw_aggregates
from rlcompare.report.findings import BEHAVIOUR_AND_GREEDY
from rlcompare.report.page import Section, save_figure, write_report, write_table
from rlcompare.stats.aggregates import by_method, score_scales
from rlcompare.stats.intervals import Estimate, interval
from rlcompare.studies.measures import per_seed_metrics
from rlcompare.tabular.config import ExperimentConfig
from rlcompare.tabular.results import Results

if TYPE_CHECKING:
    from typing_extensions import TypeIs

    from rlcompare.deep.config import DeepConfig
    from rlcompare.deep.results import DeepResults

Tables = list[tuple[str, pd.DataFrame] | tuple[str, pd.DataFrame, str]]
"""A section's tables (:class:`~rlcompare.report.page.Section`)."""

MAX_CURVES = 12
PANELS = {"tabular": (("behaviour_return", "behaviour (ε-greedy) return, mean over training"),
                      ("greedy_return", "greedy return, final")),
          "deep": (("final", "greedy return, final round"), ("auc", "area under the greedy curve"))}
"""What the figures across a swept key draw, per engine: (a column of the per-seed metrics, its title)."""


def _value(value: object) -> str:
    return json.dumps(value) if isinstance(value, list | tuple | dict) else str(value)


def configuration_rows(runs: dict[str, Results], metrics_of: dict[str, pd.DataFrame], swept: list[str]
                       ) -> pd.DataFrame:
    """One row per configuration: its hash, swept values, seeds, returns and time to converge
    (``metrics_of``: :func:`per_seed_metrics` of each, by hash)."""
    rows = []
    for config_hash, results in runs.items():
        metrics = metrics_of[config_hash]
        episodes = results.config.episodes
        behaviour, greedy = metrics["behaviour_return"].to_numpy(), metrics["greedy_return"].to_numpy()
        censored = metrics["convergence_episode"].fillna(episodes).to_numpy()
        rows.append({
            "config": config_hash, **{key: _value(swept_value(results.config, key)) for key in swept},
            "seeds": len(results.seeds),
            "behaviour mean": interval(behaviour).format(1),
            "greedy mean": interval(greedy).format(1) if np.isfinite(greedy).all() else "n/a",
            "greedy success": f"{np.nanmean(metrics['greedy_success']):.0%}" if np.isfinite(greedy).all() else "n/a",
            "episodes to converge (censored)": interval(censored).format(0),
            "never converged": f"{int(metrics['convergence_episode'].isna().sum())} of {len(metrics)}",
        })
    return pd.DataFrame(rows)


def round_means(results: DeepResults) -> pd.DataFrame:
    """The mean greedy return of each seed (a row, in the configuration's order) in each evaluation round (a
    column) of a :class:`~rlcompare.deep.results.DeepResults`."""
    rounds = results.evaluations.groupby(["seed", "round"], sort=True)["return"].mean().unstack("round")
    return rounds.reindex(list(results.seeds))


def deep_metrics(results: DeepResults) -> pd.DataFrame:
    """One row per seed of a :class:`~rlcompare.deep.results.DeepResults`: ``final``, the mean greedy return of the
    last evaluation round, and ``auc``, the area under the greedy curve (the mean over rounds of each round's
    mean)."""
    curves = round_means(results)
    return pd.DataFrame({"seed": list(results.seeds), "final": curves.iloc[:, -1].to_numpy(),
                         "auc": curves.mean(axis=1).to_numpy()})


def deep_configuration_rows(runs: dict[str, DeepResults], metrics_of: dict[str, pd.DataFrame], swept: list[str]
                            ) -> pd.DataFrame:
    """One row per deep configuration: its hash, swept values, seeds, environment steps, and the final greedy
    return and the area under the greedy curve (mean and IQM over seeds, 95% bootstrap intervals)."""
    rows = []
    for config_hash, results in runs.items():
        final, auc = metrics_of[config_hash]["final"].to_numpy(), metrics_of[config_hash]["auc"].to_numpy()
        rows.append({
            "config": config_hash, **{key: _value(swept_value(results.config, key)) for key in swept},
            "seeds": len(results.seeds), "steps": results.meta["timings"]["training_steps"],
            "final greedy, mean": interval(final).format(1), "final greedy, IQM": interval(final, "iqm").format(1),
            "AUC, mean": interval(auc).format(1), "AUC, IQM": interval(auc, "iqm").format(1),
            "diverged seeds": len(results.diverged),
        })
    return pd.DataFrame(rows)


def _numeric(values: list[object]) -> bool:
    return all(isinstance(v, int | float) and not isinstance(v, bool) for v in values)


def across_figure(runs: Mapping[str, Results | DeepResults], metrics_of: dict[str, pd.DataFrame], key: str,
                  swept: list[str], panels: tuple[tuple[str, str], ...] = PANELS["tabular"]) -> Figure:
    """Two metrics (``panels``: behaviour and greedy returns) against ``key``, a line per combination of the other
    swept keys."""
    envs = sorted({r.config.env for r in runs.values()})
    others = [k for k in swept if k not in (key, "env")]
    figure = Figure(figsize=(11, 3.8 * len(envs)), layout="constrained")
    axes = figure.subplots(len(envs), 2, squeeze=False)
    for row, env in enumerate(envs):
        lines: dict[str, list[tuple[Any, list[Estimate]]]] = {}
        for config_hash, results in ((h, r) for h, r in runs.items() if r.config.env == env):
            metrics = metrics_of[config_hash]
            label = ", ".join(f"{k}={_value(swept_value(results.config, k))}" for k in others) or "all"
            lines.setdefault(label, []).append((swept_value(results.config, key),
                                                [interval(metrics[name].to_numpy()) for name, _ in panels]))
        for column, (_, title) in enumerate(panels):
            ax = axes[row, column]
            for label, points in sorted(lines.items()):
                points.sort(key=lambda p: p[0])
                x = [p[0] for p in points]
                estimates = [p[1][column] for p in points]
                y = np.array([e.value for e in estimates])
                error = np.array([[e.value - e.low for e in estimates], [e.high - e.value for e in estimates]])
                ax.errorbar(x, y, yerr=np.nan_to_num(error), marker="o", capsize=3, label=label)
            ax.set_xlabel(key)
            ax.set_ylabel("return")
            ax.set_title(f"{env}: {title}", fontsize="medium")
            ax.grid(alpha=0.3)
            ax.legend(fontsize="x-small")
    figure.suptitle(f"Across {key} (mean over seeds, 95% bootstrap intervals)")
    return figure


def curves_figure(runs: list[Results], swept: list[str], env: str) -> Figure:
    figure = Figure(figsize=(9, 4.5), layout="constrained")
    ax = figure.subplots()
    curves = {_label(r.config, swept): r.records.returns for r in runs}
    episodes = np.arange(1, runs[0].config.episodes + 1)
    window = max(1, min(100, runs[0].config.episodes // 10))
    plots.plot_return_curves(ax, episodes, curves, window=window)
    ax.set_title(f"{env}: behaviour return, moving average of {window} episodes, 95% bands over seeds")
    return figure


def deep_curves_figure(runs: list[DeepResults], swept: list[str], env: str) -> Figure:
    """The greedy return of deep configurations against environment steps, mean over seeds with 95% bands."""
    figure = Figure(figsize=(9, 4.5), layout="constrained")
    ax = figure.subplots()
    for r in runs:
        steps, curves = greedy_curve(r)
        plots.plot_return_curves(ax, steps, {_label(r.config, swept): curves}, window=1, ylabel="greedy return")
    ax.set_xlabel("environment steps")
    ax.set_title(f"{env}: greedy return, 95% bands over seeds")
    return figure


def _label(config: ExperimentConfig | DeepConfig, swept: list[str]) -> str:
    """A configuration as a method across environments: its swept values but the environment."""
    return ", ".join(f"{k}={_value(swept_value(config, k))}" for k in swept if k != "env") or config.name


def _is_tabular(results: Results | DeepResults) -> TypeIs[Results]:
    """Whether ``results`` are a tabular configuration's: they hold records (a deep one's hold evaluations)."""
    return hasattr(results, "records")


def greedy_curve(results: Results | DeepResults) -> tuple[np.ndarray, np.ndarray]:
    """``(x, (seeds, rounds) mean greedy return)``: after which episode (tabular) or environment step (deep) each
    evaluation round came; no rounds where the configuration did not evaluate."""
    if _is_tabular(results):
        returns = results.records.eval_returns
        per_round: np.ndarray = returns.mean(axis=2) if returns.size else np.zeros(returns.shape[:2])
        return (np.arange(per_round.shape[1]) + 1) * results.config.eval_every, per_round
    return np.sort(results.evaluations["after_step"].unique()), round_means(results).to_numpy()


def aggregate_section(runs: Mapping[str, Results | DeepResults], metrics_of: dict[str, pd.DataFrame],
                      swept: list[str], engine: str, tables_dir: Path, figures_dir: Path) -> Section | None:
    """rliable's aggregates over the environments of a sweep that ran two or more (None where it ran one): each
    configuration's swept values but ``env`` are a method, each environment a task, scores normalised per
    environment between the worst configuration's mean (0) and the best's (1)."""
    envs = sorted({r.config.env for r in runs.values()})
    if len(envs) < 2:
        return None
    title = "Across environments"
    column, what = (("final", "final greedy return") if engine == "deep" else
                    ("greedy_return", "final greedy return") if all(
                        np.isfinite(m["greedy_return"]).all() for m in metrics_of.values()) else
                    ("behaviour_return", "behaviour return (mean over training)"))
    finals: dict[str, dict[str, np.ndarray]] = {env: {} for env in envs}
    rounds: dict[str, dict[str, np.ndarray]] = {env: {} for env in envs}
    x_of: dict[tuple[str, str], np.ndarray] = {}
    for config_hash, results in runs.items():
        label, env = _label(results.config, swept), results.config.env
        finals[env][label] = metrics_of[config_hash][column].to_numpy(np.float64)
        x_of[env, label], rounds[env][label] = greedy_curve(results)
    kept = by_method(finals)
    shared = [env for env in envs if len(finals[env]) > 1]
    left_out = sorted({label for env in envs for label in finals[env]} - set(kept))
    if len(shared) < 2 or len(kept) < 2:
        return Section(title, [
            "rliable's aggregates need two or more configurations that ran on two or more environments alike; "
            f"here {len(shared)} environment(s) had more than one configuration and {len(kept)} configuration(s) "
            "ran on all of those."])
    finals = {env: {label: finals[env][label] for label in kept} for env in shared}
    scales = score_scales(finals)
    scores = by_method(finals, scales)
    xs = [x_of[env, label] for env in shared for label in scores]
    curves: dict[str, np.ndarray] = {}
    if column != "behaviour_return" and all(x.size and np.array_equal(x, xs[0]) for x in xs):
        curves = by_method({env: {label: rounds[env][label] for label in scores} for env in shared}, scales)
    drawn = draw_aggregates(scores, figures_dir, tasks="environments", curves=curves, x=xs[0],
                            curve_xlabel="environment steps" if engine == "deep" else "episodes")
    files = [write_table(drawn.intervals, tables_dir, "aggregates"),
             write_table(drawn.improvements, tables_dir, "improvement")]
    return Section(title, [
        f"{len(scores)} configurations over {len(shared)} environments ({', '.join(shared)}), each configuration "
        "named by its swept values but the environment, as rliable defines its aggregates (Agarwal et al. 2021, "
        "\"Deep Reinforcement Learning at the Edge of the Statistical Precipice\"), drawn here. Each seed's "
        f"{what} is normalised environment by environment between the worst configuration's mean (0) and the best's "
        "(1): the scale is this sweep's own range, not the environment's, so a score says where a configuration "
        "stands among these. Median and mean are of each environment's mean over seeds; IQM, optimality gap (γ = 1) "
        "and the profiles pool every seed of every environment; intervals and bands are 95% stratified bootstrap "
        "ones (seeds resampled within each environment). "
        + ("Sample efficiency: the IQM of the greedy return at each evaluation round. " if curves else
           "No sample-efficiency curves: the configurations did not evaluate at the same points. ")
        + (f"Left out, not run on every one of these environments with as many seeds: {'; '.join(left_out)}. "
           if left_out else "")
        + (f"Left out, one configuration alone: {', '.join(env for env in envs if env not in shared)}."
           if len(shared) < len(envs) else "")],
        [("Aggregates of normalised scores", drawn.intervals, files[0]),
         ("Probability of improvement", drawn.improvements, files[1])], drawn.figures)


def build_sweep_report(root: Path, group_by: tuple[str, ...] = ()) -> tuple[Path, list[str]]:
    """Tables, figures and ``report.html`` of the sweep stored in ``root``; the page and what is missing."""
    with store.rewriting(Path(root), store.SWEEP.kind):
        return _build_sweep_report(Path(root), group_by)


def _build_sweep_report(root: Path, group_by: tuple[str, ...]) -> tuple[Path, list[str]]:
    manifest = read_manifest(root)
    swept = list(manifest.get("swept", []))
    unknown = [key for key in group_by if key not in swept]
    if unknown:
        raise store.StoreError(f"group by {unknown[0]!r}: not a swept key of this sweep; swept: {', '.join(swept)}")
    runs, problems = load_configurations(root)
    if not runs:
        raise store.StoreError(f"{root}: no finished trial to report")
    tables_dir, figures_dir = root / "tables", root / "figures"
    store.remove_outputs(root, "figures/*.png")  # the figures of an earlier report, not a user's own
    engine = engine_of(manifest)
    deep = engine == "deep"
    metrics = {config_hash: (deep_metrics if deep else per_seed_metrics)(results)
               for config_hash, results in runs.items()}
    table = (deep_configuration_rows if deep else configuration_rows)(runs, metrics, swept)
    if deep:
        problems += [f"configuration {config_hash}, {note}" for config_hash, results in runs.items()
                     if (note := cast("DeepResults", results).divergence())]
    write_table(table, tables_dir, "configurations")
    grouped: Tables = []
    for key in group_by:
        for value, rows in table.groupby(key, sort=True):
            write_table(rows, tables_dir, _file(f"by-{key}-{value}"))
            grouped.append((f"{key} = {value}", rows.drop(columns=key)))
    numeric = [key for key in swept if _numeric([swept_value(r.config, key) for r in runs.values()])]
    across = [(save_figure(across_figure(runs, metrics, key, swept, PANELS[engine]),
                           figures_dir / f"across-{_file(key)}.png", dpi=90), f"Across {key}") for key in numeric]
    curves = []
    for env in sorted({r.config.env for r in runs.values()}):
        chosen = [r for r in runs.values() if r.config.env == env]
        if len(chosen) <= MAX_CURVES:
            draw = deep_curves_figure if deep else curves_figure
            curves.append((save_figure(draw(chosen, swept, env), figures_dir / f"curves-{_file(env)}.png", dpi=90),
                           f"Learning curves on {env}"))
        else:
            problems.append(f"learning curves on {env}: {len(chosen)} configurations, more than {MAX_CURVES}; "
                            "see the tables and the figures across each swept key")
    done = sum(is_finished(trial_path(root, t["config_hash"], t["seed"]), engine=engine) for t in manifest["trials"])
    across_envs = aggregate_section(runs, metrics, swept, engine, tables_dir, figures_dir)
    sections = [
        Section("Sweep", [f"{manifest['name']}: {len(runs)} configurations with finished trials, {done} of "
                          f"{len(manifest['trials'])} trials finished, root seed {manifest['root_seed']}. Swept: "
                          f"{', '.join(swept) or 'nothing'}. Every configuration runs the same seeds, so they "
                          "compare on common random numbers.",
                          *([BEHAVIOUR_AND_GREEDY] if engine == "tabular" else [])],
                tables=[("Configurations", table)]),
        *([Section("Grouped", tables=grouped)] if grouped else []),
        Section("Across the swept parameters", figures=across) if across else Section(
            "Across the swept parameters", ["No numeric key is swept."]),
        *([across_envs] if across_envs else []),
        Section("Learning curves", figures=curves),
    ]
    path = write_report(root / "report.html", f"Sweep: {manifest['name']}", sections, problems)
    return path, problems


def _file(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in name)
