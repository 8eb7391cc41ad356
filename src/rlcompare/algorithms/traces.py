"""Eligibility traces for SARSA(λ) (Sutton and Barto, 12.7) and Watkins's Q(λ) (12.10) with binary features.

``z`` holds a trace per weight, flat: the trace of ``w[i, a]`` is ``z[i * actions + a]``, and the loops pass ``w``
flat too, once an episode. Only the pairs listed in ``touched`` (flagged in ``listed``) can be non-zero, so
decaying, applying or cutting the traces costs the number of pairs visited in the episode, not the size of
``w``. A pair enters the list the first time its trace is marked and leaves it when the traces are cleared. Pairs
are listed by that flat index.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from rlcompare.algorithms.linear import feature_on, n_features_on
from rlcompare.compiled import njit


class SarsaLambda(NamedTuple):
    """SARSA(λ) (12.7): the TD error bootstraps on the action taken next."""

    lam: float
    replacing: bool
    """Replacing traces (set to 1) instead of accumulating ones (add 1)."""


class QLambda(NamedTuple):
    """Watkins's Q(λ) (12.10): the TD error bootstraps on the greedy action, and every trace is cut after an
    exploratory one."""

    lam: float
    replacing: bool


@njit(inline="always")
def mark(z: np.ndarray, touched: np.ndarray, listed: np.ndarray, n_touched: int, s: int | np.ndarray,
         action: int, n_actions: int, replacing: bool) -> int:
    """Raise the traces of ``(i, action)`` for the features ``i`` active in ``s``; the new length of the list."""
    for k in range(n_features_on(s)):
        pair = feature_on(s, k) * n_actions + action
        if not listed[pair]:
            listed[pair] = True
            touched[n_touched] = pair
            n_touched += 1
        z[pair] = 1.0 if replacing else z[pair] + 1.0
    return n_touched


@njit(inline="always")
def apply(w_flat: np.ndarray, z: np.ndarray, touched: np.ndarray, n_touched: int, step_size: float) -> None:
    """``w += step_size * z`` over the listed pairs (``step_size`` is α δ)."""
    for k in range(n_touched):
        w_flat[touched[k]] += step_size * z[touched[k]]


@njit(inline="always")
def decay(z: np.ndarray, touched: np.ndarray, n_touched: int, factor: float) -> None:
    """``z *= factor`` (γ λ) over the listed pairs."""
    for k in range(n_touched):
        z[touched[k]] *= factor


@njit(inline="always")
def clear(z: np.ndarray, touched: np.ndarray, listed: np.ndarray, n_touched: int) -> int:
    """Every trace to 0 and the list emptied; returns its new length, 0."""
    for k in range(n_touched):
        z[touched[k]] = 0.0
        listed[touched[k]] = False
    return 0
