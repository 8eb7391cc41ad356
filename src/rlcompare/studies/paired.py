"""The paired study: the paper's question, on-policy against off-policy target, asked with networks.

SARSA(λ) and Q(λ) in one PQN-style engine whose only switch is the bootstrap (purejaxql's ``pqn_gymnax.py``), on
paired seeds, beside any other deep method. Each set of environments it is asked on is a configuration of it:
classic control with the tabular pair beside (:mod:`rlcompare.studies.deep.study`), MinAtar's games
(:mod:`rlcompare.studies.deep.minatar`). A configuration gives a
:class:`~rlcompare.studies.paired_plan.PairedStudy` (environments, margins, labels), a
:class:`~rlcompare.studies.paired_plan.Plan` from its options (:mod:`rlcompare.studies.paired_plan`, which ``--plan``
reads without this module), and the registry's ``run`` (:func:`train`) and ``report``
(:func:`rlcompare.studies.paired_report.findings`, then sections of its own). Here, written once: a plan trained
or loaded, on this machine or as a backend's tasks, and what a report reads of each run (greedy curves, each
seed's returns).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from rlcompare.deep.config import DeepConfig
from rlcompare.deep.results import DeepResults
from rlcompare.experiment import rundir, store
from rlcompare.experiment.backends import RayBackend
from rlcompare.experiment.engines import load_run
from rlcompare.experiment.runner import run_or_load
from rlcompare.stats.metrics import returns_per_seed
from rlcompare.studies.interface import UI, Advance
from rlcompare.studies.paired_plan import PAIR, Plan
from rlcompare.studies.seed_blocks import Backend, trained_on
from rlcompare.tabular.config import ExperimentConfig
from rlcompare.tabular.results import Results


def reproduce(out: Path, study: str, plan: Plan, *, progress: Advance | None = None, force: bool = False,
              backend: Backend | None = None) -> Iterator[tuple[str, DeepResults | Results, bool]]:
    """Train (or load, where finished) the configurations beside the networks, then every network's, into
    ``out``: on this machine, or with ``backend`` (connected) as tasks, a block of seeds each
    (:mod:`rlcompare.studies.seed_blocks`)."""
    def advance(task: str) -> Callable[[int], None] | None:
        return None if progress is None else (lambda n: progress(task, n))

    if plan.beside:
        yield from run_or_load(Path(out), plan.beside, study=study, progress=advance("tabular"), force=force)
    if backend is None:
        yield from run_or_load(Path(out), plan.configs(), study=study, progress=advance("deep"), force=force,
                               workers=plan.workers)
    else:
        yield from trained_on(backend, Path(out), study, plan.configs(), progress=advance("deep"), force=force)


def cluster(address: str | None) -> Backend | None:
    """The Ray cluster at ``address``, joined now so that one that cannot be reached is reported before anything is
    written; None (this machine) without an address."""
    if address is None:
        return None
    backend = RayBackend(address, here="leave out --address to train here")
    backend.connect()
    return backend


def train(out: Path, study: str, plan: Plan, ui: UI, *, force: bool = False, backend: Backend | None = None
          ) -> dict[str, Any]:
    """:func:`reproduce`, telling ``ui`` of each configuration as it finishes."""
    groups: dict[str, Mapping[str, DeepConfig | ExperimentConfig]] = {"tabular": plan.beside, "deep": plan.configs()}
    runs = {}
    with ui.tasks({task: sum(c.progress_total for c in configs.values())
                   for task, configs in groups.items() if configs}) as advance:
        for name, results, reused in reproduce(out, study, plan, progress=advance, force=force, backend=backend):
            runs[name] = results
            ui.done(name, results, reused)
    return runs


# --- what a report computes from the run directories ------------------------------------------------------

def load_runs(out: Path) -> tuple[dict[str, DeepResults], dict[str, Results], list[str]]:
    """The finished runs of a study directory, deep and tabular, and what is missing or broken."""
    deep: dict[str, DeepResults] = {}
    tabular: dict[str, Results] = {}
    problems, failed = [], []
    for run_dir in sorted(p for p in Path(out).iterdir() if p.is_dir() and store.owner_of(p) == store.RUN):
        try:
            results = load_run(run_dir)
            if isinstance(results, Results):
                tabular[run_dir.name] = results
            else:
                deep[run_dir.name] = results
        except (store.StoreError, ValueError) as error:
            problems.append(str(error))
            failed.append(run_dir.name)
    return deep, tabular, problems + rundir.missing_members(Path(out), failed)


def over_environments(scores: np.ndarray, statistic: str) -> np.ndarray:
    """Each seed's score over the environments, ``scores`` being ``(environments, seeds)``: their ``mean``, or their
    ``iqm``, the mean of the middle half (rliable's interquartile mean, Agarwal et al. 2021: scipy's ``trim_mean``
    cutting a quarter of the environments at each end, rounded down; 5 games: the middle 3, 3 or fewer: all)."""
    if statistic == "iqm":
        from scipy.stats import trim_mean

        return np.asarray(trim_mean(scores, 0.25, axis=0), dtype=float)
    return np.asarray(scores.mean(axis=0), dtype=float)


def eval_curves(results: DeepResults) -> tuple[np.ndarray, np.ndarray]:
    """``(after_step, (seeds, rounds) mean greedy return)``."""
    frame = results.evaluations.groupby(["seed", "round"], sort=True)["return"].mean()
    curves = frame.to_numpy().reshape(len(results.seeds), -1)
    steps = np.sort(results.evaluations["after_step"].unique())
    return steps, curves


def final_returns(results: DeepResults) -> np.ndarray:
    """Each seed's mean greedy return in the last evaluation round."""
    return eval_curves(results)[1][:, -1]


def per_seed(results: DeepResults) -> pd.DataFrame:
    """One row per seed: :func:`~rlcompare.stats.metrics.returns_per_seed` (behaviour, final greedy return, area
    under the greedy curve)."""
    training = {seed: returns.to_numpy() for seed, returns in results.episodes.groupby("seed")["return"]}
    no_episode = np.full(1, np.nan)  # a seed that finished no training episode (Atari's first steps)
    return returns_per_seed(results.seeds, [training.get(seed, no_episode) for seed in results.seeds],
                            eval_curves(results)[1])


def seconds_per_step(results: DeepResults) -> float:
    """Wall-clock seconds per environment step of one seed: its group of ``vmap_width`` seeds trains side by side
    at a steady pace, so a seed reached step ``k`` about ``k`` times this after its group began."""
    groups = -(-len(results.seeds) // results.config.vmap_width)
    return float(results.meta["timings"]["wall_seconds"] / (groups * results.meta["timings"]["training_steps"]))


def run_of(runs: Mapping[str, DeepResults], env: str, method: str) -> DeepResults | None:
    return next((r for r in runs.values() if r.config.env == env and r.config.algorithm == method), None)


def pair_of(runs: Mapping[str, DeepResults], env: str) -> tuple[DeepResults, DeepResults] | None:
    """The on- and off-policy runs of :data:`PAIR` on ``env``, where both ran on the same seeds."""
    on, off = (run_of(runs, env, method) for method in PAIR)
    return (on, off) if on is not None and off is not None and on.seeds == off.seeds else None
