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

from rlcompare.experiment.config import ExperimentConfig
from rlcompare.experiment.runner import run, uses_fast_path

FAST_ALGORITHMS = ("q_learning", "sarsa", "expected_sarsa", "double_q_learning")
GENERAL_ALGORITHMS = ("n_step_sarsa", "sarsa_lambda", "q_lambda", "reinforce", "reinforce_baseline")


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
    algorithm: str, threads: int, *, features: str = "grid", runs: int = 8, episodes: int = 2000, repeats: int = 3
) -> Measurement:
    """Median over ``repeats`` of training ``runs`` seeds with ε = 0.5 and no evaluation, on ``threads``
    threads, through :func:`rlcompare.run` (which compiles before it starts the clock)."""
    config = ExperimentConfig(
        algorithm=algorithm, schedule="constant", epsilon=0.5, features=features,
        alpha=0.05 if features == "grid" else 0.5 / 8, seeds=tuple(range(runs)), episodes=episodes,
        eval_every=0, stages=(("final", 1.0),),
    )
    previous = numba.get_num_threads()
    numba.set_num_threads(threads)
    try:
        timings = [run(config).meta["timings"] for _ in range(repeats)]
    finally:
        numba.set_num_threads(previous)
    path = "fast" if uses_fast_path(config) else "general"
    return Measurement(f"{algorithm} ({features}, {path} kernel)", threads, timings[0]["training_steps"],
                       statistics.median(t["wall_seconds"] for t in timings))


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
    """Every measurement, reported as it is taken: the Gymnasium loop, the paper's algorithms on the fast
    kernel, then every other algorithm on the general kernel (shorter runs, as it is slower), and two on tiles."""
    threads = sorted({1, numba.config.NUMBA_NUM_THREADS})
    plan = [(algorithm, "grid", 2000) for algorithm in FAST_ALGORITHMS]
    plan += [(algorithm, "grid", 300) for algorithm in GENERAL_ALGORITHMS]
    plan += [(algorithm, "tiles", 300) for algorithm in ("sarsa", "sarsa_lambda")]
    measurements = [gymnasium_steps_per_second()]
    report(measurements[-1])
    for algorithm, features, episodes in plan:
        for n in threads:
            measurements.append(kernel_steps_per_second(algorithm, n, features=features, episodes=episodes))
            report(measurements[-1])
    return measurements
