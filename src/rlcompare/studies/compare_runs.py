"""``rlcompare compare``: rlcompare's verdicts and report for runs other libraries made (read by
:mod:`rlcompare.experiment.outside` into one tidy table).

Each run's values (episode returns, or evaluations) are put on a common grid of environment steps per environment,
from the step where every run has begun to the step where the shortest has ended, by linear interpolation; two
numbers a run are compared: the mean over the last tenth of that range (the final window) and the mean over all of
it (the normalised area under the curve). Seeds of two libraries' runs share no randomness, so methods are compared
as independent samples (:func:`~rlcompare.stats.compare.compare_independent`) unless the user says the seeds are
paired; every comparison of a report is one Holm family. A margin of no difference is the user's, declared on the
command line before the report is read; without one, no claim of equivalence is made.
"""

from __future__ import annotations

from collections.abc import Hashable
from dataclasses import dataclass
from itertools import combinations
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from rlcompare.experiment import store
from rlcompare.experiment.outside import OutsideRunError
from rlcompare.report.aggregate_plots import Aggregates, across_section, draw_aggregates
from rlcompare.report.findings import gap_and_interval
from rlcompare.report.page import Section, save_figure, write_report, write_table
from rlcompare.report.plots import plot_return_curves
from rlcompare.stats.aggregates import by_method, score_scales
from rlcompare.stats.compare import Judged, Paired, compare_independent, compare_paired, judge_family
from rlcompare.stats.design import RANK_SUM, SIGNED_RANK, smallest_p
from rlcompare.studies.interface import Report

GRID_POINTS = 200
"""Points of each environment's common grid of steps."""
FINAL_WINDOW = 0.1
"""The final window: the last tenth of the common steps."""
SHORTEST_SHARE = 0.9
"""A run that ends before this share of its environment's longest run is refused: not one budget."""
METRICS = {"final": "mean over the final tenth of the steps", "auc": "mean over all the steps (area under the curve)"}
COMPARISON = store.Owner("comparison")
"""What ``rlcompare compare`` writes its directory as."""


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


def checked(frame: pd.DataFrame, cut: bool = False) -> None:
    """Refuse, naming the file, a run that ends well before its environment's longest (another budget, unless
    ``cut``: the comparison is then on the steps every run reached) and a seed one method of an environment has
    and another lacks."""
    runs = runs_of(frame)
    for env, rows in frame.groupby("env", sort=True):
        ends = {key: run["step"].iloc[-1] for key, run in runs.items() if key[0] == env}
        longest = max(ends.values())
        for key, end in ends.items():
            if end < SHORTEST_SHARE * longest and not cut:
                source = runs[key]["source"].iloc[0]
                raise OutsideRunError(f"{source}: {key[1]} seed {key[2]} on {env} ends at step {end:,}; expected runs "
                                      f"of one budget (the longest ends at {longest:,}), or --cut-to-shortest")
        seeds = {str(method): set(group.astype(str)) for method, group in rows.groupby("method")["seed"]}
        every = set().union(*seeds.values())
        for method, have in seeds.items():
            if have != every:
                missing = sorted(every - have)
                raise OutsideRunError(f"{sorted(set(rows.loc[rows['method'] == method, 'source']))[0]}: {method} on "
                                      f"{env} lacks seed {', '.join(missing)}; expected every method to have the "
                                      f"same seeds ({', '.join(sorted(every))})")


def curves(frame: pd.DataFrame) -> list[Curves]:
    """Every environment's runs interpolated onto its common grid of steps."""
    found = []
    for env, rows in frame.groupby("env", sort=True):
        runs = runs_of(rows)
        start = max(run["step"].iloc[0] for run in runs.values())
        end = min(run["step"].iloc[-1] for run in runs.values())
        grid = np.linspace(start, end, GRID_POINTS)
        values: dict[str, list[np.ndarray]] = {}
        seeds: dict[str, list[str]] = {}
        for (_, method, seed), run in runs.items():
            values.setdefault(method, []).append(np.interp(grid, run["step"].to_numpy(np.float64),
                                                           run["value"].to_numpy(np.float64)))
            seeds.setdefault(method, []).append(str(seed))
        found.append(Curves(str(env), grid, {m: np.stack(v) for m, v in values.items()},
                            {m: tuple(s) for m, s in seeds.items()}))
    return found


