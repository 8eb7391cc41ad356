"""What ``rlcompare compare`` reads of each run (:mod:`rlcompare.studies.compare_runs`): each environment's runs over
their common range, checked to be one budget, one kind of point and one source a run; two numbers a run read from
its own points (the final window's mean and the mean of the value in force, a zero-order hold), and the curves on a
common grid for the pictures alone.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import pandas as pd

from rlcompare.experiment.formats import OutsideRunError

GRID_POINTS = 200
"""Points of each environment's common grid of steps."""
FINAL_WINDOW = 0.1
"""The final window: the last tenth of the common steps."""
SHORTEST_SHARE = 0.9
"""A run that ends before this share of its environment's longest run is refused: not one budget."""
METRICS = {"final": "mean of the points in the final tenth of the steps",
           "auc": "mean over all the steps of the value in force (area under the curve)"}
PRIMARY = ("final",)
"""The metric compared unless the user declares others (``--metric``): each one more doubles the family."""


@dataclass(frozen=True)
class Curves:
    """One environment's runs on its common grid: ``values[method]`` is ``(seeds, GRID_POINTS)``, the seeds by
    their labels in ``seeds[method]``."""

    env: str
    steps: np.ndarray
    values: dict[str, np.ndarray]
    seeds: dict[str, tuple[str, ...]]


def runs_of(frame: pd.DataFrame) -> dict[tuple[str, str, str], pd.DataFrame]:
    """Each run's rows, sorted by step, by ``(env, method, seed)``."""
    return {(str(env), str(method), str(seed)): rows.sort_values("step", kind="stable")
            for (env, method, seed), rows in frame.groupby(["env", "method", "seed"], sort=True)}


def checked(frame: pd.DataFrame, cut: bool = False, paired: bool = False) -> None:
    """Refuse, naming the file, an environment that one method alone ran; a run that ends well before its
    environment's longest (another budget, unless ``cut``: the comparison is then on the steps every run reached,
    and there must be some); and, where ``paired``, a seed one method of an environment has and another lacks
    (seeds matched by label; independent samples need no common labels)."""
    for env, runs, start, end in environments(frame):
        first = next(iter(runs.values()))["source"].iloc[0]
        methods = sorted({method for _, method, _ in runs})
        if len(methods) < 2:
            raise OutsideRunError(f"{first}: {methods[0]} alone on {env}; expected two methods or more on an "
                                  "environment to compare")
        ends = {key: run["step"].iloc[-1] for key, run in runs.items()}
        longest = max(ends.values())
        for key, last in ends.items():
            if last < SHORTEST_SHARE * longest and not cut:
                raise OutsideRunError(f"{runs[key]['source'].iloc[0]}: {key[1]} seed {key[2]} on {env} ends at step "
                                      f"{last:,}; expected runs of one budget (the longest ends at {longest:,}), or "
                                      "--cut-to-shortest")
        if start >= end:
            raise OutsideRunError(f"{first}: the runs on {env} share no steps (one begins at {start:,.0f}, one ends at "
                                  f"{end:,.0f}); expected runs that overlap")
        if not paired:
            continue
        seeds = {method: {seed for _, m, seed in runs if m == method} for method in methods}
        every = set().union(*seeds.values())
        for method, have in seeds.items():
            if have != every:
                source = min(runs[env, method, seed]["source"].iloc[0] for seed in have)
                raise OutsideRunError(f"{source}: {method} on {env} lacks seed {', '.join(sorted(every - have))}; "
                                      f"expected every method to have the same seeds ({', '.join(sorted(every))})")


def environments(frame: pd.DataFrame) -> Iterator[tuple[str, dict[tuple[str, str, str], pd.DataFrame], float, float]]:
    """Each environment, its runs (:func:`runs_of`) and their common range: from the step where every run has begun
    to the step where the shortest has ended."""
    for env, rows in frame.groupby("env", sort=True):
        runs = runs_of(rows)
        yield (str(env), runs, float(max(run["step"].iloc[0] for run in runs.values())),
               float(min(run["step"].iloc[-1] for run in runs.values())))


def curves(frame: pd.DataFrame) -> list[Curves]:
    """Every environment's runs interpolated onto its common grid of steps (for the pictures)."""
    found = []
    for env, runs, start, end in environments(frame):
        grid = np.linspace(start, end, GRID_POINTS)
        values: dict[str, list[np.ndarray]] = {}
        seeds: dict[str, list[str]] = {}
        for (_, method, seed), run in runs.items():
            values.setdefault(method, []).append(np.interp(grid, run["step"].to_numpy(np.float64),
                                                           run["value"].to_numpy(np.float64)))
            seeds.setdefault(method, []).append(str(seed))
        found.append(Curves(env, grid, {m: np.stack(v) for m, v in values.items()},
                            {m: tuple(s) for m, s in seeds.items()}))
    return found


def window_mean(steps: np.ndarray, values: np.ndarray, low: float, high: float) -> float:
    """The mean of the values recorded at steps in ``[low, high]``, each point once however many steps it spans;
    where none is, the value in force at ``high`` (the last recorded before it)."""
    inside = (steps >= low) & (steps <= high)
    if inside.any():
        return float(values[inside].mean())
    return float(values[np.searchsorted(steps, high, side="right") - 1])


def held_mean(steps: np.ndarray, values: np.ndarray, start: float, end: float) -> float:
    """The mean over ``[start, end]`` of the value in force at each step, each recorded value holding from its
    step to the next (a zero-order hold); ``steps`` sorted, the first at or before ``start``, ``end > start``."""
    first = int(np.searchsorted(steps, start, side="right")) - 1
    inside = (steps > start) & (steps < end)
    knots = np.concatenate([[start], steps[inside], [end]])
    held = values[first:first + len(knots) - 1]
    return float(np.sum(held * np.diff(knots)) / (end - start))


@dataclass(frozen=True)
class Numbers:
    """One environment's two numbers a run (:data:`METRICS`): per method and metric, a value a seed, the seeds by
    their labels in ``seeds[method]``; and the common range they were read over."""

    env: str
    start: float
    end: float
    values: dict[str, dict[str, np.ndarray]]
    seeds: dict[str, tuple[str, ...]]


def numbers(frame: pd.DataFrame) -> list[Numbers]:
    """Every environment's runs read over their common range: the final window's mean and the held mean."""
    found = []
    for env, runs, start, end in environments(frame):
        low = end - FINAL_WINDOW * (end - start)
        values: dict[str, dict[str, list[float]]] = {}
        seeds: dict[str, list[str]] = {}
        for (_, method, seed), run in runs.items():
            steps, points = run["step"].to_numpy(np.float64), run["value"].to_numpy(np.float64)
            mine = values.setdefault(method, {"final": [], "auc": []})
            mine["final"].append(window_mean(steps, points, low, end))
            mine["auc"].append(held_mean(steps, points, start, end))
            seeds.setdefault(method, []).append(str(seed))
        found.append(Numbers(env, start, end,
                             {m: {k: np.asarray(v) for k, v in by.items()} for m, by in values.items()},
                             {m: tuple(s) for m, s in seeds.items()}))
    return found
