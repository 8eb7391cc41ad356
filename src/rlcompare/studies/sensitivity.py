"""Does the paper's conclusion, SARSA beats Q-Learning on Mountain Car, survive other settings?

A grid run through the sweep engine (so ``--address`` runs it on a Ray cluster, as ``rlcompare sweep`` does):
α ∈ {0.01, 0.05, 0.1, 0.2, 0.5}, γ ∈ {0.9, 0.99, 1}, ε decaying from 1 to ε_end ∈ {0, 0.01, 0.05}, and the
1000-step limit either bootstrapped through (``truncation_as_terminal = false``) or terminal as old Gym's
``done`` made it (``true``), each for Q-Learning and SARSA; everything else is the paper's setting
(:class:`ExperimentConfig`'s defaults). Every configuration runs the sweep's seeds, so SARSA and Q-Learning
meet on common random numbers (paired seeds, the same start states).

A cell of the grid is one (α, γ, ε_end, time limit). In each, on two metrics per seed:

- behaviour return: the mean ε-greedy return over all training episodes (what the agent collects while it
  learns, the paper's "mean cumulative reward");
- greedy return: the mean return of the greedy policy in the last evaluation round (what it learned),

the paired difference SARSA minus Q-Learning over seeds, with a 95% BCa bootstrap interval, and the
two-sided Wilcoxon signed-rank p-value. Each metric's cells are one family: their p-values are adjusted
with Holm's step-down method, and a cell is marked "SARSA better" (or "Q-Learning better") when its adjusted
p-value is below 0.05 and its interval excludes 0 on that side, "not resolved" otherwise. At the default size
of 20 seeds the smallest Wilcoxon p-value is 2 / 2**20; at 10 seeds it would be 2 / 2**10, about 0.002,
more than Holm's first threshold over 90 cells (0.05 / 90): no cell could ever be resolved.

The study directory (``runs/sensitivity``) is the study's, like every study's; it holds the sweep's store in
``sweep/``, a directory claimed for the sweep with its own marker, as the paper's study holds one run
directory per configuration (a directory's marker lists its own files; a subdirectory rlcompare writes is
claimed with its own marker). A re-run resumes: the sweep's store skips finished trials.

- ``tables/cells.{md,csv}``: one row per cell, both metrics;
- ``figures/heatmap-behaviour.png``, ``figures/heatmap-greedy.png``: a panel per (time limit, γ), α x ε_end
  cells coloured by the difference, each annotated with its value and mark;
- ``report.html``: a generated summary first (cells each way, where the conclusion flips), then the rest.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.colors import Normalize
from matplotlib.figure import Figure

from rlcompare.analysis.report import Section, save_figure, write_report, write_table
from rlcompare.analysis.stats import Estimate, holm, paired_difference, rank_test
from rlcompare.experiment import rundir, store
from rlcompare.experiment.config import ConfigError, ExperimentConfig
from rlcompare.experiment.sweep import Sweep, SweepError, Trial, parse_sweep
from rlcompare.experiment.sweep_store import read_manifest, read_table, run_sweep, trial_path
from rlcompare.studies.interface import UI, Report, run_trials
from rlcompare.studies.registry import SensitivityOptions

STUDY = "sensitivity"
SWEEP_DIR = "sweep"
"""The sweep's store, inside the study directory."""
ROOT_SEED = 0
DEFAULT_SEEDS = SensitivityOptions.seeds
DEFAULT_EPISODES = SensitivityOptions.episodes
ALGORITHMS = ("q_learning", "sarsa")
FIXED = {"schedule": "decay"}
"""ε decays linearly from ``epsilon_start`` (1, the default) to ``epsilon_end``; the rest are the defaults
(but a run shorter than the default evaluation interval is evaluated once, at its end)."""
GRID: dict[str, tuple] = {
    "alpha": (0.01, 0.05, 0.1, 0.2, 0.5),
    "gamma": (0.9, 0.99, 1.0),
    "epsilon_end": (0.0, 0.01, 0.05),
    "truncation_as_terminal": (False, True),
}
"""The axes of the grid, in the order of the cells; each cell runs every algorithm of :data:`ALGORITHMS`."""
SYMBOLS = {"alpha": "α", "gamma": "γ", "epsilon_end": "ε_end", "truncation_as_terminal": "time limit"}
PAPER_CELL = {"alpha": 0.05, "gamma": 0.9, "epsilon_end": 0.0, "truncation_as_terminal": True}
"""The paper's setting: ε decaying from 1 to 0 (its end is not given), old Gym's ``done`` at the time limit."""
LEVEL = 0.05
METRICS = {"behaviour": "behaviour return (mean ε-greedy return over training)",
           "greedy": "greedy return (final evaluation round)"}
