"""Steps per second of the fused kernels against a plain reference kernel of each method and a plain Gymnasium +
numpy loop, measured in one run.

One step is what tabular control does per time step: choose an ε-greedy action, step the environment,
discretize the observation and update the table. The Gymnasium loop is the 1x reference of
``DESIGN.md``: ``gymnasium.make(env)``, the observation put on the same grid as the kernels' with numpy
(``DiscretizeObservation`` does the same where the box is bounded), and the table updated in numpy.
The reference kernels (:data:`REFERENCES`) are the yardstick of the compiled engine: each method written by hand
in numba for tabular Mountain Car alone, doing the same training, so a row's ratio to its reference is what
rlcompare's composition (environments, features and methods chosen by type, records, evaluation hooks) costs
or saves. Every environment is measured three ways: the Gymnasium loop, the compiled port, and the kernels
stepping Gymnasium through the adapter.
"""

from __future__ import annotations

import contextlib
import math
import os
import platform
import statistics
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace
from datetime import datetime, timezone
from pathlib import Path

import gymnasium as gym
import numba
import numpy as np

from rlcompare.algorithms.registry import METHODS
from rlcompare.compiled import njit
from rlcompare.envs.discretize import UniformGrid, cell_indices, make_grid
from rlcompare.envs.features import grid_bounds, make_features
from rlcompare.envs.registry import PORTS, TABLE_ENVIRONMENTS, environment
from rlcompare.experiment import store
from rlcompare.experiment.runner import run
from rlcompare.machine import versions
from rlcompare.rng import next_double
from rlcompare.tabular.config import ExperimentConfig
from rlcompare.tabular.runs import over_runs
from rlcompare.tabular.state import initial_state
from rlcompare.tabular.train import epsilon_schedule

ONE_STEP = tuple(name for name, m in METHODS.items() if m.one_step)
MULTI_STEP = tuple(name for name, m in METHODS.items() if m.family not in ("baseline", "one-step"))
"""The other learners: n-step, traces and policy gradient, benchmarked on shorter runs."""
PORT_EPISODES = {name: environment(name).bench_episodes for name in (*PORTS, *TABLE_ENVIRONMENTS)
                 if environment(name).bench_episodes}
"""Episodes per seed of Q-Learning with ε = 0.5 that make about a million steps on each port (its entry's)."""


# --- plain reference kernels ----------------------------------------------------------------------------
#
# The yardstick of the kernel rows: for each method, a kernel written by hand for tabular Mountain Car on the
# 20 x 20 grid and nothing else, with the dynamics, the grid and the update inline. Each trains every run of
# ``w`` (runs, cells, actions) over the episodes of ``epsilons`` and keeps what rlcompare's records keep per
# episode (return and length); it draws from the same per-run streams (``rng[run, 0]`` resets, ``rng[run, 1]``
# the agent's choices) in the same order, so its returns equal rlcompare's (tests/test_benchmark.py checks it).


@njit(inline="always")
def _mountain_car(position: float, velocity: float, action: int) -> tuple[float, float, bool]:
    """Gymnasium's MountainCar-v0 step: ``(position, velocity, terminated)``; every reward is -1."""
    velocity = min(max(velocity + ((action - 1) * 0.001 + math.cos(3 * position) * (-0.0025)), -0.07), 0.07)
    position = min(max(position + velocity, -1.2), 0.6)
    if position == -1.2 and velocity < 0:
        velocity = 0.0
    return position, velocity, position >= 0.5 and velocity >= 0.0


@njit(inline="always")
def _bin(x: float, low: float, scale: float, edges: np.ndarray) -> int:
    """``np.digitize(x, edges)`` from a first guess (``DiscretizeObservation``'s cell of one dimension)."""
    last = edges.size
    guess = (x - low) * scale
    cell = 0 if guess < 0.0 else (last if guess >= last else int(guess))
    while cell > 0 and x < edges[cell - 1]:
        cell -= 1
    while cell < last and x >= edges[cell]:
        cell += 1
    return cell


