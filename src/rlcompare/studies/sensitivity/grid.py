"""The grid of the sensitivity study (:mod:`rlcompare.studies.sensitivity.study`): its axes and cells, the sweep
file that runs it, and each cell's SARSA-minus-Q-Learning comparison over paired seeds, one Holm family per metric."""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.dataset as ds

from rlcompare.experiment import rundir, store
from rlcompare.experiment.sweep import Sweep, SweepError, parse_sweep
from rlcompare.experiment.sweep_store import (
    TRIALS_DIR,
    engine_of,
    is_finished,
    read_manifest,
    trial_path,
)
from rlcompare.formatting import cut, quote
from rlcompare.stats.compare import compare_paired, comparison_label
from rlcompare.stats.intervals import Estimate
from rlcompare.stats.metrics import returns_from_tables
from rlcompare.stats.significance import holm
from rlcompare.studies.registry import SensitivityOptions
from rlcompare.tabular.config import ExperimentConfig

STUDY = "sensitivity"
SWEEP_DIR = "sweep"
"""The sweep's store, inside the study directory."""
ROOT_SEED = 0
DEFAULT_SEEDS = SensitivityOptions.seeds
DEFAULT_EPISODES = SensitivityOptions.episodes
ALGORITHMS = ("q_learning", "sarsa")
AxisValue = float | bool
"""A value of an axis of the grid: a number, or the time limit's flag."""
GivenGrid = Mapping[str, Sequence[object]]
"""Each axis of a grid and its values, as given (:func:`plan` checks them)."""
FIXED = {"schedule": "decay"}
"""The cross: ε decays linearly from ``epsilon_start`` (1, the default) to ``epsilon_end``; the rest are the
defaults (but a run shorter than the default evaluation interval is evaluated once, at its end)."""
GRID: dict[str, tuple[AxisValue, ...]] = {
    "alpha": (0.01, 0.05, 0.1, 0.2, 0.5),
    "gamma": (0.9, 0.99, 1.0),
    "epsilon_end": (0.0, 0.01, 0.05),
    "truncation_as_terminal": (False, True),
}
"""The axes of the cross, in the order of the cells; each cell runs every algorithm of :data:`ALGORITHMS`."""
CONSTANT_EPSILONS = (0.1, 0.25, 0.5)
"""The constant ε values of the schedule block (the paper's constant runs: 0.5)."""
AXES: dict[str, tuple[AxisValue, ...]] = {**GRID, "epsilon": CONSTANT_EPSILONS}
"""Every axis ``--grid`` sets: the cross's and the schedule block's constant ε."""
SCHEDULE_BLOCK: dict[str, AxisValue] = {"alpha": 0.05, "truncation_as_terminal": True}
"""Where the schedule block sits: the paper's α and time limit. Its axes: the schedule (constant at each
``epsilon``, decaying to each ``epsilon_end``) x ``gamma``."""
CELL_KEYS = ("schedule", *GRID)
"""What tells the cells apart; a constant cell's ``epsilon_end`` is its constant ε."""
SYMBOLS = {"alpha": "α", "gamma": "γ", "epsilon_end": "ε_end", "truncation_as_terminal": "time limit",
           "epsilon": "constant ε", "schedule": "ε schedule"}
PAPER_CELL: dict[str, str | AxisValue] = {"schedule": "decay", "alpha": 0.05, "gamma": 0.9, "epsilon_end": 0.0,
                                          "truncation_as_terminal": True}
"""The paper's setting: ε decaying from 1 to 0 (its end is not given), old Gym's ``done`` at the time limit."""
PAPER_CONSTANT_CELL: dict[str, str | AxisValue] = {**PAPER_CELL, "schedule": "constant", "epsilon_end": 0.5}
"""The paper's constant runs: ε = 0.5 throughout, the rest as :data:`PAPER_CELL`."""
LEVEL = 0.05
METRICS = {"behaviour": "behaviour return (mean ε-greedy return over training)",
           "greedy": "greedy return (final evaluation round)"}
SARSA_BETTER, Q_BETTER, NOT_RESOLVED = "SARSA better", "Q-Learning better", "not resolved"


# --- the grid and its sweep ---------------------------------------------------------------------------------