SARSA_BETTER, Q_BETTER, NOT_RESOLVED = "SARSA better", "Q-Learning better", "not resolved"
SHORT_MARKS = {SARSA_BETTER: "SARSA", Q_BETTER: "Q-Learning", NOT_RESOLVED: "n.r."}
LISTED_CELLS = 12
"""Cells named one by one in the summary; beyond that, the table."""


# --- the grid and its sweep ---------------------------------------------------------------------------------

def parse_grid(specs: Iterable[str]) -> dict[str, tuple]:
    """``KEY=V1,V2,...`` pairs (``--grid alpha=0.1,0.2``) over :data:`GRID`; a key not given keeps its values.
    A :class:`ValueError` names the key and what is allowed."""
    grid = dict(GRID)
    for spec in specs:
        key, sep, text = spec.partition("=")
        key = key.strip()
        if not sep or key not in GRID:
            raise ValueError(f"got {store.quote(spec)}; allowed: KEY=V1,V2,... with KEY one of {', '.join(GRID)}")
        parts = [part.strip() for part in text.split(",") if part.strip()]
        if not parts:
            raise ValueError(f"{key}: empty; allowed: at least one value, e.g. {key}="
                             f"{','.join(_toml(v) for v in GRID[key][:2])}")
        grid[key] = tuple(_grid_value(key, part) for part in parts)
    return grid


def _grid_value(key: str, text: str) -> float | bool:
    if key == "truncation_as_terminal":
        if text.lower() not in ("true", "false"):
            raise ValueError(f"{key}: got {store.quote(text)}; allowed: true or false")
        return text.lower() == "true"
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise ValueError(f"{key}: got {store.quote(text)}; allowed: finite numbers separated by commas")
    return value


def _toml(value) -> str:
    """A TOML literal: JSON's spelling of numbers, booleans, strings and lists is TOML's too."""
    return json.dumps(value)


def sweep_text(grid: dict[str, Sequence], seeds: int, episodes: int, root_seed: int = ROOT_SEED) -> str:
    """The study as a sweep file."""
    fixed = {**FIXED, "episodes": episodes, "eval_every": min(ExperimentConfig.eval_every, episodes)}
    lines = ["[sweep]", f'name = "{STUDY}"', f"root_seed = {root_seed}", f"seeds = {seeds}", "", "[fixed]",
             *(f"{key} = {_toml(value)}" for key, value in fixed.items()), "", "[grid]",
             f"algorithm = {_toml(list(ALGORITHMS))}",
             *(f"{key} = {_toml(list(values))}" for key, values in grid.items())]
    return "\n".join(lines) + "\n"


def plan(grid: dict[str, Sequence] | None = None, seeds: int = DEFAULT_SEEDS, episodes: int = DEFAULT_EPISODES
         ) -> tuple[Sweep, str]:
    """The study's sweep and its file, validated: :class:`SweepError` lists every problem, by key."""
    grid = dict(GRID if grid is None else grid)
    problems = [f"grid.{store.cut(str(key), 80)}: unknown key; allowed: {', '.join(GRID)}"
                for key in grid if key not in GRID]
    problems += [f"grid.{key}: empty; allowed: at least one value" for key in GRID if key in grid and not grid[key]]
    if problems:
        raise SweepError("sensitivity grid", problems)
    text = sweep_text({key: grid.get(key, GRID[key]) for key in GRID}, seeds, episodes)
    return parse_sweep(text, "sensitivity grid"), text