@njit(inline="always")
def _cell(grid: UniformGrid, position: float, velocity: float) -> int:
    """The grid's cell of the observation Gymnasium returns (the state rounded to float32)."""
    bins = grid.bins[1]
    return (_bin(np.float32(position), grid.low[0], grid.scale[0], grid.edges[0]) * bins
            + _bin(np.float32(velocity), grid.low[1], grid.scale[1], grid.edges[1]))


@njit(inline="always")
def _start(rng: np.ndarray) -> tuple[float, float]:
    """Gymnasium's reset: position uniform in [-0.6, -0.4), velocity 0."""
    return -0.6 + 0.2 * next_double(rng), 0.0


@njit(inline="always")
def _epsilon_greedy(row: np.ndarray, epsilon: float, rng: np.ndarray) -> int:
    """A uniform action with probability ε, else a greedy one, ties broken uniformly."""
    if next_double(rng) < epsilon:
        return int(next_double(rng) * row.size)
    best, ties = 0, 1
    for a in range(1, row.size):
        if row[a] > row[best]:
            best, ties = a, 1
        elif row[a] == row[best]:
            ties += 1
    if ties == 1:
        return best
    pick = int(next_double(rng) * ties)
    for a in range(best, row.size):
        if row[a] == row[best]:
            if pick == 0:
                return a
            pick -= 1
    return best


@njit(cache=True, nogil=True)
def reference_q_learning(rng, epsilons, grid, w, w2, alpha, gamma, limit, returns, lengths):
    """Tabular Q-Learning (the paper's Algorithm 1)."""
    for i in range(w.shape[0]):
        q, env_rng, agent_rng = w[i], rng[i, 0], rng[i, 1]
        for episode in range(epsilons.size):
            epsilon = epsilons[episode]
            position, velocity = _start(env_rng)
            s = _cell(grid, position, velocity)
            action = _epsilon_greedy(q[s], epsilon, agent_rng)
            total, steps = 0.0, 0
            while True:
                position, velocity, terminated = _mountain_car(position, velocity, action)
                total += -1.0
                steps += 1
                s_next = _cell(grid, position, velocity)
                target = -1.0
                if not terminated:
                    target += gamma * max(q[s_next, 0], q[s_next, 1], q[s_next, 2])
                q[s, action] += alpha * (target - q[s, action])
                if terminated or steps >= limit:
                    break
                action = _epsilon_greedy(q[s_next], epsilon, agent_rng)
                s = s_next
            returns[i, episode], lengths[i, episode] = total, steps


@njit(cache=True, nogil=True)
def reference_sarsa(rng, epsilons, grid, w, w2, alpha, gamma, limit, returns, lengths):
    """Tabular SARSA (the paper's Algorithm 2): A' is drawn before the update, which bootstraps on it."""
    for i in range(w.shape[0]):
        q, env_rng, agent_rng = w[i], rng[i, 0], rng[i, 1]
        for episode in range(epsilons.size):
            epsilon = epsilons[episode]
            position, velocity = _start(env_rng)
            s = _cell(grid, position, velocity)
            action = _epsilon_greedy(q[s], epsilon, agent_rng)
            total, steps = 0.0, 0
            while True:
                position, velocity, terminated = _mountain_car(position, velocity, action)
                total += -1.0
                steps += 1
                s_next = _cell(grid, position, velocity)
                target, next_action = -1.0, 0
                if not terminated:
                    next_action = _epsilon_greedy(q[s_next], epsilon, agent_rng)
                    target += gamma * q[s_next, next_action]
                q[s, action] += alpha * (target - q[s, action])
                if terminated or steps >= limit:
                    break
                s, action = s_next, next_action
            returns[i, episode], lengths[i, episode] = total, steps


