"""What ``rlcompare report`` prints for a directory that is not a study's: one run, a sweep's store, a benchmark's
tables."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from rich.text import Text

from rlcompare.cli.console import console, plural, print_bench, print_frame
from rlcompare.experiment import store

if TYPE_CHECKING:
    import pandas as pd


def run_report(run_dir: Path) -> None:
    """One run directory: its results over seeds, checked on load; and the study it is a configuration of."""
    from rlcompare.experiment.engines import load_run

    store.refuse_while_written(run_dir)
    with console.status(f"Loading {run_dir}"):
        results = load_run(run_dir)
        shown = run_summary(results)
    print_frame(*shown)
    console.print(f"Run directory: {run_dir} ({results.config.name}, {plural(len(results.seeds), 'seed')})",
                  highlight=False)
    try:
        parent = store.owner_of(run_dir.resolve().parent)
    except store.StoreError:
        parent = None
    if parent is not None and parent.kind == "study":
        console.print(f"It is one configuration of {parent}: 'rlcompare report {run_dir.resolve().parent}' builds "
                      "that study's report.", highlight=False)


def bench_report(directory: Path) -> None:
    """A benchmark's directory: the tables of each file ``bench`` wrote there, as it printed them, with when and
    where they were measured."""
    from rlcompare.bench.tables import BENCH_FILES, read_bench_document

    listed = store.listed_outputs(directory)
    for name in BENCH_FILES:
        if name in listed and (directory / name).is_file():
            said, tables = read_bench_document(directory / name)
            console.print(said, highlight=False)
            for table in tables:
                print_bench(table)


def run_summary(results: Any) -> tuple[pd.DataFrame, str, str]:
    """A run's table: its mean behaviour and greedy return over seeds with 95% intervals, as ``run`` prints
    (a deep run: the greedy return of its last evaluation round)."""
    from rlcompare.studies.paper.study import summary
    from rlcompare.tabular.results import Results

    if isinstance(results, Results):
        return summary([results], paper=False)
    import numpy as np

    from rlcompare.stats.metrics import returns_per_seed
    from rlcompare.studies.measures import table_ii

    seeds = list(results.seeds)
    training = results.episodes.groupby("seed", sort=False)["return"]
    rounds = results.evaluations.groupby(["seed", "round"])["return"].mean().unstack("round").loc[seeds]
    metrics = returns_per_seed(tuple(seeds), [training.get_group(seed).to_numpy() for seed in seeds],
                               rounds.to_numpy())
    frame = table_ii({results.config.name: metrics.assign(greedy_success=np.nan)}, {})
    return (frame[["configuration", "behaviour mean", "greedy mean"]],
            "Mean return over seeds [95% bootstrap interval]",
            "behaviour: ε-greedy return averaged over all training episodes; greedy: return of the final network's "
            "greedy policy")


def sweep_report(root: Path, group_by: tuple[str, ...]) -> None:
    from rlcompare.studies.sweep_report import build_sweep_report

    with console.status("Building the sweep's report"):
        path, problems = build_sweep_report(root, group_by)
    for problem in problems:
        console.print(Text("Warning: ", style="yellow") + Text(problem), highlight=False)
    console.print(f"Report: {path}")
