"""Does the paper's conclusion, SARSA beats Q-Learning on Mountain Car, survive other settings?

A grid run through the sweep engine (so ``--address`` runs it on a Ray cluster, as ``rlcompare sweep`` does),
in two blocks, each configuration for Q-Learning and SARSA; everything else is the paper's setting
(:class:`ExperimentConfig`'s defaults):

- the cross: α ∈ {0.01, 0.05, 0.1, 0.2, 0.5}, γ ∈ {0.9, 0.99, 1}, ε decaying from 1 to ε_end ∈ {0, 0.01, 0.05},
  and the 1000-step limit either bootstrapped through (``truncation_as_terminal = false``) or terminal as old
  Gym's ``done`` made it (``true``);
- the schedule block: ε's schedule x γ at the paper's α (0.05) and time limit (terminal): ε constant at
  ε ∈ {0.1, 0.25, 0.5} (the paper's constant runs: 0.5) or decaying from 1 to each ε_end of the cross, with each
  γ of the cross. Its decaying cells are the cross's own (the same configurations, trained once); the constant
  ones are its own, as [[include]] tables of the sweep file. Crossing the constant schedule with every axis
  would double the study; the block adds a tenth.

Every configuration runs the sweep's seeds, so SARSA and Q-Learning meet on common random numbers (paired
seeds, the same start states).

A cell of the grid is one (schedule, α, γ, ε_end, time limit), where a constant cell's ``epsilon_end`` is its
constant ε (the ε its training ends with). In each, on two metrics per seed:

- behaviour return: the mean ε-greedy return over all training episodes (what the agent collects while it
  learns, the paper's "mean cumulative reward");
- greedy return: the mean return of the greedy policy in the last evaluation round (what it learned),

the paired difference SARSA minus Q-Learning over seeds, with a 95% BCa bootstrap interval, and the
two-sided Wilcoxon signed-rank p-value. Each metric's cells, both blocks together, are one family: their
p-values are adjusted with Holm's step-down method, and a cell is marked "SARSA better" (or "Q-Learning
better") when its adjusted p-value is below 0.05 and its interval excludes 0 on that side, "not resolved"
otherwise. At the default size of 20 seeds the smallest Wilcoxon p-value is 2 / 2**20; at 10 seeds it would be
2 / 2**10, about 0.002, more than Holm's first threshold over 99 cells (0.05 / 99): no cell could ever be
resolved.

The study directory (``runs/sensitivity``) is the study's, like every study's; it holds the sweep's store in
``sweep/``, a directory claimed for the sweep with its own marker, as the paper's study holds one run
directory per configuration (a directory's marker lists its own files; a subdirectory rlcompare writes is
claimed with its own marker). A re-run resumes: the sweep's store skips finished trials (a study directory
run before the schedule block existed trains the block's constant configurations alone). The report, drawn by
:mod:`rlcompare.studies.sensitivity_report`, writes:

- ``tables/cells.{md,csv}``: one row per cell, both metrics;
- ``figures/heatmap-behaviour.png``, ``figures/heatmap-greedy.png``: the cross, a panel per (time limit, γ),
  α x ε_end cells coloured by the difference, each annotated with its value and mark;
- ``figures/schedule-behaviour.png``, ``figures/schedule-greedy.png``: the schedule block, ε schedule x γ
  cells, coloured and annotated the same way;
- ``report.html``: a generated summary first (cells each way; every region where the conclusion flips, with
  the difference and interval at each of its cells; over which axes it never flips), then the rest.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.dataset as ds

from rlcompare.analysis.compare import compare_paired, comparison_label
from rlcompare.analysis.metrics import returns_from_tables
from rlcompare.analysis.stats import Estimate, holm
from rlcompare.experiment import rundir, store
from rlcompare.experiment.config import ConfigError, ExperimentConfig
from rlcompare.experiment.sweep import Sweep, SweepError, Trial, parse_sweep
from rlcompare.experiment.sweep_store import (
    TRIALS_DIR,
    engine_of,
    is_finished,
    read_manifest,
    run_sweep,
    trial_path,
)
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
"""The cross: ε decays linearly from ``epsilon_start`` (1, the default) to ``epsilon_end``; the rest are the
defaults (but a run shorter than the default evaluation interval is evaluated once, at its end)."""
GRID: dict[str, tuple] = {
    "alpha": (0.01, 0.05, 0.1, 0.2, 0.5),
    "gamma": (0.9, 0.99, 1.0),
    "epsilon_end": (0.0, 0.01, 0.05),
    "truncation_as_terminal": (False, True),
}
"""The axes of the cross, in the order of the cells; each cell runs every algorithm of :data:`ALGORITHMS`."""
CONSTANT_EPSILONS = (0.1, 0.25, 0.5)
"""The constant ε values of the schedule block (the paper's constant runs: 0.5)."""
AXES: dict[str, tuple] = {**GRID, "epsilon": CONSTANT_EPSILONS}
"""Every axis ``--grid`` sets: the cross's and the schedule block's constant ε."""
SCHEDULE_BLOCK = {"alpha": 0.05, "truncation_as_terminal": True}
"""Where the schedule block sits: the paper's α and time limit. Its axes: the schedule (constant at each
``epsilon``, decaying to each ``epsilon_end``) x ``gamma``."""
CELL_KEYS = ("schedule", *GRID)
"""What tells the cells apart; a constant cell's ``epsilon_end`` is its constant ε."""
SYMBOLS = {"alpha": "α", "gamma": "γ", "epsilon_end": "ε_end", "truncation_as_terminal": "time limit",
           "epsilon": "constant ε", "schedule": "ε schedule"}
PAPER_CELL = {"schedule": "decay", "alpha": 0.05, "gamma": 0.9, "epsilon_end": 0.0, "truncation_as_terminal": True}
"""The paper's setting: ε decaying from 1 to 0 (its end is not given), old Gym's ``done`` at the time limit."""
PAPER_CONSTANT_CELL = {**PAPER_CELL, "schedule": "constant", "epsilon_end": 0.5}
"""The paper's constant runs: ε = 0.5 throughout, the rest as :data:`PAPER_CELL`."""
LEVEL = 0.05
METRICS = {"behaviour": "behaviour return (mean ε-greedy return over training)",
           "greedy": "greedy return (final evaluation round)"}
SARSA_BETTER, Q_BETTER, NOT_RESOLVED = "SARSA better", "Q-Learning better", "not resolved"


# --- the grid and its sweep ---------------------------------------------------------------------------------

def parse_grid(specs: Iterable[str]) -> dict[str, tuple]:
    """``KEY=V1,V2,...`` pairs (``--grid alpha=0.1,0.2``) over :data:`AXES`; a key not given keeps its values.
    A :class:`ValueError` names the key and what is allowed."""
    grid = dict(AXES)
    for spec in specs:
        key, sep, text = spec.partition("=")
        key = key.strip()
        if not sep or key not in AXES:
            raise ValueError(f"got {store.quote(spec)}; allowed: KEY=V1,V2,... with KEY one of {', '.join(AXES)}")
        parts = [part.strip() for part in text.split(",") if part.strip()]
        if not parts:
            raise ValueError(f"{key}: empty; allowed: at least one value, e.g. {key}="
                             f"{','.join(_toml(v) for v in AXES[key][:2])}")
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


def schedule_configs(grid: dict[str, Sequence]) -> list[dict]:
    """The schedule block's configurations the cross lacks, as the sweep's [[include]] tables: every constant
    ε with every γ, and the decaying ones too where the cross does not hold the block's α and time limit."""
    at = dict(SCHEDULE_BLOCK)
    crossed = all(value in grid[key] for key, value in at.items())
    tables = []
    for gamma in grid["gamma"]:
        exploration = [{"schedule": "constant", "epsilon": epsilon} for epsilon in grid["epsilon"]]
        if not crossed:
            exploration += [{"schedule": "decay", "epsilon_end": end} for end in grid["epsilon_end"]]
        tables += [{"algorithm": algorithm, **explore, "alpha": at["alpha"], "gamma": gamma,
                    "truncation_as_terminal": at["truncation_as_terminal"]}
                   for explore in exploration for algorithm in ALGORITHMS]
    return tables


def sweep_text(grid: dict[str, Sequence], seeds: int, episodes: int, root_seed: int = ROOT_SEED) -> str:
    """The study as a sweep file: the cross as its [grid], the schedule block's own configurations as
    [[include]] tables (none where ``grid`` has no ``epsilon``)."""
    fixed = {**FIXED, "episodes": episodes, "eval_every": min(ExperimentConfig.eval_every, episodes)}
    lines = ["[sweep]", f'name = "{STUDY}"', f"root_seed = {root_seed}", f"seeds = {seeds}", "", "[fixed]",
             *(f"{key} = {_toml(value)}" for key, value in fixed.items()), "", "[grid]",
             f"algorithm = {_toml(list(ALGORITHMS))}",
             *(f"{key} = {_toml(list(grid[key]))}" for key in GRID)]
    if "epsilon" in grid:
        for table in schedule_configs(grid):
            lines += ["", "[[include]]", *(f"{key} = {_toml(value)}" for key, value in table.items())]
    return "\n".join(lines) + "\n"


def plan(grid: dict[str, Sequence] | None = None, seeds: int = DEFAULT_SEEDS, episodes: int = DEFAULT_EPISODES
         ) -> tuple[Sweep, str]:
    """The study's sweep and its file, validated: :class:`SweepError` lists every problem, by key."""
    grid = dict(AXES if grid is None else grid)
    problems = [f"grid.{store.cut(str(key), 80)}: unknown key; allowed: {', '.join(AXES)}"
                for key in grid if key not in AXES]
    problems += [f"grid.{key}: empty; allowed: at least one value" for key in AXES if key in grid and not grid[key]]
    if problems:
        raise SweepError("sensitivity grid", problems)
    grid = {key: tuple(grid.get(key, AXES[key])) for key in AXES}
    problems = _epsilon_problems(grid["epsilon"])
    try:  # the cross first, so that a bad value of its axes is named once, at its place in [grid]
        parse_sweep(sweep_text({key: grid[key] for key in GRID}, seeds, episodes), "sensitivity grid")
    except SweepError as error:
        problems = error.problems + problems
    if problems:
        raise SweepError("sensitivity grid", problems)
    text = sweep_text(grid, seeds, episodes)
    return parse_sweep(text, "sensitivity grid"), text


def _epsilon_problems(values: Sequence) -> list[str]:
    """The constant ε values' problems, named at ``grid.epsilon[i]`` as the sweep names the cross's."""
    problems = []
    for i, value in enumerate(values):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 <= value <= 1:
            problems.append(f"grid.epsilon[{i}]: got {store.quote(value)}; allowed: a number in [0, 1]")
        elif value in values[:i]:
            problems.append(f"grid.epsilon[{i}]: the same configuration as grid.epsilon[{values.index(value)}]; "
                            "allowed: each configuration once")
    return problems


def cell_count(grid: dict[str, Sequence] | None = None) -> int:
    """How many cells the study's grid has: the cross's, and the schedule block's own."""
    grid = {**AXES, **(grid or {})}
    own = len(schedule_configs(grid)) // len(ALGORITHMS)
    return math.prod(len(grid[key]) for key in GRID) + own


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
    """One row per finished trial of a sweep's store: its configuration's hash, algorithm and cell
    (:data:`CELL_KEYS`), its seed, ``behaviour`` (the mean return over every training episode) and ``greedy``
    (the mean return of the last evaluation round), as :mod:`rlcompare.analysis.metrics` defines them for every
    study. Read as two Parquet datasets of the columns those need, over the trials whose files belong together
    (checked once for both): seconds for thousands of trials, where loading each run takes a minute."""
    columns = ["config", "algorithm", *CELL_KEYS, "seed", "behaviour", "greedy"]
    manifest = read_manifest(root)
    engine = engine_of(manifest)
    trials = [(entry["config_hash"], entry["seed"]) for entry in manifest["trials"]
              if is_finished(trial_path(root, entry["config_hash"], entry["seed"]), engine=engine)]
    if not trials:
        return pd.DataFrame(columns=columns)
    episodes, evaluations = (_dataset(root, trials, name, wanted) for name, wanted in (
        (rundir.EPISODES_FILE, ["seed", "return"]), (rundir.EVALUATIONS_FILE, ["seed", "round", "return"])))
    frame = returns_from_tables(episodes, evaluations, ["config", "seed"]).rename(
        columns={"behaviour_return": "behaviour", "greedy_return": "greedy"})
    first_seed = frame.groupby("config")["seed"].first()
    values = pd.DataFrame([{"config": hash_, **_cell_config(trial_path(root, hash_, seed))}
                           for hash_, seed in first_seed.items()])
    return frame.merge(values, on="config")[columns]


def _dataset(root: Path, trials: list[tuple[str, int]], name: str, columns: list[str]) -> pd.DataFrame:
    """``name`` of every trial as one frame of ``columns``, with ``config`` (the hash) from its path."""
    partitioning = ds.partitioning(pa.schema([("config", pa.string()), ("trial", pa.int64())]), flavor="hive")
    dataset = ds.dataset([str(trial_path(root, hash_, seed) / name) for hash_, seed in trials], format="parquet",
                         partitioning=partitioning, partition_base_dir=str(Path(root) / TRIALS_DIR))
    return dataset.to_table(columns=["config", *columns]).to_pandas()


def _cell_config(trial_dir: Path) -> dict:
    """A trial's algorithm and cell, from its ``config.json``: a constant schedule's ε as its ``epsilon_end``."""
    config = store.read_json(trial_dir / rundir.CONFIG_FILE)
    cell = {key: config[key] for key in ("algorithm", *CELL_KEYS)}
    if config["schedule"] == "constant":
        cell["epsilon_end"] = config["epsilon"]
    return cell


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
    its :data:`CELL_KEYS`, the seeds compared and, per metric, the means, SARSA minus Q-Learning with its 95%
    interval, the Wilcoxon and Holm p-values and the mark."""
    rows = []
    for cell, group in seeds.groupby(list(CELL_KEYS), sort=True):
        row: dict[str, object] = dict(zip(CELL_KEYS, cell, strict=True))
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
    cells = pd.DataFrame(rows, columns=[*CELL_KEYS, "seeds", *(f"{m}_{part}" for m in METRICS for part in (
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