@njit(cache=True, nogil=True)
def reference_expected_sarsa(rng, epsilons, grid, w, w2, alpha, gamma, limit, returns, lengths):
    """Tabular Expected SARSA (6.6), on-policy: the target is the ε-greedy policy's mean of q(S', .), the greedy
    share split among tied maxima."""
    n_actions = w.shape[2]
    for i in range(w.shape[0]):
        q, env_rng, agent_rng = w[i], rng[i, 0], rng[i, 1]
        for episode in range(epsilons.size):
            epsilon = epsilons[episode]
            position, velocity = _start(env_rng)
            s = _cell(grid, position, velocity)
            action = _epsilon_greedy(q[s], epsilon, agent_rng)
            total, steps = 0.0, 0
            while True:
                position, velocity, terminated = _mountain_car(position, velocity, action)
                total += -1.0
                steps += 1
                s_next = _cell(grid, position, velocity)
                target = -1.0
                if not terminated:
                    best, ties = q[s_next, 0], 1
                    for a in range(1, n_actions):
                        if q[s_next, a] > best:
                            best, ties = q[s_next, a], 1
                        elif q[s_next, a] == best:
                            ties += 1
                    explore = epsilon / n_actions
                    greedy, expected = explore + (1.0 - epsilon) / ties, 0.0
                    for a in range(n_actions):
                        expected += (greedy if q[s_next, a] == best else explore) * q[s_next, a]
                    target += gamma * expected
                q[s, action] += alpha * (target - q[s, action])
                if terminated or steps >= limit:
                    break
                action = _epsilon_greedy(q[s_next], epsilon, agent_rng)
                s = s_next
            returns[i, episode], lengths[i, episode] = total, steps


@njit(cache=True, nogil=True)
def reference_double_q_learning(rng, epsilons, grid, w, w2, alpha, gamma, limit, returns, lengths):
    """Tabular Double Q-Learning (6.7): ε-greedy in Q1 + Q2; a fair coin picks the table that learns, which
    picks the next action that the other values."""
    n_actions = w.shape[2]
    both = np.empty(n_actions)
    for i in range(w.shape[0]):
        q1, q2, env_rng, agent_rng = w[i], w2[i], rng[i, 0], rng[i, 1]
        for episode in range(epsilons.size):
            epsilon = epsilons[episode]
            position, velocity = _start(env_rng)
            s = _cell(grid, position, velocity)
            for a in range(n_actions):
                both[a] = q1[s, a] + q2[s, a]
            action = _epsilon_greedy(both, epsilon, agent_rng)
            total, steps = 0.0, 0
            while True:
                position, velocity, terminated = _mountain_car(position, velocity, action)
                total += -1.0
                steps += 1
                s_next = _cell(grid, position, velocity)
                heads = next_double(agent_rng) < 0.5
                learner, other = (q1, q2) if heads else (q2, q1)
                target = -1.0
                if not terminated:
                    best = 0
                    for a in range(1, n_actions):
                        if learner[s_next, a] > learner[s_next, best]:
                            best = a
                    target += gamma * other[s_next, best]
                learner[s, action] += alpha * (target - learner[s, action])
                if terminated or steps >= limit:
                    break
                for a in range(n_actions):
                    both[a] = q1[s_next, a] + q2[s_next, a]
                action = _epsilon_greedy(both, epsilon, agent_rng)
                s = s_next
            returns[i, episode], lengths[i, episode] = total, steps