def per_seed(curve: Curves) -> dict[str, dict[str, np.ndarray]]:
    """Per method, each seed's final-window mean and area (:data:`METRICS`)."""
    last = curve.steps >= curve.steps[-1] - FINAL_WINDOW * (curve.steps[-1] - curve.steps[0])
    return {method: {"final": values[:, last].mean(axis=1), "auc": values.mean(axis=1)}
            for method, values in curve.values.items()}


@dataclass(frozen=True)
class Comparison:
    """One row of the verdict table: method ``a`` against ``b`` on an environment, by a metric (:data:`METRICS`)."""

    env: str
    metric: str
    a: str
    b: str


def compared(found: list[Curves], paired: bool, margin: float | None) -> dict[Comparison, Paired]:
    """Each pair of methods on each environment, on each metric; seeds matched by label where ``paired``."""
    result = {}
    for curve in found:
        numbers = per_seed(curve)
        for a, b in combinations(sorted(curve.values), 2):
            order_b = [curve.seeds[b].index(seed) for seed in curve.seeds[a]]
            for metric in METRICS:
                x, y = numbers[a][metric], numbers[b][metric][order_b]
                result[Comparison(curve.env, metric, a, b)] = (compare_paired(x, y, margin) if paired
                                                               else compare_independent(x, y, margin))
    return result


def judged(found: dict[Comparison, Paired]) -> dict[Comparison, tuple[Judged, str]]:
    """The comparisons as one Holm family, each with its label in the methods' own names."""
    family: dict[Hashable, Paired] = {key: paired for key, paired in found.items()}
    judgements = judge_family(family, ("A", "B"))
    return {key: (judgements[key], {"A better": f"{key.a} better", "B better": f"{key.b} better"}.get(
        judgements[key].label, judgements[key].label)) for key in found}


def verdicts(found: dict[Comparison, tuple[Judged, str]]) -> pd.DataFrame:
    """A row per comparison."""
    return pd.DataFrame([{
        "environment": key.env, "metric": key.metric, "A": key.a, "B": key.b, "A mean": j.paired.a_mean,
        "B mean": j.paired.b_mean, "A - B (95% CI)": j.paired.difference.format(3),
        "P(A > B)": j.paired.improvement.format(2), "p (Holm)": j.p, "p equivalent (Holm)": j.p_equivalence,
        "seeds": j.paired.seeds, "verdict": label,
    } for key, (j, label) in found.items()])


def answer(found: dict[Comparison, tuple[Judged, str]], paired: bool) -> list[str]:
    """The answer in words: each environment's final-window comparisons, and how they were tested."""
    test = ("paired seeds (Wilcoxon signed-rank)" if paired
            else "seeds as independent samples (Mann-Whitney; the runs share no randomness)")
    lines = []
    for key, (j, label) in found.items():
        if key.metric == "final":
            gap, interval = gap_and_interval(j.paired.difference)
            lines.append(f"On {key.env}, {key.a} against {key.b} over the final tenth of the steps: {key.a} scores "
                         f"{gap} ({interval}; {label}).")
    seeds = min((j.paired.seeds for j, _ in found.values()), default=0)
    floor = smallest_p(SIGNED_RANK if paired else RANK_SUM, seeds)
    return [*lines, f"Tested as {test}; p-values Holm-adjusted over every row of the verdict table. With {seeds} "
                    f"seeds a side the test cannot give a p below {floor:.3g}."]