def parse_grid(specs: Iterable[str]) -> dict[str, tuple[AxisValue, ...]]:
    """``KEY=V1,V2,...`` pairs (``--grid alpha=0.1,0.2``) over :data:`AXES`; a key not given keeps its values.
    A :class:`ValueError` names the key and what is allowed."""
    grid = dict(AXES)
    for spec in specs:
        key, sep, text = spec.partition("=")
        key = key.strip()
        if not sep or key not in AXES:
            raise ValueError(f"got {quote(spec)}; allowed: KEY=V1,V2,... with KEY one of {', '.join(AXES)}")
        parts = [part.strip() for part in text.split(",") if part.strip()]
        if not parts:
            raise ValueError(f"{key}: empty; allowed: at least one value, e.g. {key}="
                             f"{','.join(_toml(v) for v in AXES[key][:2])}")
        grid[key] = tuple(_grid_value(key, part) for part in parts)
    return grid


def _grid_value(key: str, text: str) -> AxisValue:
    if key == "truncation_as_terminal":
        if text.lower() not in ("true", "false"):
            raise ValueError(f"{key}: got {quote(text)}; allowed: true or false")
        return text.lower() == "true"
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise ValueError(f"{key}: got {quote(text)}; allowed: finite numbers separated by commas")
    return value


def _toml(value: object) -> str:
    """A TOML literal: JSON's spelling of numbers, booleans, strings and lists is TOML's too."""
    return json.dumps(value)


def schedule_configs(grid: GivenGrid) -> list[dict[str, object]]:
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


def sweep_text(grid: GivenGrid, seeds: int, episodes: int, root_seed: int = ROOT_SEED) -> str:
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


def plan(grid: GivenGrid | None = None, seeds: int = DEFAULT_SEEDS, episodes: int = DEFAULT_EPISODES
         ) -> tuple[Sweep, str]:
    """The study's sweep and its file, validated: :class:`SweepError` lists every problem, by key."""
    grid = dict(AXES if grid is None else grid)
    problems = [f"grid.{cut(str(key), 80)}: unknown key; allowed: {', '.join(AXES)}"
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


def _epsilon_problems(values: Sequence[object]) -> list[str]:
    """The constant ε values' problems, named at ``grid.epsilon[i]`` as the sweep names the cross's."""
    problems = []
    for i, value in enumerate(values):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 <= value <= 1:
            problems.append(f"grid.epsilon[{i}]: got {quote(value)}; allowed: a number in [0, 1]")
        elif value in values[:i]:
            problems.append(f"grid.epsilon[{i}]: the same configuration as grid.epsilon[{values.index(value)}]; "
                            "allowed: each configuration once")
    return problems


def cell_count(grid: GivenGrid | None = None) -> int:
    """How many cells the study's grid has: the cross's, and the schedule block's own."""
    grid = {**AXES, **(grid or {})}
    own = len(schedule_configs(grid)) // len(ALGORITHMS)
    return math.prod(len(grid[key]) for key in GRID) + own


# --- cells, differences and marks ---------------------------------------------------------------------------

def seed_returns(root: Path) -> pd.DataFrame:
    """One row per finished trial of a sweep's store: its configuration's hash, algorithm and cell
    (:data:`CELL_KEYS`), its seed, ``behaviour`` (the mean return over every training episode) and ``greedy``
    (the mean return of the last evaluation round), as :mod:`rlcompare.stats.metrics` defines them for every
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
    values = pd.DataFrame([{"config": hash_, **_cell_config(trial_path(root, str(hash_), seed))}
                           for hash_, seed in first_seed.items()])
    return frame.merge(values, on="config")[columns]


def _dataset(root: Path, trials: list[tuple[str, int]], name: str, columns: list[str]) -> pd.DataFrame:
    """``name`` of every trial as one frame of ``columns``, with ``config`` (the hash) from its path."""
    partitioning = ds.partitioning(pa.schema([("config", pa.string()), ("trial", pa.int64())]), flavor="hive")
    dataset = ds.dataset([str(trial_path(root, hash_, seed) / name) for hash_, seed in trials], format="parquet",
                         partitioning=partitioning, partition_base_dir=str(Path(root) / TRIALS_DIR))
    frame: pd.DataFrame = dataset.to_table(columns=["config", *columns]).to_pandas()
    return frame


def _cell_config(trial_dir: Path) -> dict[str, Any]:
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
    vocabulary of :func:`~rlcompare.stats.compare.comparison_label`."""
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