def run_sensitivity(out: Path, sweep: Sweep, text: str, backend, progress: Callable[[Trial], None] | None = None,
                    *, force: bool = False) -> tuple[int, int]:
    """Claim ``out`` as the study's directory and run the trials of ``sweep`` its store lacks on ``backend``.
    Returns (trials already finished, trials run now)."""
    with store.output_directory(Path(out), store.Owner("study", STUDY), force=force):
        return run_sweep(sweep, text, Path(out) / SWEEP_DIR, backend, progress)


def plan_of(options: SensitivityOptions) -> tuple[Sweep, str]:
    """The study's sweep and its file from its options; a bad grid is a :class:`ConfigError` naming ``grid``."""
    try:
        return plan(parse_grid(options.grid), options.seeds, options.episodes)
    except SweepError as error:
        raise ConfigError("grid", options.grid, "; ".join(error.problems)) from None
    except ValueError as error:
        raise ConfigError("grid", options.grid, str(error)) from None


def run(out: Path, options: SensitivityOptions, ui: UI, *, study: str = STUDY, force: bool = False) -> None:
    """The study's trials that ``out`` lacks, on this machine's cores or on Ray at ``options.address``."""
    sweep, text = plan_of(options)
    started = time.perf_counter()
    where = f"Ray at {options.address}" if options.address else "this machine"
    finished, ran = run_trials(
        sweep, "local" if options.address is None else "ray", options.workers, options.address,
        f"of {options.episodes} episodes on {where}; study {out}", ui,
        lambda executor, progress: run_sensitivity(out, sweep, text, executor, progress, force=force))
    ui.say(f"{ran} trials run, {finished} already finished: {time.perf_counter() - started:.1f} s")


# --- cells, differences and marks ---------------------------------------------------------------------------

def seed_returns(root: Path) -> pd.DataFrame:
    """One row per finished trial of a sweep's store: its configuration's hash, algorithm and values of the
    grid's keys, its seed, ``behaviour`` (the mean return over every training episode) and ``greedy`` (the mean
    return of the last evaluation round), as :func:`rlcompare.analysis.tables.per_seed_metrics` defines them.
    Read as two Parquet datasets: seconds for thousands of trials, where loading each run takes a minute."""
    columns = ["config", "algorithm", *GRID, "seed", "behaviour", "greedy"]
    episodes = read_table(root, rundir.EPISODES_FILE)
    if episodes.empty:
        return pd.DataFrame(columns=columns)
    behaviour = episodes.groupby(["config", "seed"])["return"].mean().rename("behaviour")
    greedy = _last_round_means(read_table(root, rundir.EVALUATIONS_FILE)).rename("greedy")
    frame = pd.concat([behaviour, greedy], axis=1).reset_index()
    first_seed = frame.groupby("config")["seed"].first()
    values = pd.DataFrame([{"config": hash_, **_cell_config(trial_path(root, hash_, seed))}
                           for hash_, seed in first_seed.items()])
    return frame.merge(values, on="config")[columns]


def _last_round_means(evaluations: pd.DataFrame) -> pd.Series:
    """The mean return of each trial's last evaluation round, by (config, seed); NaN-free, empty if none."""
    if evaluations.empty:
        return pd.Series(dtype=np.float64)
    last = evaluations["round"] == evaluations.groupby("config")["round"].transform("max")
    return evaluations[last].groupby(["config", "seed"])["return"].mean()


def _cell_config(trial_dir: Path) -> dict:
    """A trial's algorithm and values of the grid's keys, from its ``config.json``."""
    config = store.read_json(trial_dir / rundir.CONFIG_FILE)
    return {key: config[key] for key in ("algorithm", *GRID)}


