"""The reference kernels: the yardstick of the benchmark's kernel rows.

For each method, a kernel written by hand for tabular Mountain Car on the 20 x 20 grid and nothing else, with
the dynamics, the grid and the update inline (the greedy choice, ties broken at random, is
:mod:`rlcompare.algorithms.policies`', a loop over one row). Each trains every run of ``w`` (runs, cells, actions)
over the episodes of ``epsilons`` and keeps what rlcompare's records keep per episode (return and length); it draws
from the same per-run streams (``rng[run, 0]`` resets, ``rng[run, 1]`` the agent's choices) in the same order, so
its returns equal rlcompare's (tests/engines/test_benchmark.py checks it). A row's ratio to its reference is what
rlcompare's composition (environments, features and methods chosen by type, records, evaluation hooks) costs or
saves.

The one-step methods share one loop whose rule is a constant each kernel passes, as the two λ methods share
theirs: numba inlines the loop and the compiler drops the branches of the other rules.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from rlcompare.algorithms.policies import greedy_action, greedy_action_random_ties
from rlcompare.compiled import njit
from rlcompare.envs.discretize import UniformGrid
from rlcompare.rng import next_double

Q_LEARNING, SARSA, EXPECTED_SARSA, DOUBLE_Q_LEARNING = 0, 1, 2, 3
"""The rules of :func:`_one_step`."""


@njit(inline="always")
def _mountain_car(position: float, velocity: float, action: int) -> tuple[float, float, bool]:
    """Gymnasium's MountainCar-v0 step: ``(position, velocity, terminated)``; every reward is -1."""
    velocity = min(max(velocity + ((action - 1) * 0.001 + math.cos(3 * position) * (-0.0025)), -0.07), 0.07)
    position = min(max(position + velocity, -1.2), 0.6)
    if position == -1.2 and velocity < 0:
        velocity = 0.0
    return position, velocity, position >= 0.5 and velocity >= 0.0


@njit(inline="always")
def _bin(x: np.float32, low: float, scale: float, edges: np.ndarray) -> int:
    """``np.digitize(x, edges)`` from a first guess (``DiscretizeObservation``'s cell of one dimension)."""
    last: int = edges.size
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
    bins: int = grid.bins[1]
    return (_bin(np.float32(position), grid.low[0], grid.scale[0], grid.edges[0]) * bins
            + _bin(np.float32(velocity), grid.low[1], grid.scale[1], grid.edges[1]))


@njit(inline="always")
def _start(rng: np.ndarray) -> tuple[float, float]:
    """Gymnasium's reset: position uniform in [-0.6, -0.4), velocity 0."""
    return -0.6 + 0.2 * next_double(rng), 0.0


@njit(inline="always")
def _epsilon_greedy(row: np.ndarray, epsilon: float, rng: np.ndarray) -> int:
    """A uniform action with probability ε, else a greedy one, ties broken uniformly. The uniform draw is written
    out: through :func:`~rlcompare.algorithms.policies.uniform_action` Q-Learning's kernel ran at half its speed."""
    if next_double(rng) < epsilon:
        return int(next_double(rng) * row.size)
    return greedy_action_random_ties(row, rng)


@njit(inline="always")
def _expected_value(q: np.ndarray, s: int, epsilon: float) -> float:
    """The ε-greedy policy's mean of ``q[s]``, the greedy share split among tied maxima (Expected SARSA, 6.6)."""
    n_actions = q.shape[1]
    best, ties = q[s, 0], 1
    for a in range(1, n_actions):
        if q[s, a] > best:
            best, ties = q[s, a], 1
        elif q[s, a] == best:
            ties += 1
    explore = epsilon / n_actions
    greedy, expected = explore + (1.0 - epsilon) / ties, 0.0
    for a in range(n_actions):
        expected += (greedy if q[s, a] == best else explore) * q[s, a]
    return expected


@njit(inline="always")
def _act(q1: np.ndarray, q2: np.ndarray, s: int, both: np.ndarray, epsilon: float, rng: np.ndarray,
         double: bool) -> int:
    """ε-greedy in row ``s`` of ``q1``, or of ``q1 + q2`` (written into ``both``) for Double Q-Learning."""
    if double:
        for a in range(both.size):
            both[a] = q1[s, a] + q2[s, a]
        return _epsilon_greedy(both, epsilon, rng)
    return _epsilon_greedy(q1[s], epsilon, rng)


