"""Steps per second of the fused kernels against a plain Gymnasium + numpy loop, measured in one run.

One step is what tabular control does per time step: choose an ε-greedy action, step the environment,
discretize the observation and update the table. The Gymnasium loop is the 1x reference of
``DESIGN.md``: ``gymnasium.make("MountainCar-v0")`` with ``DiscretizeObservation`` and numpy.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass

import gymnasium as gym
import numba
import numpy as np

from rlcompare.engine.tabular import ALGORITHM_CODES, Settings, allocate_records, initial_state, train_runs
from rlcompare.envs import mountain_car
from rlcompare.envs.discretize import make_grid


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
    algorithm: str, threads: int, runs: int = 8, episodes: int = 2000, repeats: int = 3
) -> Measurement:
    """Median over ``repeats`` of a training call with ε = 0.5, no evaluation, on ``threads`` threads."""
    grid = make_grid(mountain_car.OBSERVATION_LOW, mountain_car.OBSERVATION_HIGH, 20)
    settings = Settings(ALGORITHM_CODES[algorithm], 0.05, 0.9, 1000, False, 0)
    epsilons = np.full(episodes, 0.5)
    previous = numba.get_num_threads()
    numba.set_num_threads(threads)
    try:
        timings, steps = [], 0
        for _ in range(repeats + 1):  # the first call may compile; it is not timed
            state = initial_state(list(range(runs)), grid.n_cells, mountain_car.N_ACTIONS)
            records = allocate_records(runs, episodes, 0, 1, np.zeros(0, dtype=np.int64), state.q.shape[1:])
            started = time.perf_counter()
            train_runs(settings, state, grid, epsilons, 0, episodes, records)
            timings.append(time.perf_counter() - started)
            steps = int(records.lengths.sum())
    finally:
        numba.set_num_threads(previous)
    return Measurement(f"{algorithm} kernel", threads, steps, statistics.median(timings[1:]))


def gymnasium_steps_per_second(steps: int = 60_000, seed: int = 0) -> Measurement:
    """A plain Python loop of tabular Q-Learning on ``gymnasium.make("MountainCar-v0")``."""
    env = gym.wrappers.DiscretizeObservation(gym.make("MountainCar-v0", max_episode_steps=1000), bins=20)
    rng = np.random.default_rng(seed)
    q = np.zeros((env.observation_space.n, env.action_space.n))
    alpha, gamma, epsilon = 0.05, 0.9, 0.5
    state, _ = env.reset(seed=seed)
    started = time.perf_counter()
    for _ in range(steps):
        action = int(rng.integers(3)) if rng.random() < epsilon else int(np.argmax(q[state]))
        next_state, reward, terminated, truncated, _ = env.step(action)
        target = reward if terminated else reward + gamma * np.max(q[next_state])
        q[state, action] += alpha * (target - q[state, action])
        state = env.reset()[0] if terminated or truncated else next_state
    return Measurement("gymnasium loop", 1, steps, time.perf_counter() - started)


def run_benchmark(report: Callable[[Measurement], None] = lambda m: None) -> list[Measurement]:
    """Every measurement, reported as it is taken."""
    threads = numba.config.NUMBA_NUM_THREADS
    measurements = [gymnasium_steps_per_second()]
    report(measurements[-1])
    for algorithm in ("q_learning", "sarsa"):
        for n in sorted({1, threads}):
            measurements.append(kernel_steps_per_second(algorithm, n))
            report(measurements[-1])
    return measurements
