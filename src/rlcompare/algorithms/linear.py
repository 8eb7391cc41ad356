"""Action values linear in binary features (Sutton and Barto, 9.5 and 10.1).

``q(s, a)`` is the sum of ``w[i, a]`` over the features ``i`` active in ``s``, and its gradient with respect to
``w[i, a]`` is 1 on each of them. A state ``s`` is given by its active features: one integer where one feature
is active (the grid's cell, a finite environment's state), where ``w`` is the paper's Q-table and ``q(s, .)`` is
its row; an array of indices where several are (one tile per tiling). Compiled code keeps a table's cell in a
register, as a plain tabular loop would; the functions below are written once for both.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numba import types
from numba.extending import overload

from rlcompare.compiled import njit


def n_features_on(s: int | np.ndarray) -> int:
    """How many features are active in ``s``."""
    return 1 if isinstance(s, int | np.integer) else len(s)


def feature_on(s: int | np.ndarray, k: int) -> int:
    """The ``k``-th feature active in ``s``."""
    return int(s) if isinstance(s, int | np.integer) else int(s[k])


def action_values(w: np.ndarray, s: int | np.ndarray, out: np.ndarray) -> np.ndarray:
    """``q(s, a)`` for every action: a table's row itself (read it before ``w`` changes), else summed into
    ``out``."""
    return w[s] if isinstance(s, int | np.integer) else _summed_values(w, s, out)


# Each implementation below is chosen by the numba types of the arguments. Its parameters are named as the
# typing function's but not annotated, which numba's check of the two signatures (``strict``) takes for a
# difference.


@overload(n_features_on, strict=False)
def _n_features_on(s: types.Type) -> Callable[..., int]:
    if isinstance(s, types.Integer):
        return lambda s: 1
    return lambda s: s.size


@overload(feature_on, strict=False)
def _feature_on(s: types.Type, k: types.Type) -> Callable[..., int]:
    if isinstance(s, types.Integer):
        return lambda s, k: s
    return lambda s, k: s[k]


@overload(action_values, strict=False, inline="always")  # a table's row read in place, as a plain loop reads it
def _action_values(w: types.Type, s: types.Type, out: types.Type) -> Callable[..., np.ndarray]:
    if isinstance(s, types.Integer):
        return lambda w, s, out: w[s]
    return lambda w, s, out: _summed_values(w, s, out)


@njit  # not inlined at numba's level, whose inliner loses the scope of the sums (NumbaIRAssumptionWarning)
def _summed_values(w: np.ndarray, s: np.ndarray, out: np.ndarray) -> np.ndarray:
    """:func:`action_value` of every action, each summed in a register (a sum kept in ``out`` would be stored
    and loaded again at every feature)."""
    for a in range(w.shape[1]):
        out[a] = action_value(w, s, a)
    return out


@njit(inline="always")
def _row(s: int | np.ndarray, k: int) -> np.uint64:
    """The ``k``-th active feature as an unsigned index, whose row numba reads without testing it for a
    negative (from-the-end) index."""
    return np.uint64(feature_on(s, k))


@njit(inline="always")
def action_value(w: np.ndarray, s: int | np.ndarray, action: int) -> float:
    """``q(s, action)``."""
    column = np.uint64(action)
    total: float = w[_row(s, 0), column]
    for k in range(1, n_features_on(s)):
        total += w[_row(s, k), column]
    return total


@njit(inline="always")
def add_to_action(w: np.ndarray, s: int | np.ndarray, action: int, amount: float) -> None:
    """A semi-gradient step of ``amount`` on ``q(s, action)`` (9.5)."""
    column = np.uint64(action)
    for k in range(n_features_on(s)):
        w[_row(s, k), column] += amount


@njit(inline="always")
def count_visit(visits: np.ndarray, s: int | np.ndarray) -> None:
    """One more step taken with each of the state's features active."""
    for k in range(n_features_on(s)):
        visits[_row(s, k)] += 1
