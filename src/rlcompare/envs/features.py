"""The features of a configuration's states: the grid (:mod:`~rlcompare.envs.discretize`), the tile coder
(:mod:`~rlcompare.envs.tiles`), or, for a finite environment, one feature per state (Sutton and Barto, 9.5: a table
is the linear case with one-hot features), defined here. All three give compiled code ``states_buffer`` and
``features_of`` (:mod:`rlcompare.algorithms.linear` says what a state's features are)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from rlcompare.compiled import njit
from rlcompare.envs.discretize import UniformGrid, make_grid
from rlcompare.envs.tiles import TileCoding, make_tile_coding

if TYPE_CHECKING:
    from rlcompare.envs.registry import Environment


class OneHot(NamedTuple):
    """One feature per state of a finite environment."""

    n_features: int


@njit(inline="always")
def states_buffer(features: OneHot, size: int) -> np.ndarray:
    """Room for ``size`` states."""
    return np.empty(size, np.int64)


@njit(inline="always")
def features_of(features: OneHot, observation: np.ndarray | tuple[int], buffer: np.ndarray, at: int) -> int:
    """The state's index is its feature; also kept in ``buffer[at]``."""
    state = int(observation[0])
    buffer[at] = state
    return state


def grid_bounds(env: Environment, bounds: tuple[tuple[float, float], ...] | None) -> tuple[np.ndarray, np.ndarray]:
    """The box the grid and the tiles span: ``bounds`` if given, else the environment's defaults."""
    if bounds is None:
        return env.low, env.high
    return np.array([low for low, _ in bounds], dtype=np.float64), np.array([high for _, high in bounds],
                                                                            dtype=np.float64)


def make_features(env: Environment, features: str, bins: int | tuple[int, ...], tilings: int, tiles: int,
                  hash_size: int, bounds: tuple[tuple[float, float], ...] | None = None,
                  ) -> UniformGrid | TileCoding | OneHot:
    """The grid (one active cell) or the tile coder (one active tile per tiling). A finite environment's state
    is its only active feature, whatever ``features`` says."""
    if env.n_states:
        return OneHot(env.n_states)
    low, high = grid_bounds(env, bounds)
    if features == "grid":
        return make_grid(low, high, bins)
    return make_tile_coding(low, high, tilings=tilings, tiles=tiles, hash_size=hash_size or None)


def feature_count(env: Environment, features: str, bins: int | tuple[int, ...], tilings: int, tiles: int,
                  hash_size: int) -> int:
    """How many features a configuration has, without building them."""
    if env.n_states:
        return env.n_states
    if features == "grid":
        return int(math.prod(np.broadcast_to(np.asarray(bins), env.low.shape).tolist()))
    if hash_size:
        return hash_size
    return tilings * int(math.prod(t + 1 for t in np.broadcast_to(np.asarray(tiles), env.low.shape).tolist()))
