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

import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from rlcompare.experiment import store
from rlcompare.experiment.sweep import Sweep, SweepError, Trial
from rlcompare.experiment.sweep_store import (
    run_sweep,
)
from rlcompare.studies.interface import UI, Report, run_trials
from rlcompare.studies.registry import SensitivityOptions
from rlcompare.studies.sensitivity_grid import STUDY, SWEEP_DIR, parse_grid, plan
from rlcompare.studies.sensitivity_report import build_report
from rlcompare.validation import ConfigError

if TYPE_CHECKING:
    from rlcompare.experiment.backends import Backend


def run_sensitivity(out: Path, sweep: Sweep, text: str, backend: Backend,
                    progress: Callable[[Trial], None] | None = None, *, force: bool = False) -> tuple[int, int]:
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


# --- the report ---------------------------------------------------------------------------------------------

def report(out: Path, ui: UI | None = None, *, runs: None = None, videos: bool = True) -> Report:
    """Tables, heatmaps and ``report.html`` of the study in ``out``, from its sweep's store alone: the page, the
    summary it opens with, and what is missing (it draws no videos)."""
    with store.rewriting(Path(out), "study") as owner:
        if owner.name != STUDY:
            raise store.StoreError(f"{out}: holds {owner}; allowed: the {STUDY} study's directory")
        return build_report(Path(out))