@njit(cache=True, nogil=True)
def reference_n_step_sarsa(rng, epsilons, grid, w, w2, alpha, gamma, limit, returns, lengths, n):
    """n-step SARSA (7.2), the book's box: S, A and R in ring buffers of n + 1; a time-limit cut bootstraps on
    q(S_T, A_T)."""
    size = n + 1
    states, actions, rewards, discounts = (np.zeros(size, np.int64), np.zeros(size, np.int64), np.zeros(size),
                                           np.empty(size))
    for j in range(size):
        discounts[j] = gamma ** j
    for i in range(w.shape[0]):
        q, env_rng, agent_rng = w[i], rng[i, 0], rng[i, 1]
        for episode in range(epsilons.size):
            epsilon = epsilons[episode]
            position, velocity = _start(env_rng)
            states[0] = _cell(grid, position, velocity)
            actions[0] = _epsilon_greedy(q[states[0]], epsilon, agent_rng)
            horizon, cut, t, total = limit + n + 1, False, 0, 0.0
            while True:
                if t < horizon:
                    position, velocity, terminated = _mountain_car(position, velocity, actions[t % size])
                    total += -1.0
                    later = (t + 1) % size
                    rewards[later], states[later] = -1.0, _cell(grid, position, velocity)
                    if terminated or t + 1 >= limit:
                        horizon, cut = t + 1, not terminated
                    if not terminated:
                        actions[later] = _epsilon_greedy(q[states[later]], epsilon, agent_rng)
                tau = t - n + 1
                if tau >= 0:
                    end, ret = min(tau + n, horizon), 0.0
                    for k in range(tau + 1, end + 1):
                        ret += discounts[k - tau - 1] * rewards[k % size]
                    if tau + n < horizon or cut:
                        ret += discounts[end - tau] * q[states[end % size], actions[end % size]]
                    s, a = states[tau % size], actions[tau % size]
                    q[s, a] += alpha * (ret - q[s, a])
                if tau == horizon - 1:
                    break
                t += 1
            returns[i, episode], lengths[i, episode] = total, horizon


@njit(inline="always")
def _lambda_kernel(rng, epsilons, grid, w, alpha, gamma, limit, returns, lengths, lam, watkins):
    """SARSA(λ) (12.7) or Watkins's Q(λ) (12.10) with replacing traces, kept on the list of the pairs visited
    in the episode (``touched``): decaying and applying them costs that list, not the table."""
    n_actions = w.shape[2]
    z, listed, touched = np.zeros(w[0].size), np.zeros(w[0].size, np.bool_), np.empty(w[0].size, np.int64)
    for i in range(w.shape[0]):
        q, env_rng, agent_rng = w[i], rng[i, 0], rng[i, 1]
        flat = q.reshape(q.size)
        for episode in range(epsilons.size):
            epsilon = epsilons[episode]
            position, velocity = _start(env_rng)
            s = _cell(grid, position, velocity)
            action = _epsilon_greedy(q[s], epsilon, agent_rng)
            total, steps, count = 0.0, 0, 0
            while True:
                position, velocity, terminated = _mountain_car(position, velocity, action)
                total += -1.0
                steps += 1
                delta, pair = -1.0 - q[s, action], s * n_actions + action
                if not listed[pair]:
                    listed[pair], touched[count], count = True, pair, count + 1
                z[pair] = 1.0
                s_next, next_action, exploratory = _cell(grid, position, velocity), 0, False
                if not terminated:
                    next_action = _epsilon_greedy(q[s_next], epsilon, agent_rng)
                    best = max(q[s_next, 0], q[s_next, 1], q[s_next, 2])
                    exploratory = q[s_next, next_action] < best
                    delta += gamma * (best if watkins else q[s_next, next_action])
                step_size = alpha * delta
                for k in range(count):
                    flat[touched[k]] += step_size * z[touched[k]]
                if terminated or steps >= limit:
                    break
                if watkins and exploratory:
                    for k in range(count):
                        z[touched[k]], listed[touched[k]] = 0.0, False
                    count = 0
                else:
                    for k in range(count):
                        z[touched[k]] *= gamma * lam
                s, action = s_next, next_action
            for k in range(count):
                z[touched[k]], listed[touched[k]] = 0.0, False
            returns[i, episode], lengths[i, episode] = total, steps


@njit(cache=True, nogil=True)
def reference_sarsa_lambda(rng, epsilons, grid, w, w2, alpha, gamma, limit, returns, lengths, lam):
    """SARSA(λ), replacing traces."""
    _lambda_kernel(rng, epsilons, grid, w, alpha, gamma, limit, returns, lengths, lam, False)


