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
claimed with its own marker). A re-run resumes: the sweep's store skips finished trials. The report, drawn by
:mod:`rlcompare.studies.sensitivity_report`, writes:

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

from rlcompare.analysis.compare import compare_paired, comparison_label
from rlcompare.analysis.metrics import returns_from_tables
from rlcompare.analysis.stats import Estimate, holm
from rlcompare.experiment import rundir, store
from rlcompare.experiment.config import ConfigError, ExperimentConfig
from rlcompare.experiment.sweep import Sweep, SweepError, Trial, parse_sweep
from rlcompare.experiment.sweep_store import read_table, run_sweep, trial_path
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
    return of the last evaluation round), as :mod:`rlcompare.analysis.metrics` defines them for every study.
    Read as two Parquet datasets: seconds for thousands of trials, where loading each run takes a minute."""
    columns = ["config", "algorithm", *GRID, "seed", "behaviour", "greedy"]
    episodes = read_table(root, rundir.EPISODES_FILE)
    if episodes.empty:
        return pd.DataFrame(columns=columns)
    frame = returns_from_tables(episodes, read_table(root, rundir.EVALUATIONS_FILE), ["config", "seed"]).rename(
        columns={"behaviour_return": "behaviour", "greedy_return": "greedy"})
    first_seed = frame.groupby("config")["seed"].first()
    values = pd.DataFrame([{"config": hash_, **_cell_config(trial_path(root, hash_, seed))}
                           for hash_, seed in first_seed.items()])
    return frame.merge(values, on="config")[columns]


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
    SARSA minus Q-Learning excludes 0 on that side; not resolved otherwise (NaN bounds included): the one
    vocabulary of :func:`~rlcompare.analysis.compare.comparison_label`."""
    return comparison_label(difference, adjusted_p, ("SARSA", "Q-Learning"), level=level)


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
            paired = compare_paired(a, b, improvement=False)
            difference = paired.difference
            row |= {"seeds": paired.seeds, f"{metric}_sarsa": paired.a_mean, f"{metric}_q_learning": paired.b_mean,
                    f"{metric}_difference": difference.value, f"{metric}_low": difference.low,
                    f"{metric}_high": difference.high, f"{metric}_p": paired.p_value}
        else:
            rows.append(row)
    cells = pd.DataFrame(rows, columns=[*GRID, "seeds", *(f"{m}_{part}" for m in METRICS for part in (
        "sarsa", "q_learning", "difference", "low", "high", "p"))])
    for metric in METRICS:
        differences = [Estimate(*values) for values in cells[[f"{metric}_{part}" for part in (
            "difference", "low", "high")]].itertuples(index=False)]
        cells[f"{metric}_holm"], cells[f"{metric}_mark"] = mark_family(differences, cells[f"{metric}_p"].tolist())
    return cells.astype({"truncation_as_terminal": bool, "seeds": int})


# --- the report ---------------------------------------------------------------------------------------------

def report(out: Path, ui: UI | None = None, *, runs: None = None, videos: bool = True) -> Report:
    """Tables, heatmaps and ``report.html`` of the study in ``out``, from its sweep's store alone: the page, the
    summary it opens with, and what is missing (it draws no videos)."""
    from rlcompare.studies.sensitivity_report import build_report

    with store.rewriting(Path(out), "study") as owner:
        if owner.name != STUDY:
            raise store.StoreError(f"{out}: holds {owner}; allowed: the {STUDY} study's directory")
        return build_report(Path(out))
