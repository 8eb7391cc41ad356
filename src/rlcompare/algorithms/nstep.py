"""n-step SARSA (Sutton and Barto, 7.2): ``q(S_τ, A_τ)`` moves toward the n-step return
``G = R_{τ+1} + γ R_{τ+2} + ... + γ^{n-1} R_{τ+n} + γ^n q(S_{τ+n}, A_{τ+n})``, cut at the episode's end T.

Rewards live in a ring buffer of ``n + 1`` entries indexed by time modulo ``n + 1``, as the book's box keeps
them.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from rlcompare.compiled import njit


class NStepSarsa(NamedTuple):
    """n-step SARSA (7.2)."""

    n: int


@njit(inline="always")
def powers(gamma: float, n: int) -> np.ndarray:
    """``γ^0 .. γ^n``, each computed as ``gamma ** j``."""
    out = np.empty(n + 1)
    for j in range(n + 1):
        out[j] = gamma ** j
    return out


@njit(inline="always")
def n_step_rewards(rewards: np.ndarray, tau: int, n: int, horizon: int, discounts: np.ndarray) -> float:
    """``sum over i from τ+1 to min(τ+n, T) of γ^(i-τ-1) R_i``, the rewards part of the n-step return
    (``discounts`` holds the powers of γ)."""
    size = rewards.size
    ret = 0.0
    for k in range(tau + 1, min(tau + n, horizon) + 1):
        ret += discounts[k - tau - 1] * rewards[k % size]
    return ret
