"""REINFORCE (Sutton and Barto, 13.3; the paper's Algorithm 3) and REINFORCE with baseline (13.4), for a softmax
policy over linear action preferences ``h(s, a) = sum of theta[i, a]`` over the active features of ``s``.

After the episode, for each t: ``theta += alpha * gamma^t * (G_t - v(S_t)) * grad ln pi(A_t | S_t)``, with
``v`` a learned state value ``sum of baseline[i, 0]`` (13.4) or 0 (13.3). The paper's Algorithm 3 writes the
step without ``gamma^t``; ``discount_gradient`` chooses. For a softmax over linear preferences,
``d ln pi(A_t | S_t) / d h(S_t, a) = 1{a = A_t} - pi(a | S_t)`` (13.9).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from rlcompare.algorithms.linear import action_value, action_values, add_to_action
from rlcompare.algorithms.softmax import softmax
from rlcompare.compiled import njit


class Reinforce(NamedTuple):
    """REINFORCE, with a baseline when ``baseline_alpha`` > 0."""

    discount_gradient: bool
    """Scale the step at time t by γ^t (the book's 13.3 box) or not (the paper's Algorithm 3)."""
    baseline_alpha: float
    """Step size of the state-value baseline (13.4); 0: no baseline."""


@njit(inline="always")
def returns_to_go(rewards: np.ndarray, steps: int, gamma: float) -> np.ndarray:
    """``G_t = R_{t+1} + gamma G_{t+1}`` for t < ``steps``, from the end; a time-limit cut ends it there."""
    out = np.empty(steps)
    ret = 0.0
    for t in range(steps - 1, -1, -1):
        ret = rewards[t] + gamma * ret
        out[t] = ret
    return out


@njit(inline="always")
def episode_update(rule: Reinforce, theta: np.ndarray, baseline: np.ndarray, states: np.ndarray,
                   actions: np.ndarray, rewards: np.ndarray, steps: int, alpha: float, gamma: float,
                   h: np.ndarray, pi: np.ndarray) -> None:
    """The updates of one finished episode, t = 0 .. T-1 in order (``states[t]`` is ``S_t``)."""
    returns = returns_to_go(rewards, steps, gamma)
    discount = 1.0
    for t in range(steps):
        s, delta = states[t], returns[t]
        if rule.baseline_alpha > 0.0:
            delta -= action_value(baseline, s, 0)
            add_to_action(baseline, s, 0, rule.baseline_alpha * delta)
        softmax(action_values(theta, s, h), pi)
        scale = alpha * (discount if rule.discount_gradient else 1.0) * delta
        for a in range(theta.shape[1]):
            gradient = (1.0 if a == actions[t] else 0.0) - pi[a]
            add_to_action(theta, s, a, scale * gradient)
        discount *= gamma