@njit(cache=True, nogil=True)
def reference_q_lambda(rng, epsilons, grid, w, w2, alpha, gamma, limit, returns, lengths, lam):
    """Watkins's Q(λ), replacing traces, every trace cut after an exploratory action."""
    _lambda_kernel(rng, epsilons, grid, w, alpha, gamma, limit, returns, lengths, lam, True)


@njit(inline="always")
def _softmax(h: np.ndarray, pi: np.ndarray) -> None:
    """``pi = exp(h) / sum(exp(h))``, shifted by the largest preference."""
    top, total = max(h[0], h[1], h[2]), 0.0
    for a in range(h.size):
        pi[a] = 1.0 if h[a] == top else math.exp(h[a] - top)
        total += pi[a]
    for a in range(h.size):
        pi[a] /= total


@njit(cache=True, nogil=True)
def reference_reinforce(rng, epsilons, grid, w, w2, alpha, gamma, limit, returns, lengths):
    """REINFORCE as the paper's Algorithm 3 writes it (no γ^t): the softmax policy over the preferences acts for
    a whole episode, then each step moves the preferences of its state by α G_t ∇ ln π(A_t | S_t)."""
    n_actions = w.shape[2]
    states, actions, rewards, to_go = (np.empty(limit, np.int64), np.empty(limit, np.int64), np.empty(limit),
                                       np.empty(limit))
    pi = np.empty(n_actions)
    for i in range(w.shape[0]):
        theta, env_rng, agent_rng = w[i], rng[i, 0], rng[i, 1]
        for episode in range(epsilons.size):
            position, velocity = _start(env_rng)
            total, steps, terminated = 0.0, 0, False
            while not terminated and steps < limit:
                s = _cell(grid, position, velocity)
                _softmax(theta[s], pi)
                u, action, cumulative = next_double(agent_rng), n_actions - 1, 0.0
                for a in range(n_actions - 1):
                    cumulative += pi[a]
                    if u < cumulative:
                        action = a
                        break
                states[steps], actions[steps] = s, action
                position, velocity, terminated = _mountain_car(position, velocity, action)
                rewards[steps] = -1.0
                total += -1.0
                steps += 1
            ret = 0.0
            for t in range(steps - 1, -1, -1):
                ret = rewards[t] + gamma * ret
                to_go[t] = ret
            for t in range(steps):
                s = states[t]
                _softmax(theta[s], pi)
                for a in range(n_actions):
                    theta[s, a] += alpha * to_go[t] * ((1.0 if a == actions[t] else 0.0) - pi[a])
            returns[i, episode], lengths[i, episode] = total, steps


REFERENCES: dict[str, tuple[Callable, tuple[str, ...]]] = {
    "q_learning": (reference_q_learning, ()),
    "sarsa": (reference_sarsa, ()),
    "expected_sarsa": (reference_expected_sarsa, ()),
    "double_q_learning": (reference_double_q_learning, ()),
    "n_step_sarsa": (reference_n_step_sarsa, ("n",)),
    "sarsa_lambda": (reference_sarsa_lambda, ("lam",)),
    "q_lambda": (reference_q_lambda, ("lam",)),
    "reinforce": (reference_reinforce, ()),
}
"""Each method's reference kernel and the configuration fields it takes after the common arguments."""


@dataclass(frozen=True)
class Measurement:
    label: str
    threads: int
    steps: int
    seconds: float
    reference: Measurement | None = None
    """The method's reference kernel on the same seeds and threads, measured in turn with this one (kernel rows of
    the methods in :data:`REFERENCES`)."""
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

    def as_dict(self) -> dict:
        return {"label": self.label, "threads": self.threads, "steps": self.steps, "seconds": self.seconds,
                "steps_per_second": self.steps_per_second, "cpu_seconds": self.cpu_seconds}


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
    return timings["training_steps"], timings["wall_seconds"]