def paired_values(rows: pd.DataFrame, metric: str) -> tuple[np.ndarray, np.ndarray]:
    """A cell's SARSA and Q-Learning values of ``metric`` on the seeds both finished, in seed order."""
    table = rows.pivot(index="seed", columns="algorithm", values=metric).sort_index()
    table = table.reindex(columns=list(ALGORITHMS)).dropna(subset=list(ALGORITHMS))
    return table["sarsa"].to_numpy(dtype=np.float64), table["q_learning"].to_numpy(dtype=np.float64)


def mark(difference: Estimate, adjusted_p: float, level: float = LEVEL) -> str:
    """SARSA better / Q-Learning better when the adjusted p-value is below ``level`` and the interval of
    SARSA minus Q-Learning excludes 0 on that side; not resolved otherwise (NaN bounds included)."""
    if not adjusted_p < level:
        return NOT_RESOLVED
    if difference.low > 0:
        return SARSA_BETTER
    if difference.high < 0:
        return Q_BETTER
    return NOT_RESOLVED


def mark_family(differences: Sequence[Estimate], p_values: Sequence[float], level: float = LEVEL
                ) -> tuple[np.ndarray, list[str]]:
    """Holm-adjusted p-values over the family and each member's mark."""
    adjusted = holm(p_values)
    return adjusted, [mark(d, p, level) for d, p in zip(differences, adjusted, strict=True)]


def compare_cells(seeds: pd.DataFrame) -> pd.DataFrame:
    """One row per cell (from :func:`seed_returns`'s rows) with both algorithms on at least one common seed:
    the grid's values, the seeds compared and, per metric, the means, SARSA minus Q-Learning with its 95%
    interval, the Wilcoxon and Holm p-values and the mark."""
    rows = []
    for cell, group in seeds.groupby(list(GRID), sort=True):
        row: dict[str, object] = dict(zip(GRID, cell, strict=True))
        for metric in METRICS:
            a, b = paired_values(group, metric)
            if not len(a):
                break
            difference = paired_difference(a, b)
            row |= {"seeds": len(a), f"{metric}_sarsa": float(np.mean(a)), f"{metric}_q_learning": float(np.mean(b)),
                    f"{metric}_difference": difference.value, f"{metric}_low": difference.low,
                    f"{metric}_high": difference.high,
                    f"{metric}_p": rank_test(a, b) if np.isfinite(a - b).all() else np.nan}
        else:
            rows.append(row)
    cells = pd.DataFrame(rows, columns=[*GRID, "seeds", *(f"{m}_{part}" for m in METRICS for part in (
        "sarsa", "q_learning", "difference", "low", "high", "p"))])
    for metric in METRICS:
        differences = [Estimate(*values) for values in cells[[f"{metric}_{part}" for part in (
            "difference", "low", "high")]].itertuples(index=False)]
        cells[f"{metric}_holm"], cells[f"{metric}_mark"] = mark_family(differences, cells[f"{metric}_p"].tolist())
    return cells.astype({"truncation_as_terminal": bool, "seeds": int})


def missing(seeds: pd.DataFrame, manifest: dict) -> list[str]:
    """What the report lacks: unfinished trials, and cells with one algorithm alone."""
    problems = []
    unfinished = len(manifest["trials"]) - len(seeds)
    if unfinished:
        problems.append(f"{unfinished} of {len(manifest['trials'])} trials not finished; run 'rlcompare reproduce "
                        f"{STUDY}' again with the same options to finish them")
    for cell, group in seeds.groupby(list(GRID), sort=True):
        lacking = [a for a in ALGORITHMS if a not in set(group["algorithm"])]
        if lacking:
            problems.append(f"cell {setting(dict(zip(GRID, cell, strict=True)))}: no finished trial of "
                            f"{', '.join(lacking)}")
    return problems


# --- words --------------------------------------------------------------------------------------------------

def _value(key: str, value) -> str:
    if key == "truncation_as_terminal":
        return "terminal" if value else "bootstrapped"
    return f"{value:g}"