@njit(inline="always")
def _double_q_update(learner: np.ndarray, other: np.ndarray, s: int, action: int, s_next: int, terminated: bool,
                     alpha: float, gamma: float) -> None:
    """Double Q-Learning's update (6.7): the table that learns picks the next action, the other values it."""
    target = -1.0
    if not terminated:
        target += gamma * other[s_next, greedy_action(learner[s_next])]
    learner[s, action] += alpha * (target - learner[s, action])


@njit(inline="always")
def _one_step(rng: np.ndarray, epsilons: np.ndarray, grid: UniformGrid, w: np.ndarray, w2: np.ndarray,
              alpha: float, gamma: float, limit: int, returns: np.ndarray, lengths: np.ndarray, rule: int) -> None:
    """Q-Learning, SARSA, Expected SARSA or Double Q-Learning, by ``rule``. SARSA draws A' before its update,
    which bootstraps on it; the others draw it after. Double Q-Learning's fair coin picks the table that learns."""
    double, drawn_before = rule == DOUBLE_Q_LEARNING, rule == SARSA
    both = np.empty(w.shape[2])
    for i in range(w.shape[0]):
        q, q2, env_rng, agent_rng = w[i], w2[i], rng[i, 0], rng[i, 1]
        for episode in range(epsilons.size):
            epsilon = epsilons[episode]
            position, velocity = _start(env_rng)
            s = _cell(grid, position, velocity)
            action = _act(q, q2, s, both, epsilon, agent_rng, double)
            steps = 0
            while True:
                position, velocity, terminated = _mountain_car(position, velocity, action)
                steps += 1
                s_next, next_action = _cell(grid, position, velocity), 0
                if double:
                    learner, other = (q, q2) if next_double(agent_rng) < 0.5 else (q2, q)
                    _double_q_update(learner, other, s, action, s_next, terminated, alpha, gamma)
                else:
                    target = -1.0
                    if not terminated:
                        if drawn_before:
                            next_action = _act(q, q2, s_next, both, epsilon, agent_rng, double)
                            target += gamma * q[s_next, next_action]
                        elif rule == EXPECTED_SARSA:
                            target += gamma * _expected_value(q, s_next, epsilon)
                        else:
                            target += gamma * max(q[s_next, 0], q[s_next, 1], q[s_next, 2])
                    q[s, action] += alpha * (target - q[s, action])
                if terminated or steps >= limit:
                    break
                if not drawn_before:
                    next_action = _act(q, q2, s_next, both, epsilon, agent_rng, double)
                s, action = s_next, next_action
            returns[i, episode], lengths[i, episode] = -float(steps), steps


@njit(cache=True, nogil=True)
def reference_q_learning(rng: np.ndarray, epsilons: np.ndarray, grid: UniformGrid, w: np.ndarray, w2: np.ndarray,
                         alpha: float, gamma: float, limit: int, returns: np.ndarray, lengths: np.ndarray) -> None:
    """Tabular Q-Learning (the paper's Algorithm 1)."""
    _one_step(rng, epsilons, grid, w, w2, alpha, gamma, limit, returns, lengths, Q_LEARNING)


@njit(cache=True, nogil=True)
def reference_sarsa(rng: np.ndarray, epsilons: np.ndarray, grid: UniformGrid, w: np.ndarray, w2: np.ndarray,
                    alpha: float, gamma: float, limit: int, returns: np.ndarray, lengths: np.ndarray) -> None:
    """Tabular SARSA (the paper's Algorithm 2)."""
    _one_step(rng, epsilons, grid, w, w2, alpha, gamma, limit, returns, lengths, SARSA)


@njit(cache=True, nogil=True)
def reference_expected_sarsa(rng: np.ndarray, epsilons: np.ndarray, grid: UniformGrid, w: np.ndarray,
                             w2: np.ndarray, alpha: float, gamma: float, limit: int, returns: np.ndarray,
                             lengths: np.ndarray) -> None:
    """Tabular Expected SARSA (6.6), on-policy."""
    _one_step(rng, epsilons, grid, w, w2, alpha, gamma, limit, returns, lengths, EXPECTED_SARSA)


@njit(cache=True, nogil=True)
def reference_double_q_learning(rng: np.ndarray, epsilons: np.ndarray, grid: UniformGrid, w: np.ndarray,
                                w2: np.ndarray, alpha: float, gamma: float, limit: int, returns: np.ndarray,
                                lengths: np.ndarray) -> None:
    """Tabular Double Q-Learning (6.7): ε-greedy in Q1 + Q2."""
    _one_step(rng, epsilons, grid, w, w2, alpha, gamma, limit, returns, lengths, DOUBLE_Q_LEARNING)