def reference_seconds(config: ExperimentConfig) -> tuple[int, float]:
    """Training steps and seconds of the method's reference kernel training every seed of ``config``, runs spread
    over threads as rlcompare's are (:func:`~rlcompare.tabular.runs.over_runs`)."""
    kernel, extra = REFERENCES[config.algorithm]
    grid = make_features(config.environment, config.features, config.bins, config.tilings, config.tiles,
                         config.hash_size, config.bounds)
    state = initial_state(list(config.seeds), grid.n_features, config.environment.n_actions)
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
    ours, plain = [], []
    with numba_threads(threads):
        for turn in range(repeats):
            for measure, times in [(kernel_seconds, ours), (reference_seconds, plain)][::1 - 2 * (turn % 2)]:
                times.append(measure(config))
    return (Measurement(f"{algorithm} (grid)", threads, ours[0][0], statistics.median(t[1] for t in ours)),
            Measurement(f"{algorithm}, reference kernel", threads, plain[0][0], statistics.median(t[1] for t in plain)))


@contextlib.contextmanager
def numba_threads(threads: int) -> Iterator[None]:
    previous = numba.get_num_threads()
    numba.set_num_threads(threads)
    try:
        yield
    finally:
        numba.set_num_threads(previous)


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
    learners (shorter runs), and two on tiles. A method with a reference kernel (:data:`REFERENCES`) is measured
    in turn with it, on the same seeds and threads."""
    threads = sorted({1, numba.config.NUMBA_NUM_THREADS})
    plan = [(algorithm, "grid", 2000) for algorithm in ONE_STEP]
    plan += [(algorithm, "grid", 300) for algorithm in MULTI_STEP]
    plan += [(algorithm, "tiles", 300) for algorithm in ("sarsa", "sarsa_lambda")]
    measurements = [gymnasium_steps_per_second(steps=30_000)]
    report(measurements[-1])
    for algorithm, features, episodes in plan:
        for n in threads:
            if features == "grid" and algorithm in REFERENCES:
                ours, plain = kernel_and_reference(algorithm, n, episodes=episodes)
                measurements.append(replace(ours, reference=plain))
            else:
                measurements.append(kernel_steps_per_second(algorithm, n, features=features, episodes=episodes))
            report(measurements[-1])
    return measurements


def study_threads(configs: list[ExperimentConfig], repeats: int = 3,
                  report: Callable[[Measurement], None] = lambda m: None) -> list[Measurement]:
    """Training every configuration of a study (evaluation rounds included) on 1 and on all threads, measured in
    turn ``repeats`` times; each the median of its own. Steps are training and evaluation steps."""
    threads = sorted({1, numba.config.NUMBA_NUM_THREADS})
    for config in configs:  # compile or load every loop before the clock starts
        run(replace(config, seeds=config.seeds[:1], episodes=1))
    timings: dict[int, list[tuple[int, float, float]]] = {n: [] for n in threads}
    for _ in range(repeats):
        for n in threads:
            with numba_threads(n):
                steps, started, cpu = 0, time.perf_counter(), time.process_time()
                for config in configs:
                    timing = run(config).meta["timings"]
                    steps += timing["training_steps"] + timing["evaluation_steps"]
                timings[n].append((steps, time.perf_counter() - started, time.process_time() - cpu))
    label = (f"{len(configs)} configurations x {len(configs[0].seeds)} seeds x {configs[0].episodes} episodes, "
             "evaluation included")
    measurements = []
    for n in threads:
        steps, seconds, cpu = timings[n][0][0], *(statistics.median(t[k] for t in timings[n]) for k in (1, 2))
        measurements.append(Measurement(label, n, steps, seconds, cpu_seconds=cpu))
    for measurement in measurements:
        report(measurement)
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
    """:func:`run_benchmark`'s measurements, each against its method's reference kernel (same seeds, same threads),
    the Gymnasium loop (the first) and its own 1 thread."""
    reference = measurements[0].steps_per_second
    single = {m.label: m.steps_per_second for m in measurements if m.threads == 1}
    rows = [(m.label, str(m.threads), f"{m.steps_per_second:,.0f}",
             "" if m.reference is None else f"{m.reference.steps_per_second:,.0f}",
             "" if m.vs_reference is None else f"{m.vs_reference:.2f}x",
             f"{m.steps_per_second / reference:,.0f}x", f"{m.steps_per_second / single[m.label]:.2f}x")
            for m in measurements]
    return BenchTable("Every algorithm on MountainCar-v0, 20 bins (one step: act, step, update)",
                      ("what", "threads", "steps/s", "reference kernel steps/s", "vs reference kernel",
                       "vs Gymnasium", "vs 1 thread"), rows,
                      ("reference kernel: the method written plainly by hand for tabular Mountain Car alone "
                       "(rlcompare.bench.tabular.REFERENCES), trained on the same seeds and threads in turn",))


def study_table(measurements: list[Measurement]) -> BenchTable:
    """:func:`study_threads`'s measurements, each against 1 thread."""
    single = measurements[0].steps_per_second
    rows = [(str(m.threads), f"{m.steps:,}", f"{m.seconds:.2f}", f"{m.steps_per_second:,.0f}",
             f"{m.steps_per_second / single:.2f}x", f"{(m.cpu_seconds or 0.0) / m.seconds:.2f}")
            for m in measurements]
    return BenchTable(f"The paper's study on threads: {measurements[0].label}",
                      ("threads", "steps", "seconds", "steps/s", "vs 1 thread", "cores used"), rows,
                      ("cores used: processor time over wall time (medians); below the threads, other work on the "
                       "machine had the rest",))