def setting(row: dict, keys: Iterable[str] = GRID) -> str:
    """``α = 0.5, γ = 1, ε_end = 0, time limit terminal``."""
    return ", ".join(f"time limit {_value(k, row[k])}" if k == "truncation_as_terminal"
                     else f"{SYMBOLS[k]} = {_value(k, row[k])}" for k in keys)


def _counts(marks: pd.Series) -> str:
    counts = marks.value_counts()
    return (f"SARSA better in {counts.get(SARSA_BETTER, 0)} of {len(marks)} cells, Q-Learning better in "
            f"{counts.get(Q_BETTER, 0)}, not resolved in {counts.get(NOT_RESOLVED, 0)}")


def _where(chosen: pd.DataFrame, cells: pd.DataFrame) -> str:
    """Which values of each key the chosen cells fall on, out of the cells with that value."""
    parts = []
    for key in GRID:
        if cells[key].nunique() < 2:
            continue
        counts = [(value, int((chosen[key] == value).sum()), int((cells[key] == value).sum()))
                  for value in sorted(cells[key].unique())]
        parts.append(f"{SYMBOLS[key]}: " + ", ".join(f"{_value(key, v)} {n} of {total}" for v, n, total in counts))
    return "; ".join(parts)


def _spread(chosen: pd.DataFrame, cells: pd.DataFrame) -> str:
    where = _where(chosen, cells)
    return f", by setting: {where}" if where else ""


def metric_summary(cells: pd.DataFrame, metric: str) -> list[str]:
    """Cells each way on ``metric``, where the conclusion flips (Q-Learning better) and where it is not
    resolved."""
    marks = cells[f"{metric}_mark"]
    lines = [f"{METRICS[metric].capitalize()}: {_counts(marks)}."]
    flips, unresolved = cells[marks == Q_BETTER], cells[marks == NOT_RESOLVED]
    if not flips.empty:
        named = "; ".join(setting(row) for row in flips.head(LISTED_CELLS).to_dict("records"))
        more = f"; and {len(flips) - LISTED_CELLS} more (see the table)" if len(flips) > LISTED_CELLS else ""
        lines.append(f"The conclusion flips (Q-Learning better) in {len(flips)} cells{_spread(flips, cells)}. "
                     f"They are: {named}{more}.")
    if not unresolved.empty:
        lines.append(f"Not resolved in {len(unresolved)} cells{_spread(unresolved, cells)}.")
    if not (marks == Q_BETTER).any():
        lines.append("The conclusion never flips on this metric: no cell has Q-Learning better.")
    return lines


def paper_cell_line(cells: pd.DataFrame) -> str | None:
    """The paper's own setting, where the grid holds it."""
    at = np.logical_and.reduce([np.isclose(cells[k].astype(float), float(v)) for k, v in PAPER_CELL.items()])
    if not at.any():
        return None
    row = cells[at].iloc[0]
    told = "; ".join(f"{metric} {_difference(row, metric)}: {row[f'{metric}_mark']}" for metric in METRICS)
    return f"The paper's setting ({setting(row)}): SARSA - Q-Learning, {told}."


def summary(cells: pd.DataFrame) -> list[str]:
    """The report's opening: the family, then each metric's cells, flips and the paper's cell."""
    if cells.empty:
        return ["No cell has both SARSA and Q-Learning finished yet."]
    lines = [f"{len(cells)} cells (α x γ x ε_end x time limit), SARSA against Q-Learning on {_seeds(cells)} paired "
             f"seeds each. Marks: Holm's correction over the {len(cells)} cells of each metric (each metric is "
             f"one family of {len(cells)} tests), family-wise level {LEVEL:g}, and the 95% interval of the "
             "difference on the same side of 0."]
    for metric in METRICS:
        lines += metric_summary(cells, metric)
    paper = paper_cell_line(cells)
    return [*lines, paper] if paper else lines


def _seeds(cells: pd.DataFrame) -> str:
    low, high = int(cells["seeds"].min()), int(cells["seeds"].max())
    return str(low) if low == high else f"{low} to {high}"