@njit(cache=True, nogil=True)
def reference_n_step_sarsa(rng: np.ndarray, epsilons: np.ndarray, grid: UniformGrid, w: np.ndarray,
                           w2: np.ndarray, alpha: float, gamma: float, limit: int, returns: np.ndarray,
                           lengths: np.ndarray, n: int) -> None:
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
            horizon, cut, t = limit + n + 1, False, 0
            while True:
                if t < horizon:
                    position, velocity, terminated = _mountain_car(position, velocity, actions[t % size])
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
            returns[i, episode], lengths[i, episode] = -float(horizon), horizon


@njit(inline="always")
def _lambda(rng: np.ndarray, epsilons: np.ndarray, grid: UniformGrid, w: np.ndarray, alpha: float, gamma: float,
            limit: int, returns: np.ndarray, lengths: np.ndarray, lam: float, watkins: bool) -> None:
    """SARSA(λ) (12.7) or Watkins's Q(λ) (12.10) with replacing traces, kept on the list of the pairs visited
    in the episode (``touched``): decaying and applying them costs that list, not the table."""
    n_actions = w.shape[2]
    z, listed, touched = np.zeros(w[0].size), np.zeros(w[0].size, np.bool_), np.empty(w[0].size, np.int64)
    for i in range(w.shape[0]):
        q, env_rng, agent_rng = w[i], rng[i, 0], rng[i, 1]
        flat = q.reshape(q.size)
        for episode in range(epsilons.size):
            epsilon, steps, count = epsilons[episode], 0, 0
            position, velocity = _start(env_rng)
            s = _cell(grid, position, velocity)
            action = _epsilon_greedy(q[s], epsilon, agent_rng)
            while True:
                position, velocity, terminated = _mountain_car(position, velocity, action)
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
            returns[i, episode], lengths[i, episode] = -float(steps), steps


@njit(cache=True, nogil=True)
def reference_sarsa_lambda(rng: np.ndarray, epsilons: np.ndarray, grid: UniformGrid, w: np.ndarray,
                           w2: np.ndarray, alpha: float, gamma: float, limit: int, returns: np.ndarray,
                           lengths: np.ndarray, lam: float) -> None:
    """SARSA(λ), replacing traces."""
    _lambda(rng, epsilons, grid, w, alpha, gamma, limit, returns, lengths, lam, False)


@njit(cache=True, nogil=True)
def reference_q_lambda(rng: np.ndarray, epsilons: np.ndarray, grid: UniformGrid, w: np.ndarray, w2: np.ndarray,
                       alpha: float, gamma: float, limit: int, returns: np.ndarray, lengths: np.ndarray,
                       lam: float) -> None:
    """Watkins's Q(λ), replacing traces, every trace cut after an exploratory action."""
    _lambda(rng, epsilons, grid, w, alpha, gamma, limit, returns, lengths, lam, True)


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
def reference_reinforce(rng: np.ndarray, epsilons: np.ndarray, grid: UniformGrid, w: np.ndarray, w2: np.ndarray,
                        alpha: float, gamma: float, limit: int, returns: np.ndarray, lengths: np.ndarray) -> None:
    """REINFORCE as the paper's Algorithm 3 writes it (no γ^t): the softmax policy over the preferences acts for
    a whole episode, then each step moves the preferences of its state by α G_t ∇ ln π(A_t | S_t)."""
    n_actions = w.shape[2]
    states, actions, to_go = np.empty(limit, np.int64), np.empty(limit, np.int64), np.empty(limit)
    pi = np.empty(n_actions)
    for i in range(w.shape[0]):
        theta, env_rng, agent_rng = w[i], rng[i, 0], rng[i, 1]
        for episode in range(epsilons.size):
            position, velocity = _start(env_rng)
            steps, terminated = 0, False
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
                steps += 1
            ret = 0.0
            for t in range(steps - 1, -1, -1):
                ret = -1.0 + gamma * ret
                to_go[t] = ret
            for t in range(steps):
                s = states[t]
                _softmax(theta[s], pi)
                for a in range(n_actions):
                    theta[s, a] += alpha * to_go[t] * ((1.0 if a == actions[t] else 0.0) - pi[a])
            returns[i, episode], lengths[i, episode] = -float(steps), steps


REFERENCES: dict[str, tuple[Callable[..., None], tuple[str, ...]]] = {
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
