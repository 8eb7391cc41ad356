"""Steps per second of the fused kernels against a plain Gymnasium + numpy loop, measured in one run.

One step is what tabular control does per time step: choose an ε-greedy action, step the environment,
discretize the observation and update the table. The Gymnasium loop is the 1x reference of
``DESIGN.md``: ``gymnasium.make(env)``, the observation put on the same grid as the kernels' with numpy
(``DiscretizeObservation`` does the same where the box is bounded), and the table updated in numpy.
Every environment is measured three ways: that loop, the compiled port, and the kernels stepping
Gymnasium through the adapter.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass

import gymnasium as gym
import numba
import numpy as np

from rlcompare.algorithms.registry import METHODS
from rlcompare.envs.discretize import cell_indices, make_grid
from rlcompare.envs.features import grid_bounds
from rlcompare.envs.registry import PORTS, TABLE_ENVIRONMENTS, environment
from rlcompare.experiment.config import ExperimentConfig
from rlcompare.experiment.runner import run

ONE_STEP = tuple(name for name, m in METHODS.items() if m.one_step)
MULTI_STEP = tuple(name for name, m in METHODS.items() if m.family not in ("baseline", "one-step"))
"""The other learners: n-step, traces and policy gradient, benchmarked on shorter runs."""
PORT_EPISODES = {name: environment(name).bench_episodes for name in (*PORTS, *TABLE_ENVIRONMENTS)
                 if environment(name).bench_episodes}
"""Episodes per seed of Q-Learning with ε = 0.5 that make about a million steps on each port (its entry's)."""


@dataclass(frozen=True)
class Measurement:
    label: str
    threads: int
    steps: int
    seconds: float

    @property
    def steps_per_second(self) -> float:
        return self.steps / self.seconds


def kernel_steps_per_second(
    algorithm: str, threads: int, *, features: str = "grid", runs: int = 8, episodes: int = 2000, repeats: int = 3,
    env: str = "MountainCar-v0", adapter: bool = False,
) -> Measurement:
    """Median over ``repeats`` of training ``runs`` seeds with ε = 0.5 and no evaluation, on ``threads``
    threads, through :func:`rlcompare.run` (which compiles before it starts the clock)."""
    config = ExperimentConfig(
        algorithm=algorithm, schedule="constant", epsilon=0.5, features=features, env=env, adapter=adapter,
        alpha=0.05 if features == "grid" else 0.5 / 8, seeds=tuple(range(runs)), episodes=episodes,
        eval_every=0, stages=(("final", 1.0),),
    )
    previous = numba.get_num_threads()
    numba.set_num_threads(threads)
    try:
        timings = [run(config).meta["timings"] for _ in range(repeats)]
    finally:
        numba.set_num_threads(previous)
    what = f"{algorithm} ({features})" if env == "MountainCar-v0" and not adapter else \
        f"{env}, {'Gymnasium adapter' if adapter else 'compiled port'}"
    return Measurement(what, threads, timings[0]["training_steps"],
                       statistics.median(t["wall_seconds"] for t in timings))


def gymnasium_steps_per_second(env: str = "MountainCar-v0", steps: int = 60_000, seed: int = 0) -> Measurement:
    """A plain Python loop of tabular Q-Learning on ``gymnasium.make(env)``, on the environment's default grid
    (or its states) and step limit."""
    config = ExperimentConfig(env=env)
    spec = config.environment
    environment = gym.make(env, max_episode_steps=config.max_steps)
    if spec.n_states:
        def state_of(observation) -> int:
            return int(observation)
        n_states = spec.n_states
    else:
        grid = make_grid(*grid_bounds(spec, None), config.bins)
        n_states = grid.n_cells

        def state_of(observation) -> int:
            return int(cell_indices(grid, observation)[0])
    rng = np.random.default_rng(seed)
    q = np.zeros((n_states, spec.n_actions))
    alpha, gamma, epsilon = 0.05, 0.9, 0.5
    state = state_of(environment.reset(seed=seed)[0])
    started = time.perf_counter()
    for _ in range(steps):
        action = int(rng.integers(spec.n_actions)) if rng.random() < epsilon else int(np.argmax(q[state]))
        observation, reward, terminated, truncated, _ = environment.step(action)
        next_state = state_of(observation)
        target = reward if terminated else reward + gamma * np.max(q[next_state])
        q[state, action] += alpha * (target - q[state, action])
        state = state_of(environment.reset()[0]) if terminated or truncated else next_state
    environment.close()
    return Measurement(f"{env}, Gymnasium loop", 1, steps, time.perf_counter() - started)


def run_benchmark(report: Callable[[Measurement], None] = lambda m: None) -> list[Measurement]:
    """Every measurement, reported as it is taken: the Gymnasium loop, the one-step methods, then the other
    learners (shorter runs), and two on tiles."""
    threads = sorted({1, numba.config.NUMBA_NUM_THREADS})
    plan = [(algorithm, "grid", 2000) for algorithm in ONE_STEP]
    plan += [(algorithm, "grid", 300) for algorithm in MULTI_STEP]
    plan += [(algorithm, "tiles", 300) for algorithm in ("sarsa", "sarsa_lambda")]
    measurements = [gymnasium_steps_per_second(steps=30_000)]
    report(measurements[-1])
    for algorithm, features, episodes in plan:
        for n in threads:
            measurements.append(kernel_steps_per_second(algorithm, n, features=features, episodes=episodes))
            report(measurements[-1])
    return measurements


@dataclass(frozen=True)
class PortMeasurement:
    """One environment three ways: Gymnasium's loop, the compiled port on 1 and all threads, the adapter."""

    env: str
    gymnasium: Measurement
    port: list[Measurement]
    adapter: Measurement


def run_port_benchmark(envs: tuple[str, ...] = tuple(PORT_EPISODES),
                       report: Callable[[PortMeasurement], None] = lambda m: None) -> list[PortMeasurement]:
    """Q-Learning with ε = 0.5 on each ported environment: the Gymnasium loop, the port, and the adapter
    (the same kernels stepping Gymnasium, 2 seeds)."""
    threads = sorted({1, numba.config.NUMBA_NUM_THREADS})
    measurements = []
    for env in envs:
        gymnasium = gymnasium_steps_per_second(env, steps=20_000)
        port = [kernel_steps_per_second("q_learning", n, env=env, episodes=PORT_EPISODES[env]) for n in threads]
        adapter = kernel_steps_per_second("q_learning", numba.config.NUMBA_NUM_THREADS, env=env, adapter=True,
                                          runs=2, episodes=max(1, PORT_EPISODES[env] // 50), repeats=1)
        measurements.append(PortMeasurement(env, gymnasium, port, adapter))
        report(measurements[-1])
    return measurements


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


def short_sweep(trials: int, episodes: int = 20) -> tuple[object, str]:
    """A sweep of ``trials`` short trials: Q-Learning on Mountain Car, one configuration, many seeds."""
    from rlcompare.experiment.sweep import parse_sweep

    text = (f'[sweep]\nname = "bench"\nseeds = {trials}\n[fixed]\nalgorithm = "q_learning"\n'
            f"episodes = {episodes}\neval_every = 0\n[[include]]\n")
    return parse_sweep(text), text


def sweep_trials_per_second(backend, label: str, workers: int, trials: int = 200, episodes: int = 20
                            ) -> SweepMeasurement:
    """Run a sweep of short trials into a fresh store after a warm-up sweep (which loads the kernels in every
    worker); time the whole sweep."""
    import tempfile
    from pathlib import Path

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


@dataclass(frozen=True)
class BenchTable:
    """Measurements as text for the command line to print: a title, the columns (a label, then numbers), rows of
    cells, and notes on what was left out."""

    title: str
    columns: tuple[str, ...]
    rows: list[tuple[str, ...]]
    notes: tuple[str, ...] = ()


def kernel_table(measurements: list[Measurement]) -> BenchTable:
    """:func:`run_benchmark`'s measurements, each against the Gymnasium loop (the first) and its own 1 thread."""
    reference = measurements[0].steps_per_second
    single = {m.label: m.steps_per_second for m in measurements if m.threads == 1}
    rows = [(m.label, str(m.threads), f"{m.steps:,}", f"{m.seconds:.3f}", f"{m.steps_per_second:,.0f}",
             f"{m.steps_per_second / reference:,.0f}x", f"{m.steps_per_second / single[m.label]:.2f}x")
            for m in measurements]
    return BenchTable("Every algorithm on MountainCar-v0, 20 bins (one step: act, step, update)",
                      ("what", "threads", "steps", "seconds", "steps/s", "vs Gymnasium", "vs 1 thread"), rows)


def port_table(measurements: list[PortMeasurement]) -> BenchTable:
    """:func:`run_port_benchmark`'s measurements, each against Gymnasium's loop on the same environment."""
    rows = []
    for m in measurements:
        loop = m.gymnasium.steps_per_second
        cells = [f"{x.steps_per_second:,.0f} ({x.steps_per_second / loop:,.0f}x)" for x in m.port]
        rows.append((m.env, f"{loop:,.0f}", *cells,
                     f"{m.adapter.steps_per_second:,.0f} ({m.adapter.steps_per_second / loop:.2f}x)"))
    return BenchTable("Q-Learning, ε = 0.5, on each port: steps/s, and the ratio to Gymnasium's loop on the same "
                      "environment", ("environment", "Gymnasium loop", "port, 1 thread", "port, all threads",
                                      "adapter"), rows)


def sweep_table(measurements: list[SweepMeasurement], notes: tuple[str, ...] = ()) -> BenchTable:
    """:func:`sweep_trials_per_second`'s measurements: trials per second, and each trial's training and overhead."""
    rows = [(m.backend, str(m.workers), str(m.trials), f"{m.seconds:.2f}", f"{m.trials_per_second:.1f}",
             f"{m.kernel_seconds / m.trials * 1e3:.1f} ms", f"{m.overhead_per_trial * 1e3:.1f} ms")
            for m in measurements]
    return BenchTable("A sweep of 200 short trials (Q-Learning, Mountain Car, 20 episodes): store writes included",
                      ("backend", "workers", "trials", "seconds", "trials/s", "training s/trial", "overhead s/trial"),
                      rows, notes)


def sweep_benchmark(address: str | None = None) -> BenchTable:
    """A sweep of short trials on the local backend with 1 and 2 workers, and on Ray where it is installed: the
    cluster at ``address``, or a new local instance with 2 CPUs. A cluster that cannot be reached raises
    :class:`~rlcompare.experiment.backends.BackendError` before anything runs."""
    from rlcompare.experiment.backends import LocalBackend, RayBackend, ray_installed

    plan = [("local", LocalBackend(1), 1), ("local", LocalBackend(2), 2)]
    notes: tuple[str, ...] = ()
    if ray_installed():
        ray = RayBackend(address, num_cpus=None if address else 2)
        ray.connect()
        plan.append(("ray", ray, ray.cpus()))
    else:
        notes = ("Ray is not installed: pip install 'rlcompare[ray]'",)
    return sweep_table([sweep_trials_per_second(backend, label, workers) for label, backend, workers in plan], notes)