def _difference(row, metric: str) -> str:
    return Estimate(row[f"{metric}_difference"], row[f"{metric}_low"], row[f"{metric}_high"]).format(1)


def display_table(cells: pd.DataFrame) -> pd.DataFrame:
    """The cells as the report and ``tables/cells.{md,csv}`` show them."""
    table = pd.DataFrame({SYMBOLS[key]: [_value(key, v) for v in cells[key]] for key in GRID})
    table["seeds"] = cells["seeds"].to_numpy()
    for metric in METRICS:
        table[f"{metric}: SARSA"] = cells[f"{metric}_sarsa"].round(1).to_numpy()
        table[f"{metric}: Q-Learning"] = cells[f"{metric}_q_learning"].round(1).to_numpy()
        table[f"{metric}: SARSA - Q-Learning [95% CI]"] = [_difference(row, metric) for _, row in cells.iterrows()]
        table[f"{metric}: Wilcoxon p"] = cells[f"{metric}_p"].to_numpy()
        table[f"{metric}: Holm p"] = cells[f"{metric}_holm"].to_numpy()
        table[f"{metric}: mark"] = cells[f"{metric}_mark"].to_numpy()
    return table


# --- the heatmap --------------------------------------------------------------------------------------------

def heatmap_figure(cells: pd.DataFrame, metric: str) -> Figure:
    """A panel per (time limit, γ); in each, α x ε_end cells coloured by SARSA minus Q-Learning (diverging,
    centred on 0: blue where SARSA returns more) and annotated with the difference and the mark."""
    rows, columns = sorted(cells["truncation_as_terminal"].unique()), sorted(cells["gamma"].unique())
    alphas, ends = sorted(cells["alpha"].unique()), sorted(cells["epsilon_end"].unique())
    figure = Figure(figsize=(1.0 + 1.1 * len(alphas) * len(columns), 0.9 + 0.75 * len(ends) * len(rows) + 0.6),
                    layout="constrained")
    axes = figure.subplots(len(rows), len(columns), squeeze=False)
    values = cells[f"{metric}_difference"].to_numpy(dtype=np.float64)
    largest = float(np.nanmax(np.abs(values))) if np.isfinite(values).any() else 1.0
    norm = Normalize(-largest or -1.0, largest or 1.0)
    image = None
    for i, truncation in enumerate(rows):
        for j, gamma in enumerate(columns):
            panel = cells[(cells["truncation_as_terminal"] == truncation) & (cells["gamma"] == gamma)]
            image = _heatmap_panel(axes[i, j], panel, metric, alphas, ends, norm)
            axes[i, j].set_title(f"γ = {gamma:g}, time limit {_value('truncation_as_terminal', truncation)}",
                                 fontsize="medium")
    figure.colorbar(image, ax=axes, shrink=0.8, label="SARSA - Q-Learning (return)")
    figure.suptitle(f"{METRICS[metric].capitalize()}: SARSA - Q-Learning, mean over {_seeds(cells)} paired seeds; "
                    f"marks with Holm over {len(cells)} cells at {LEVEL:g}")
    return figure


def _heatmap_panel(ax, panel: pd.DataFrame, metric: str, alphas: list, ends: list, norm: Normalize):
    grid = np.full((len(ends), len(alphas)), np.nan)
    marks = np.full(grid.shape, "", dtype=object)
    for row in panel.to_dict("records"):
        at = (ends.index(row["epsilon_end"]), alphas.index(row["alpha"]))
        grid[at], marks[at] = row[f"{metric}_difference"], row[f"{metric}_mark"]
    image = ax.imshow(grid, cmap="RdBu", norm=norm, origin="lower", aspect="auto")
    for (y, x), value in np.ndenumerate(grid):
        text = "n/a" if np.isnan(value) else f"{value:+.1f}\n{SHORT_MARKS.get(marks[y, x], '')}"
        strong = np.isfinite(value) and abs(norm(value) - 0.5) > 0.3
        ax.text(x, y, text, ha="center", va="center", fontsize="x-small", color="white" if strong else "black",
                fontweight="bold" if marks[y, x] in (SARSA_BETTER, Q_BETTER) else "normal")
    ax.set_xticks(range(len(alphas)), [f"{a:g}" for a in alphas])
    ax.set_yticks(range(len(ends)), [f"{e:g}" for e in ends])
    ax.set_xlabel("α")
    ax.set_ylabel("ε_end")
    return image


