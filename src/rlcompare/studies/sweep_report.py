"""A sweep's tables, curves across its swept parameters, and ``report.html``, from its store alone.

- ``tables/configurations.{md,csv}``: one row per configuration, its swept values beside Table II's
  returns (behaviour and greedy, mean with 95% bootstrap intervals, greedy success) and Table I's time to
  converge (censored at the last episode, and how many seeds never converged).
- ``tables/by-<key>.{md,csv}``: the same rows, one table per value of a swept key (``--group-by``).
- ``figures/across-<key>.png``: for each numeric swept key (α, γ, bins, ...), the mean behaviour and greedy
  returns against its value, one line per combination of the other swept keys, one row of panels per
  environment (their returns are on different scales), 95% intervals as bars.
- ``figures/curves-<env>.png``: learning curves of every configuration of an environment (up to 12).

A deep sweep's configurations (:class:`~rlcompare.deep.run.DeepResults`) have their own columns: the final greedy
return (each seed's mean over the last evaluation round's episodes) and the area under the greedy curve (each
seed's mean over the rounds), mean and IQM with 95% bootstrap intervals. Its figures across a swept key draw those
two, and its learning curves are the greedy return against environment steps.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from rlcompare.analysis import plots
from rlcompare.analysis.report import Section, save_figure, write_report, write_table
from rlcompare.analysis.stats import interval
from rlcompare.analysis.tables import per_seed_metrics
from rlcompare.experiment import store
from rlcompare.experiment.results import Results
from rlcompare.experiment.sweep import swept_value
from rlcompare.experiment.sweep_store import engine_of, is_finished, load_configurations, read_manifest, trial_path

MAX_CURVES = 12
PANELS = {"tabular": (("behaviour_return", "behaviour (ε-greedy) return, mean over training"),
                      ("greedy_return", "greedy return, final")),
          "deep": (("final", "greedy return, final round"), ("auc", "area under the greedy curve"))}
"""What the figures across a swept key draw, per engine: (a column of the per-seed metrics, its title)."""


def _value(value) -> str:
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


def deep_metrics(results) -> pd.DataFrame:
    """One row per seed of a :class:`~rlcompare.deep.run.DeepResults`: ``final``, the mean greedy return of the
    last evaluation round, and ``auc``, the area under the greedy curve (the mean over rounds of each round's
    mean)."""
    curves = results.evaluations.groupby(["seed", "round"], sort=True)["return"].mean().unstack("round")
    curves = curves.reindex(list(results.seeds))
    return pd.DataFrame({"seed": list(results.seeds), "final": curves.iloc[:, -1].to_numpy(),
                         "auc": curves.mean(axis=1).to_numpy()})


def deep_configuration_rows(runs: dict, metrics_of: dict[str, pd.DataFrame], swept: list[str]) -> pd.DataFrame:
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
        })
    return pd.DataFrame(rows)


def _numeric(values: list) -> bool:
    return all(isinstance(v, int | float) and not isinstance(v, bool) for v in values)


def across_figure(runs: dict[str, Results], metrics_of: dict[str, pd.DataFrame], key: str, swept: list[str],
                  panels: tuple[tuple[str, str], ...] = PANELS["tabular"]) -> Figure:
    """Two metrics (``panels``: behaviour and greedy returns) against ``key``, a line per combination of the other
    swept keys."""
    envs = sorted({r.config.env for r in runs.values()})
    others = [k for k in swept if k not in (key, "env")]
    figure = Figure(figsize=(11, 3.8 * len(envs)), layout="constrained")
    axes = figure.subplots(len(envs), 2, squeeze=False)
    for row, env in enumerate(envs):
        lines: dict[str, list[tuple[float, object, object]]] = {}
        for config_hash, results in ((h, r) for h, r in runs.items() if r.config.env == env):
            metrics = metrics_of[config_hash]
            label = ", ".join(f"{k}={_value(swept_value(results.config, k))}" for k in others) or "all"
            lines.setdefault(label, []).append((swept_value(results.config, key),
                                                *(interval(metrics[name].to_numpy()) for name, _ in panels)))
        for column, (_, title) in enumerate(panels):
            ax = axes[row, column]
            for label, points in sorted(lines.items()):
                points.sort(key=lambda p: p[0])
                x = [p[0] for p in points]
                estimates = [p[1 + column] for p in points]
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
    others = [k for k in swept if k != "env"]
    curves = {", ".join(f"{k}={_value(swept_value(r.config, k))}" for k in others) or r.config.name:
              r.records.returns for r in runs}
    episodes = np.arange(1, runs[0].config.episodes + 1)
    window = max(1, min(100, runs[0].config.episodes // 10))
    plots.plot_return_curves(ax, episodes, curves, window=window)
    ax.set_title(f"{env}: behaviour return, moving average of {window} episodes, 95% bands over seeds")
    return figure


def deep_curves_figure(runs: list, swept: list[str], env: str) -> Figure:
    """The greedy return of deep configurations against environment steps, mean over seeds with 95% bands."""
    figure = Figure(figsize=(9, 4.5), layout="constrained")
    ax = figure.subplots()
    others = [k for k in swept if k != "env"]
    for r in runs:
        curves = r.evaluations.groupby(["seed", "round"], sort=True)["return"].mean().unstack("round")
        label = ", ".join(f"{k}={_value(swept_value(r.config, k))}" for k in others) or r.config.name
        plots.plot_return_curves(ax, np.sort(r.evaluations["after_step"].unique()),
                                 {label: curves.reindex(list(r.seeds)).to_numpy()}, window=1, ylabel="greedy return")
    ax.set_xlabel("environment steps")
    ax.set_title(f"{env}: greedy return, 95% bands over seeds")
    return figure


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
    write_table(table, tables_dir, "configurations")
    grouped = []
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
    sections = [
        Section("Sweep", [f"{manifest['name']}: {len(runs)} configurations with finished trials, {done} of "
                          f"{len(manifest['trials'])} trials finished, root seed {manifest['root_seed']}. Swept: "
                          f"{', '.join(swept) or 'nothing'}. Every configuration runs the same seeds, so they "
                          "compare on common random numbers."],
                tables=[("Configurations", table)]),
        *([Section("Grouped", tables=grouped)] if grouped else []),
        Section("Across the swept parameters", figures=across) if across else Section(
            "Across the swept parameters", ["No numeric key is swept."]),
        Section("Learning curves", figures=curves),
    ]
    path = write_report(root / "report.html", f"Sweep: {manifest['name']}", sections, problems)
    return path, problems


def _file(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in name)
