"""The softmax (Gibbs) policy over action preferences (Sutton and Barto, section 13.1, eq. 13.2)."""

from __future__ import annotations

import math

import numpy as np

from rlcompare.algorithms.policies import largest
from rlcompare.compiled import njit
from rlcompare.rng import next_double


@njit(inline="always")
def softmax(preferences: np.ndarray, out: np.ndarray) -> np.ndarray:
    """``pi(a) = exp(h(a)) / sum_b exp(h(b))``, shifted by the largest preference so nothing overflows (the
    largest then weighs ``exp(0) = 1`` exactly, without calling ``exp``)."""
    top = largest(preferences)
    total = 0.0
    for a in range(preferences.size):
        shifted = preferences[a] - top
        out[a] = 1.0 if shifted == 0.0 else math.exp(shifted)
        total += out[a]
    for a in range(preferences.size):
        out[a] /= total
    return out


@njit(inline="always")
def sample_softmax(preferences: np.ndarray, out: np.ndarray, rng_state: np.ndarray) -> int:
    """An action drawn from the softmax policy (its probabilities are left in ``out``)."""
    softmax(preferences, out)
    u = next_double(rng_state)
    cumulative = 0.0
    for a in range(out.size - 1):
        cumulative += out[a]
        if u < cumulative:
            return a
    return out.size - 1