# --- the report ---------------------------------------------------------------------------------------------

def report(out: Path, ui: UI | None = None, *, runs: None = None, videos: bool = True) -> Report:
    """Tables, heatmaps and ``report.html`` of the study in ``out``, from its sweep's store alone: the page, the
    summary it opens with, and what is missing (it draws no videos)."""
    with store.rewriting(Path(out), "study") as owner:
        if owner.name != STUDY:
            raise store.StoreError(f"{out}: holds {owner}; allowed: the {STUDY} study's directory")
        return _build_report(Path(out))


def _build_report(out: Path) -> Report:
    root = out / SWEEP_DIR
    manifest = read_manifest(root)
    seeds = seed_returns(root)
    cells = compare_cells(seeds)
    problems = missing(seeds, manifest)
    lines = summary(cells)
    sections = [Section("Summary", lines)]
    if not cells.empty:
        table = display_table(cells)
        write_table(table, out / "tables", "cells")
        config = store.read_json(trial_path(root, seeds["config"].iloc[0], seeds["seed"].iloc[0]) / rundir.CONFIG_FILE)
        sections += [
            Section("The grid", method_paragraphs(config, cells, len(seeds), manifest)),
            *(Section(METRICS[metric].capitalize(), figures=[(
                save_figure(heatmap_figure(cells, metric), out / "figures" / f"heatmap-{metric}.png", dpi=90),
                f"SARSA - Q-Learning on the {METRICS[metric]}; blue: SARSA returns more")]) for metric in METRICS),
            Section("Cells", tables=[("SARSA against Q-Learning, cell by cell", table)]),
        ]
    path = write_report(out / "report.html", "Sensitivity: SARSA against Q-Learning across settings", sections,
                        problems)
    return Report(path, lines, problems)


def method_paragraphs(config: dict, cells: pd.DataFrame, finished: int, manifest: dict) -> list[str]:
    """What ran (``config``: one trial's ``config.json``) and how the cells are marked."""
    grid = "; ".join(f"{SYMBOLS[k]} ∈ {{{', '.join(_value(k, v) for v in sorted(cells[k].unique()))}}}"
                     for k in GRID)
    return [
        f"{config['env']}, {config['bins']} bins per dimension, a {config['max_steps']}-step limit, "
        f"{config['episodes']} episodes per seed, ε decaying linearly from {config['epsilon_start']:g} to ε_end over "
        f"the first {config['decay_fraction']:.0%} of them; greedy evaluation every {config['eval_every']} episodes "
        f"({config['eval_episodes']} episodes each). Grid: {grid}, each for Q-Learning and SARSA. Everything else "
        "is the paper's setting. Time limit bootstrapped: the update at the cut bootstraps from the next state's "
        "value; terminal: it does not, as old Gym's done made the paper's agents do.",
        f"{finished} of {len(manifest['trials'])} trials finished (root seed {manifest['root_seed']}; every "
        f"configuration runs the same seeds, so SARSA and Q-Learning meet on the same start states). The sweep's "
        f"store is {SWEEP_DIR}/; 'rlcompare report' on it gives its own sweep report.",
        "Per cell: the mean over seeds of SARSA minus Q-Learning on paired seeds, its 95% BCa bootstrap interval, "
        f"and the two-sided Wilcoxon signed-rank p-value. Each metric's {len(cells)} cells form one family: "
        "p-values adjusted by Holm's step-down method; a cell is marked SARSA better (Q-Learning better) when its "
        f"adjusted p-value is below {LEVEL:g} and its interval lies above (below) 0, and not resolved otherwise.",
    ]
