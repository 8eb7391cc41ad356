"""Action values linear in binary features (Sutton and Barto, 9.5 and 10.1).

``q(s, a)`` is the sum of ``w[i, a]`` over the features ``i`` active in ``s``, and its gradient with respect to
``w[i, a]`` is 1 on each of them. With the grid (or a finite environment's states) one feature is active and
``w`` is the paper's Q-table; with tile coding one feature per tiling is. The active features of the states of
an episode live as rows of one array and are addressed by row: taking a view of a row on every step costs as
much as the rest of a tabular step.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(inline="always")
def action_value(w: np.ndarray, actives: np.ndarray, row: int, action: int) -> float:
    """``q(s, action)`` for the state whose active features are ``actives[row]``."""
    if actives.shape[1] == 1:  # the grid, a table: one feature, no loop
        total = w[actives[row, 0], action]
    else:
        total = 0.0
        for k in range(actives.shape[1]):
            total += w[actives[row, k], action]
    return total


@njit(inline="always")
def action_values(w: np.ndarray, actives: np.ndarray, row: int, out: np.ndarray) -> np.ndarray:
    """``q(s, a)`` for every action: a table's row itself (read it before ``w`` changes), else summed into
    ``out``."""
    if actives.shape[1] == 1:
        return w[actives[row, 0]]
    for a in range(w.shape[1]):
        out[a] = action_value(w, actives, row, a)
    return out


@njit(inline="always")
def add_to_action(w: np.ndarray, actives: np.ndarray, row: int, action: int, amount: float) -> None:
    """A semi-gradient step of ``amount`` on ``q(s, action)`` (9.5)."""
    if actives.shape[1] == 1:
        w[actives[row, 0], action] += amount
    else:
        for k in range(actives.shape[1]):
            w[actives[row, k], action] += amount


@njit(inline="always")
def count_visit(visits: np.ndarray, actives: np.ndarray, row: int) -> None:
    """One more step taken with each of the state's features active."""
    if actives.shape[1] == 1:
        visits[actives[row, 0]] += 1
    else:
        for k in range(actives.shape[1]):
            visits[actives[row, k]] += 1
