"""``rlcompare bench sweeps``: trials per second of a sweep of short trials (Q-Learning on Mountain Car, store
writes included) on the local backend with 1 and 2 workers, and on Ray where it is installed."""

from __future__ import annotations

import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from rlcompare.bench.tables import BenchTable, Measured, Say, Stage

if TYPE_CHECKING:
    from rlcompare.experiment.backends import LocalBackend, RayBackend
    from rlcompare.experiment.sweep import Sweep


@dataclass(frozen=True)
class SweepMeasurement:
    """A sweep of short trials on one backend."""

    backend: str
    workers: int
    trials: int
    seconds: float
    """Wall time of the whole sweep, store writes included."""
    kernel_seconds: float
    """Training time summed over the trials, as each trial measured it."""

    @property
    def trials_per_second(self) -> float:
        return self.trials / self.seconds

    @property
    def overhead_per_trial(self) -> float:
        """Worker seconds per trial not spent training: scheduling, shipping, the store."""
        return (self.seconds * self.workers - self.kernel_seconds) / self.trials


def short_sweep(trials: int, episodes: int = 20) -> tuple[Sweep, str]:
    """A sweep of ``trials`` short trials: Q-Learning on Mountain Car, one configuration, many seeds."""
    from rlcompare.experiment.sweep import parse_sweep

    text = (f'[sweep]\nname = "bench"\nseeds = {trials}\n[fixed]\nalgorithm = "q_learning"\n'
            f"episodes = {episodes}\neval_every = 0\n[[include]]\n")
    return parse_sweep(text), text


def sweep_trials_per_second(backend: LocalBackend | RayBackend, label: str, workers: int, trials: int = 200,
                            episodes: int = 20) -> SweepMeasurement:
    """Run a sweep of short trials into a fresh store after a warm-up sweep (which loads the kernels in every
    worker); time the whole sweep."""
    from rlcompare.experiment.sweep_store import load_configurations, run_sweep

    with tempfile.TemporaryDirectory() as scratch:
        warm, warm_text = short_sweep(workers * 2, episodes)
        run_sweep(warm, warm_text, Path(scratch) / "warm", backend)
        sweep, text = short_sweep(trials, episodes)
        started = time.perf_counter()
        run_sweep(sweep, text, Path(scratch) / "store", backend)
        seconds = time.perf_counter() - started
        results = next(iter(load_configurations(Path(scratch) / "store")[0].values()))
    return SweepMeasurement(label, workers, trials, seconds, results.meta["timings"]["wall_seconds"])


def sweep_table(measurements: list[SweepMeasurement], notes: tuple[str, ...] = ()) -> BenchTable:
    """:func:`sweep_trials_per_second`'s measurements: trials per second, and each trial's training and overhead."""
    rows: list[tuple[str, ...]] = [
        (m.backend, str(m.workers), str(m.trials), f"{m.seconds:.2f}", f"{m.trials_per_second:.1f}",
         f"{m.kernel_seconds / m.trials * 1e3:.1f} ms", f"{m.overhead_per_trial * 1e3:.1f} ms") for m in measurements]
    return BenchTable("A sweep of 200 short trials (Q-Learning, Mountain Car, 20 episodes): store writes included",
                      ("backend", "workers", "trials", "seconds", "trials/s", "training s/trial", "overhead s/trial"),
                      rows, notes)


def sweep_benchmark(address: str | None = None) -> BenchTable:
    """A sweep of short trials on the local backend with 1 and 2 workers, and on Ray where it is installed: the
    cluster at ``address``, or a new local instance with 2 CPUs. A cluster that cannot be reached raises
    :class:`~rlcompare.experiment.backends.BackendError` before anything runs."""
    from rlcompare.experiment.backends import LocalBackend, RayBackend, ray_installed

    plan: list[tuple[str, LocalBackend | RayBackend, int]] = [("local", LocalBackend(1), 1),
                                                              ("local", LocalBackend(2), 2)]
    notes: tuple[str, ...] = ()
    if ray_installed():
        ray = RayBackend(address, num_cpus=None if address else 2)
        ray.connect()
        plan.append(("ray", ray, ray.cpus()))
    else:
        notes = ("Ray is not installed: pip install 'rlcompare[ray]'",)
    return sweep_table([sweep_trials_per_second(backend, label, workers) for label, backend, workers in plan], notes)


def sweep_stage(address: str | None = None) -> Stage:
    """:func:`sweep_benchmark` as a stage: on the cluster at ``address``, or a new local Ray instance."""
    def measure(say: Say) -> Measured:
        return Measured(sweep_benchmark(address))

    return Stage("sweeps of 200 short trials: the local backend with 1 and 2 workers, then Ray", measure)
