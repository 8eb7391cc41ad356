"""Action selection from one row of a Q-table (Sutton and Barto, section 2.2 and 6.4).

The behaviour policy is ε-greedy: with probability ε an action uniformly at random (the greedy one
included), otherwise a greedy action, ties broken uniformly at random so that an all-zero row of a fresh
table does not always pick action 0. Evaluation and loaded agents act with :func:`greedy_action`, which
takes the first maximum like ``np.argmax``, so an agent acts the same here and inside Gymnasium.

In a game whose legal moves change with the state (chess), an illegal move's value is −∞ in every table (the
engine writes it there before the first episode, and no update ever reaches it): it is never a maximum, never
greedy, and the uniform choice runs over the legal moves only (:func:`uniform_legal_action`). Where every action
is legal, each function draws and returns exactly what it did before masks existed.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from rlcompare.compiled import njit
from rlcompare.rng import next_below, next_double


@njit(inline="always")
def greedy_action(q_row: np.ndarray) -> int:
    """The first action of highest value, as ``np.argmax``."""
    best = 0
    for action in range(1, q_row.size):
        if q_row[action] > q_row[best]:
            best = action
    return best


@njit(inline="always")
def largest(q_row: np.ndarray) -> float:
    """``max(q_row)``, a loop the compiler keeps in registers (the array method ``q_row.max()`` costs as much as
    the rest of a step)."""
    best: float = q_row[0]
    for action in range(1, q_row.size):
        best = max(best, q_row[action])
    return best


@njit(inline="always")
def greedy_action_random_ties(q_row: np.ndarray, rng_state: np.ndarray) -> int:
    """An action of highest value, chosen uniformly among the tied ones."""
    best, ties = 0, 1
    for action in range(1, q_row.size):
        if q_row[action] > q_row[best]:
            best, ties = action, 1
        elif q_row[action] == q_row[best]:
            ties += 1
    if ties == 1:
        return best
    pick = next_below(rng_state, ties)
    for action in range(best, q_row.size):
        if q_row[action] == q_row[best]:
            if pick == 0:
                return action
            pick -= 1
    return best  # unreachable: ``pick < ties``


@njit(inline="always")
def uniform_action(n_actions: int, rng_state: np.ndarray) -> int:
    """An action uniformly at random: the random baseline, and the exploring branch of ε-greedy."""
    return next_below(rng_state, n_actions)


@njit(inline="always")
def legal_count(q_row: np.ndarray) -> int:
    """How many actions are legal: those whose value is not −∞."""
    count = 0
    for action in range(q_row.size):
        if q_row[action] != -np.inf:
            count += 1
    return count


@njit(inline="always")
def uniform_legal_action(q_row: np.ndarray, rng_state: np.ndarray) -> int:
    """A legal action uniformly at random: the ``k``-th legal one for ``k`` drawn below their count (with every
    action legal, the draw of :func:`uniform_action`)."""
    pick = next_below(rng_state, legal_count(q_row))
    for action in range(q_row.size):
        if q_row[action] != -np.inf:
            if pick == 0:
                return action
            pick -= 1
    return 0  # unreachable: ``pick < legal_count``


@njit(inline="always")
def epsilon_greedy_action(q_row: np.ndarray, epsilon: float, rng_state: np.ndarray, masked: bool = False) -> int:
    """With probability ``epsilon`` a uniform action (a uniform legal one where the environment's legal moves are
    ``masked``), otherwise greedy with random tie-breaking."""
    if next_double(rng_state) < epsilon:
        return uniform_legal_action(q_row, rng_state) if masked else uniform_action(q_row.size, rng_state)
    return greedy_action_random_ties(q_row, rng_state)


class RandomActions(NamedTuple):
    """The paper's baseline: every action uniformly at random, nothing learned."""

    n_actions: int
