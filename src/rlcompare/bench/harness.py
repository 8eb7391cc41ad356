"""How the benchmark measures: a :class:`Measurement` of steps over seconds, numba's threads set for a while, and
three timed trainings of tabular control (one step: choose an ε-greedy action, step the environment, discretize
the observation, update the table) that the benchmark's rows are made of.

- :func:`kernel_steps_per_second`: rlcompare's kernel, through :func:`rlcompare.run`.
- :func:`kernel_and_reference`: that kernel and the method's reference kernel (:mod:`rlcompare.bench.reference`)
  in turn, on the same seeds and threads.
- :func:`gymnasium_steps_per_second`: the 1x reference of ``DESIGN.md``, a plain Python loop on
  ``gymnasium.make(env)``, the observation put on the kernels' grid with numpy (``DiscretizeObservation`` does the
  same where the box is bounded) and the table updated in numpy.
"""

from __future__ import annotations

import contextlib
import statistics
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numba
import numpy as np

from rlcompare.bench.reference import REFERENCES
from rlcompare.envs.discretize import UniformGrid, cell_indices, make_grid
from rlcompare.envs.features import grid_bounds
from rlcompare.experiment.runner import run
from rlcompare.tabular.config import ExperimentConfig
from rlcompare.tabular.runs import over_runs
from rlcompare.tabular.state import initial_state
from rlcompare.tabular.train import epsilon_schedule


@dataclass(frozen=True)
class Measurement:
    label: str
    threads: int
    steps: int
    seconds: float
    reference: Measurement | None = None
    """The method's reference kernel on the same seeds and threads, measured in turn with this one (kernel rows of
    the methods in :data:`~rlcompare.bench.reference.REFERENCES`)."""
    cpu_seconds: float | None = None
    """Processor time of the whole process over the same span, where measured: over ``seconds``, the cores it had
    (on a machine shared with other work, two threads may have had one)."""

    @property
    def steps_per_second(self) -> float:
        return self.steps / self.seconds

    @property
    def vs_reference(self) -> float | None:
        """Steps per second over the reference kernel's; None without one."""
        return None if self.reference is None else self.steps_per_second / self.reference.steps_per_second

    def as_dict(self) -> dict[str, object]:
        return {"label": self.label, "threads": self.threads, "steps": self.steps, "seconds": self.seconds,
                "steps_per_second": self.steps_per_second, "cpu_seconds": self.cpu_seconds}


def all_threads() -> int:
    """The threads numba was started with (``NUMBA_NUM_THREADS``, every core by default)."""
    threads: int = vars(numba.config)["NUMBA_NUM_THREADS"]
    return threads


def thread_counts() -> list[int]:
    """What every row is measured on: 1 thread, and all of them."""
    return sorted({1, all_threads()})


def threads_text(threads: int) -> str:
    """``1 thread``, ``2 threads``."""
    return f"{threads} thread" + ("" if threads == 1 else "s")


@contextlib.contextmanager
def temporarily(read: Callable[[], int], write: Callable[[int], None], value: int) -> Iterator[None]:
    """A setting (threads of a library) at ``value`` inside, as it was after."""
    before = read()
    write(value)
    try:
        yield
    finally:
        write(before)


def numba_threads(threads: int) -> contextlib.AbstractContextManager[None]:
    """numba's threads set to ``threads`` inside, as they were after."""
    return temporarily(numba.get_num_threads, numba.set_num_threads, threads)


def config_grid(config: ExperimentConfig) -> UniformGrid:
    """The uniform grid of ``config``'s observations (its bins over its bounds)."""
    spec = config.environment
    return make_grid(*grid_bounds(spec, config.bounds), spec.bins if config.bins is None else config.bins)


def bench_config(algorithm: str, runs: int, episodes: int, features: str = "grid", env: str = "MountainCar-v0",
                 adapter: bool = False) -> ExperimentConfig:
    """``runs`` seeds of ``algorithm`` with ε = 0.5 and no evaluation: what every kernel row trains."""
    return ExperimentConfig(
        algorithm=algorithm, schedule="constant", epsilon=0.5, features=features, env=env, adapter=adapter,
        alpha=0.05 if features == "grid" else 0.5 / 8, seeds=tuple(range(runs)), episodes=episodes,
        eval_every=0, stages=(("final", 1.0),),
    )


