"""Does the paper's conclusion, SARSA beats Q-Learning on Mountain Car, survive other settings?

A grid around the paper's setting, each configuration for Q-Learning and SARSA on the same seeds: the cross
α x γ x ε_end x time limit, and a block of ε's schedule x γ (:mod:`rlcompare.studies.sensitivity.grid`). It runs
through the sweep engine, so ``--address`` runs it on a Ray cluster and a re-run resumes; the study directory holds
the sweep's store in ``sweep/``, claimed with its own marker. Each cell compares SARSA minus Q-Learning per seed
on the behaviour return and the greedy return (a 95% BCa interval, the Wilcoxon signed-rank p, Holm over each
metric's cells); :mod:`rlcompare.studies.sensitivity.report` draws the tables, heatmaps and page. The design, why
20 seeds, and what it finds: ``docs/why.md``, "Does the conclusion survive other settings?".
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
from rlcompare.stats.design import SIGNED_RANK
from rlcompare.studies.interface import UI, Report, run_trials
from rlcompare.studies.plans import Question, StudyPlan, episodic
from rlcompare.studies.registry import SensitivityOptions
from rlcompare.studies.sensitivity.grid import METRICS, STUDY, SWEEP_DIR, parse_grid, plan
from rlcompare.studies.sensitivity.report import build_report
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


def study_plan(options: SensitivityOptions) -> StudyPlan:
    """What the study trains and can decide: SARSA against Q-Learning in every cell of the grid, one family per
    metric (:func:`~rlcompare.studies.sensitivity.grid.mark_family`)."""
    sweep, _ = plan_of(options)
    configs = {f"{config.algorithm}-{index}": config for index, config in enumerate(sweep.configs)}
    cells = len(sweep.configs) // 2
    return StudyPlan(episodic(configs), tuple(
        Question(f"SARSA against Q-Learning by the {metric} return in each of the {cells} cells", SIGNED_RANK,
                 options.seeds, cells) for metric in METRICS))


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