def kernel_rows(measurements: list[Measurement]) -> list[dict]:
    """:func:`run_benchmark`'s measurements as the JSON file keeps them: each kernel row with its ratios."""
    loop = measurements[0].steps_per_second
    single = {m.label: m.steps_per_second for m in measurements if m.threads == 1}
    return [{**m.as_dict(), "reference": None if m.reference is None else m.reference.as_dict(),
             "vs_reference": m.vs_reference, "vs_gymnasium": m.steps_per_second / loop,
             "vs_one_thread": m.steps_per_second / single[m.label]} for m in measurements[1:]]


BENCH_FILES = ("bench.json", "sweeps.json", "deep.json")
"""What ``rlcompare bench`` writes: the kernels, studies and ports; ``--sweeps``; ``--deep``."""


def read_bench_document(path: Path) -> tuple[str, list[BenchTable]]:
    """What :func:`bench_document` wrote to ``path``: a line saying when and where it measured, and its tables. A
    file of another shape is a :class:`~rlcompare.experiment.store.StoreError` naming it."""
    document = store.read_json(path)
    try:
        machine = document["machine"]
        said = (f"{path.name}: measured {document['created']} on {machine['processor']}, {machine['cpus']} CPUs, "
                f"{machine['numba_threads']} numba threads")
        tables = [BenchTable(str(t["title"]), tuple(map(str, t["columns"])),
                             [tuple(map(str, row)) for row in t["rows"]], tuple(map(str, t["notes"])))
                  for t in document["tables"]]
    except (KeyError, TypeError) as error:
        raise store.StoreError(f"{path}: not a benchmark rlcompare wrote (no {error})") from None
    return said, tables


def bench_document(tables: list[BenchTable], **sections: object) -> dict:
    """What ``rlcompare bench`` writes to ``bench.json``: when and where it measured, every table as printed, and
    the measurements of each section (``kernels``: :func:`kernel_rows`)."""
    return {"created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
            "machine": {"processor": platform.processor() or platform.machine(), "cpus": os.cpu_count(),
                        "numba_threads": numba.config.NUMBA_NUM_THREADS},
            "versions": versions(),
            "tables": [{"title": t.title, "columns": list(t.columns), "rows": [list(r) for r in t.rows],
                        "notes": list(t.notes)} for t in tables],
            **sections}


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