def kernel_seconds(config: ExperimentConfig) -> tuple[int, float]:
    """Training steps and seconds of one :func:`rlcompare.run` of ``config`` (which compiles before it starts the
    clock)."""
    timings = run(config).meta["timings"]
    return int(timings["training_steps"]), float(timings["wall_seconds"])


def reference_seconds(config: ExperimentConfig) -> tuple[int, float]:
    """Training steps and seconds of the method's reference kernel training every seed of ``config``, runs spread
    over threads as rlcompare's are (:func:`~rlcompare.tabular.runs.over_runs`)."""
    kernel, extra = REFERENCES[config.algorithm]
    grid = config_grid(config)
    state = initial_state(list(config.seeds), grid.n_features, config.environment.n_actions,
                          config.environment.legal_moves)
    runs = len(config.seeds)
    returns, lengths = np.zeros((runs, config.episodes)), np.zeros((runs, config.episodes), np.int64)
    epsilons, extras = epsilon_schedule(config), tuple(getattr(config, name) for name in extra)

    def train(first: int, stop: int, episodes: np.ndarray = epsilons) -> None:
        kernel(state.rng[first:stop], episodes, grid, state.w[first:stop], state.w2[first:stop], config.alpha,
               config.gamma, config.max_steps, returns[first:stop], lengths[first:stop], *extras)

    train(0, 0, epsilons[:0])  # compile or load it outside the clock
    started = time.perf_counter()
    over_runs(train, runs)
    return int(lengths.sum()), time.perf_counter() - started


def kernel_steps_per_second(
    algorithm: str, threads: int, *, features: str = "grid", runs: int = 8, episodes: int = 2000, repeats: int = 3,
    env: str = "MountainCar-v0", adapter: bool = False,
) -> Measurement:
    """Median over ``repeats`` of training ``runs`` seeds with ε = 0.5 and no evaluation, on ``threads``
    threads, through :func:`rlcompare.run` (which compiles before it starts the clock)."""
    config = bench_config(algorithm, runs, episodes, features, env, adapter)
    with numba_threads(threads):
        timings = [kernel_seconds(config) for _ in range(repeats)]
    what = f"{algorithm} ({features})" if env == "MountainCar-v0" and not adapter else \
        f"{env}, {'Gymnasium adapter' if adapter else 'compiled port'}"
    return Measurement(what, threads, timings[0][0], statistics.median(t[1] for t in timings))


def kernel_and_reference(algorithm: str, threads: int, *, runs: int = 8, episodes: int = 2000, repeats: int = 5,
                         ) -> tuple[Measurement, Measurement]:
    """rlcompare's kernel and the method's reference kernel on the same seeds and threads, measured in turn
    ``repeats`` times, each first in every other turn (a load on the machine then weighs on both alike); each the
    median of its own."""
    config = bench_config(algorithm, runs, episodes)
    ours: list[tuple[int, float]] = []
    plain: list[tuple[int, float]] = []
    with numba_threads(threads):
        for turn in range(repeats):
            for measure, times in [(kernel_seconds, ours), (reference_seconds, plain)][::1 - 2 * (turn % 2)]:
                times.append(measure(config))
    return (Measurement(f"{algorithm} (grid)", threads, ours[0][0], statistics.median(t[1] for t in ours)),
            Measurement(f"{algorithm}, reference kernel", threads, plain[0][0], statistics.median(t[1] for t in plain)))


def gymnasium_steps_per_second(env: str = "MountainCar-v0", steps: int = 60_000, seed: int = 0) -> Measurement:
    """A plain Python loop of tabular Q-Learning on ``gymnasium.make(env)``, on the environment's default grid
    (or its states) and step limit."""
    config = ExperimentConfig(env=env)
    spec = config.environment
    environment = gym.make(env, max_episode_steps=config.max_steps)
    state_of: Callable[[Any], int]
    if spec.n_states:
        n_states, state_of = spec.n_states, int
    else:
        grid = config_grid(config)
        n_states = grid.n_cells

        def state_of(observation: Any) -> int:
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
