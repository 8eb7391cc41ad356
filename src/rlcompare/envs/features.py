"""The features of a finite environment: each state is its own feature (Sutton and Barto, 9.5: a table is the
linear case with one-hot features). The grid and the tile coder are in :mod:`~rlcompare.envs.discretize` and
:mod:`~rlcompare.envs.tiles`; all three give compiled code ``n_active`` and ``activate``."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit


class OneHot(NamedTuple):
    """One feature per state of a finite environment."""

    n_features: int


@njit(inline="always")
def n_active(features: OneHot) -> int:
    return 1


@njit(inline="always")
def activate(features: OneHot, observation: np.ndarray | tuple, actives: np.ndarray, row: int) -> None:
    """The state's index is its feature."""
    actives[row, 0] = int(observation[0])
