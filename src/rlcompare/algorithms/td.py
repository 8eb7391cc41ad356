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

Each method is a small named tuple of what it reads beyond α, γ and ε (its type picks its update when the
engine compiles) and an update of linear values ``q(s, a) = sum of w[i, a]`` over active features, so the
same rule updates the paper's Q-table and a tile coder's weights. ``draw_before`` says when the next action
A' is drawn: before updating ``q(S, A)`` as SARSA's box does, or after it, at the top of the loop, as
Algorithm 1 does (``docs/why.md``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from rlcompare.algorithms.linear import action_value, action_values, add_to_action
from rlcompare.algorithms.policies import largest
from rlcompare.compiled import njit
from rlcompare.rng import next_double


class Transition(NamedTuple):
    """One step of experience, (S, A, R, S', A'), the states given by their active features (a table's cell, or
    one tile per tiling); ``terminal``: S' ends the episode, so its value is zero."""

    s: int | np.ndarray
    action: int
    reward: float
    s_next: int | np.ndarray
    next_action: int
    terminal: bool


class Rates(NamedTuple):
    """The step size α, the discount γ and the behaviour's ε of the episode."""

    alpha: float
    gamma: float
    epsilon: float


class QLearning(NamedTuple):
    """Algorithm 1 (6.5)."""

    draw_before: bool


class Sarsa(NamedTuple):
    """Algorithm 2 (6.4)."""

    draw_before: bool


class ExpectedSarsa(NamedTuple):
    """Expected SARSA (6.6); ``target_epsilon`` < 0 means the behaviour's ε (on-policy)."""

    draw_before: bool
    target_epsilon: float


class DoubleQLearning(NamedTuple):
    """Double Q-Learning (6.7), with its second estimate in ``w2``."""

    draw_before: bool


class DoubleExpectedSarsa(NamedTuple):
    """Double Expected SARSA (Exercise 6.13), with its second estimate in ``w2``; ``target_epsilon`` as Expected
    SARSA's."""

    draw_before: bool
    target_epsilon: float


@njit(inline="always")
def q_learning_target(reward: float, q_next: np.ndarray, gamma: float, terminal: bool) -> float:
    """``R + gamma * max_a Q(s', a)``; ``R`` when ``s'`` is terminal (Algorithm 1, line 7)."""
    if terminal:
        return reward
    return reward + gamma * largest(q_next)


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
    return reward + gamma * expected_value(q_next, q_next, epsilon)


@njit(inline="always")
def expected_value(picks: np.ndarray, values: np.ndarray, epsilon: float) -> float:
    """``sum_a pi(a) values[a]`` for the policy ε-greedy in ``picks``, its greedy share split among tied maxima;
    over the legal actions only, where some are illegal (value −∞: :mod:`rlcompare.algorithms.policies`)."""
    best, ties, legal = picks[0], 1, int(picks[0] != -np.inf)
    for action in range(1, picks.size):
        value = picks[action]
        legal += value != -np.inf
        if value > best:
            best, ties = value, 1
        elif value == best:
            ties += 1
    explore = epsilon / legal
    greedy = explore + (1.0 - epsilon) / ties
    expected = 0.0
    for action in range(picks.size):
        if picks[action] != -np.inf:
            expected += (greedy if picks[action] == best else explore) * values[action]
    return expected


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
    target: float = reward + gamma * q_next_other[best]
    return target


@njit(inline="always")
def _step_toward(w: np.ndarray, s: int | np.ndarray, action: int, target: float, alpha: float) -> None:
    """``q(S, A) <- q(S, A) + alpha * (target - q(S, A))``, the semi-gradient form (9.5)."""
    add_to_action(w, s, action, alpha * (target - action_value(w, s, action)))


@njit(inline="always")
def q_learning_update(rule: QLearning, w: np.ndarray, w2: np.ndarray, t: Transition, rates: Rates,
                      rng: np.ndarray, q_next: np.ndarray, scratch: np.ndarray) -> None:
    """Algorithm 1, line 7: ``q(S, A)`` toward ``R + gamma * max_a q(S', a)``."""
    target = q_learning_target(t.reward, action_values(w, t.s_next, q_next), rates.gamma, t.terminal)
    _step_toward(w, t.s, t.action, target, rates.alpha)


@njit(inline="always")
def sarsa_update(rule: Sarsa, w: np.ndarray, w2: np.ndarray, t: Transition, rates: Rates, rng: np.ndarray,
                 q_next: np.ndarray, scratch: np.ndarray) -> None:
    """Algorithm 2, line 6: toward ``R + gamma * q(S', A')``, ``A'`` drawn before the update whatever the order
    (the method's entry says so: :attr:`~rlcompare.algorithms.registry.Method.target_takes_next_action`)."""
    taken_value = action_value(w, t.s_next, t.next_action)
    _step_toward(w, t.s, t.action, sarsa_target(t.reward, taken_value, rates.gamma, t.terminal), rates.alpha)


@njit(inline="always")
def expected_sarsa_update(rule: ExpectedSarsa, w: np.ndarray, w2: np.ndarray, t: Transition, rates: Rates,
                          rng: np.ndarray, q_next: np.ndarray, scratch: np.ndarray) -> None:
    """6.6: toward ``R + gamma * E_pi[q(S', A)]`` for the ε-greedy target policy."""
    target_epsilon = rates.epsilon if rule.target_epsilon < 0 else rule.target_epsilon
    target = expected_sarsa_target(t.reward, action_values(w, t.s_next, q_next), target_epsilon, rates.gamma,
                                   t.terminal)
    _step_toward(w, t.s, t.action, target, rates.alpha)


@njit(inline="always")
def double_q_update(rule: DoubleQLearning, w: np.ndarray, w2: np.ndarray, t: Transition, rates: Rates,
                    rng: np.ndarray, q_next: np.ndarray, scratch: np.ndarray) -> None:
    """6.7: a fair coin picks which estimate learns; it picks the next action, the other values it."""
    if next_double(rng) < 0.5:
        _double_q_step(w, w2, t, rates, q_next, scratch)
    else:
        _double_q_step(w2, w, t, rates, q_next, scratch)


@njit(inline="always")
def _double_q_step(learner: np.ndarray, other: np.ndarray, t: Transition, rates: Rates, q_next: np.ndarray,
                   scratch: np.ndarray) -> None:
    target = double_q_target(t.reward, action_values(learner, t.s_next, q_next),
                             action_values(other, t.s_next, scratch), rates.gamma, t.terminal)
    _step_toward(learner, t.s, t.action, target, rates.alpha)


@njit(inline="always")
def double_expected_sarsa_update(rule: DoubleExpectedSarsa, w: np.ndarray, w2: np.ndarray, t: Transition,
                                 rates: Rates, rng: np.ndarray, q_next: np.ndarray, scratch: np.ndarray) -> None:
    """Exercise 6.13: a fair coin picks the estimate that learns; the target policy is ε-greedy in it, the other
    values it: ``R + gamma * sum_a pi_1(a | S') Q2(S', a)``."""
    target_epsilon = rates.epsilon if rule.target_epsilon < 0 else rule.target_epsilon
    if next_double(rng) < 0.5:
        _double_expected_step(w, w2, t, rates, target_epsilon, q_next, scratch)
    else:
        _double_expected_step(w2, w, t, rates, target_epsilon, q_next, scratch)


@njit(inline="always")
def _double_expected_step(learner: np.ndarray, other: np.ndarray, t: Transition, rates: Rates, epsilon: float,
                          q_next: np.ndarray, scratch: np.ndarray) -> None:
    target = t.reward
    if not t.terminal:
        picks, values = action_values(learner, t.s_next, q_next), action_values(other, t.s_next, scratch)
        target += rates.gamma * expected_value(picks, values, epsilon)
    _step_toward(learner, t.s, t.action, target, rates.alpha)


@njit(inline="always")
def double_q_values(rule: DoubleQLearning, w: np.ndarray, w2: np.ndarray, s: int | np.ndarray, out: np.ndarray,
                    scratch: np.ndarray) -> np.ndarray:
    """What Double Q-Learning's behaviour is ε-greedy in, and its greedy policy greedy in: ``Q1 + Q2``."""
    first, second = action_values(w, s, out), action_values(w2, s, scratch)
    for a in range(out.size):
        out[a] = first[a] + second[a]
    return out


@njit(inline="always")
def mean_of_tables(rule: DoubleQLearning, w: np.ndarray, w2: np.ndarray, out: np.ndarray) -> None:
    """Double Q-Learning's single estimate, for snapshots and maps: ``(Q1 + Q2) / 2``, into ``out``."""
    for i in range(w.shape[0]):
        for a in range(w.shape[1]):
            out[i, a] = (w[i, a] + w2[i, a]) / 2