def across(found: list[Curves], figures: Path, tables: Path) -> tuple[Aggregates | None, dict[str, str]]:
    """rliable's aggregates of the final-window numbers over two or more environments that two or more methods ran
    (each environment normalised between its worst method's mean, 0, and its best's, 1: a relative scale, with no
    published reference for runs of any library), drawn and written; none otherwise."""
    finals = {c.env: {m: v["final"] for m, v in per_seed(c).items()} for c in found}
    scales = score_scales(finals)
    scores = by_method(finals, scales)
    if len(next(iter(scores.values()), [])) < 2 or len(scores) < 2:
        return None, {}
    curves = by_method({c.env: c.values for c in found}, scales)
    drawn = draw_aggregates(scores, figures, tasks="environments", curves={m: curves[m] for m in scores},
                            x=np.linspace(0.0, 1.0, GRID_POINTS),
                            curve_xlabel="share of each environment's common steps")
    return drawn, {name: write_table(frame, tables, name) for name, frame in (
        ("aggregates", drawn.intervals), ("improvement", drawn.improvements))}


def curves_figure(curve: Curves) -> Figure:
    figure = Figure(figsize=(7, 4.2))
    ax = figure.subplots()
    plot_return_curves(ax, curve.steps, curve.values, window=1, ylabel="value")
    ax.set_xlabel("environment steps")
    ax.set_title(curve.env)
    return figure


def pairing_table(frame: pd.DataFrame) -> pd.DataFrame:
    """What was read: each source file and the method, environment and seed it was taken as."""
    return (frame.groupby(["source", "method", "env", "seed"], sort=True)
            .agg(points=("step", "size"), first_step=("step", "min"), last_step=("step", "max")).reset_index())


def report(out: Path, frame: pd.DataFrame, *, paired: bool, margin: float | None, cut: bool = False) -> Report:
    """Verdicts, tables, figures and ``report.html`` of ``frame``'s runs into ``out``; ``cut``: runs that end apart
    are compared on the steps all of them reached (:func:`checked`)."""
    checked(frame, cut)
    found = curves(frame)
    comparisons = compared(found, paired, margin)
    with store.output_directory(out, COMPARISON):
        labelled = judged(comparisons)
        table = verdicts(labelled)
        files = {"verdicts": write_table(table, out / "tables", "verdicts"),
                 "pairing": write_table(pairing_table(frame), out / "tables", "pairing")}
        lines = answer(labelled, paired)
        figures = [(save_figure(curves_figure(c), out / "figures" / f"curves-{i}.png"),
                    f"{c.env}: each method's mean over seeds on the common grid, 95% band")
                   for i, c in enumerate(found)]
        aggregates, aggregate_files = across(found, out / "figures", out / "tables")
        files |= aggregate_files
        grids = "; ".join(f"{c.env}: steps {c.steps[0]:,.0f} to {c.steps[-1]:,.0f}" for c in found)
        sections = [
            Section("The answer", lines),
            Section("What was compared", [
                f"Each run's values on a common grid of {GRID_POINTS} environment steps per environment, from the step "
                f"where every run has begun to where the shortest ends ({grids}), by linear interpolation"
                + (" (--cut-to-shortest: runs that ended apart are cut to it)" if cut else "") + ". Metrics: "
                + "; ".join(f"{name}, the {words}" for name, words in METRICS.items())
                + ". " + ("Seeds paired by their labels (--paired): the user says they share randomness." if paired
                          else "Seeds compared as independent samples: runs of different libraries share no "
                               "randomness (--paired where they do).")
                + (f" Margin of no difference, declared on the command line: ±{margin:g}." if margin is not None
                   else " No margin was declared, so no comparison can be called equivalent.")],
                [("What each file was taken as", pairing_table(frame), files["pairing"])]),
            Section("Verdicts", tables=[("Every comparison, one Holm family", table, files["verdicts"])]),
            across_section(
                "Across environments",
                "The final-window numbers pooled over the environments as rliable does (Agarwal et al. 2021): each "
                "environment normalised between its worst method's mean (0) and its best's (1), a relative scale "
                "for runs with no published reference; interval estimates, the probability of improvement, "
                "performance profiles and sample-efficiency curves, with 95% stratified bootstrap intervals.",
                aggregates, files, "Interval estimates",
                "Across environments: needs two or more environments that two or more methods ran."),
            Section("Curves", figures=figures),
        ]
        page = write_report(out / "report.html", "Runs compared", sections, [])
    return Report(page, lines, [])
