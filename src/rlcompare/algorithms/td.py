"""One-step temporal-difference control: the paper's Algorithms 1 and 2.

Both rules move ``Q(s, a)`` a step ``alpha`` toward a target (Sutton and Barto, 2nd ed., section 6.4 for
SARSA, section 6.5 for Q-Learning). They differ only in how the target values the next state:

- Q-Learning (Algorithm 1, off-policy): ``R + gamma * max_a Q(s', a)``, the greedy target policy.
- SARSA (Algorithm 2, on-policy): ``R + gamma * Q(s', a')`` with ``a'`` the action the behaviour
  policy actually takes next.
- Expected SARSA (section 6.6): ``R + gamma * sum_a pi(a | s') Q(s', a)`` for an ε-greedy target policy;
  with the behaviour's ε it is on-policy, with ε = 0 it is Q-Learning.
- Double Q-Learning (section 6.7): one estimate picks the best next action, the other values it.

At a terminal ``s'`` the value of the next state is zero and the target is ``R`` alone. An episode cut by
the time limit is not terminal: its last target still bootstraps (Pardo et al. 2018), unless the caller
asks for the old Gym behaviour of treating the cut as terminal.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(inline="always")
def q_learning_target(reward: float, q_next: np.ndarray, gamma: float, terminal: bool) -> float:
    """``R + gamma * max_a Q(s', a)``; ``R`` when ``s'`` is terminal (Algorithm 1, line 7)."""
    if terminal:
        return reward
    best = q_next[0]
    for value in q_next[1:]:
        best = max(best, value)
    return reward + gamma * best


@njit(inline="always")
def sarsa_target(reward: float, q_next_taken: float, gamma: float, terminal: bool) -> float:
    """``R + gamma * Q(s', a')`` for the action ``a'`` taken next; ``R`` when terminal (Algorithm 2, line 6)."""
    if terminal:
        return reward
    return reward + gamma * q_next_taken


@njit(inline="always")
def expected_sarsa_target(reward: float, q_next: np.ndarray, epsilon: float, gamma: float, terminal: bool) -> float:
    """``R + gamma * E_pi[Q(s', A)]`` for ε-greedy ``pi`` whose greedy share is split among tied maxima."""
    if terminal:
        return reward
    best, ties = q_next[0], 1
    for value in q_next[1:]:
        if value > best:
            best, ties = value, 1
        elif value == best:
            ties += 1
    explore = epsilon / q_next.size
    expected = 0.0
    for value in q_next:
        expected += (explore + (1.0 - epsilon) / ties if value == best else explore) * value
    return reward + gamma * expected


@njit(inline="always")
def double_q_target(reward: float, q_next: np.ndarray, q_next_other: np.ndarray, gamma: float,
                    terminal: bool) -> float:
    """``R + gamma * Q2(s', argmax_a Q1(s', a))``: ``q_next`` picks (first maximum), ``q_next_other`` values."""
    if terminal:
        return reward
    best = 0
    for action in range(1, q_next.size):
        if q_next[action] > q_next[best]:
            best = action
    return reward + gamma * q_next_other[best]


@njit(inline="always")
def td_update(q: np.ndarray, state: int, action: int, target: float, alpha: float) -> None:
    """``Q(s, a) <- Q(s, a) + alpha * (target - Q(s, a))``, in place."""
    q[state, action] += alpha * (target - q[state, action])
