"""From a configuration to what the kernels step: the environment and the features of its states."""

from __future__ import annotations

import numpy as np

from rlcompare.engine.kernel import GRID, MOUNTAIN_CAR, ONE_HOT, TABLE, TILES, Env, Features
from rlcompare.envs import mountain_car
from rlcompare.envs.discretize import UniformGrid, make_grid
from rlcompare.envs.table import chain, from_gymnasium
from rlcompare.envs.tiles import TileCoding, make_tile_coding

_NO_TABLE = chain(1)  # the kernels' table slot, unused by Mountain Car
TABLE_ENVIRONMENTS = ("CliffWalking-v1", "FrozenLake-v1", "Taxi-v4")
"""Finite environments stepped from their Gymnasium transition tables; their state is their feature."""


def observation_bounds(env: str) -> tuple[np.ndarray, np.ndarray]:
    """Gymnasium's float32 observation box, with the book's right bound (0.5) for its variant."""
    high = mountain_car.OBSERVATION_HIGH.copy()
    if env == "MountainCar-book":
        high[0] = np.float32(mountain_car.BOOK_MAX_POSITION)
    return mountain_car.OBSERVATION_LOW.copy(), high


def make_env(env: str) -> Env:
    if env in TABLE_ENVIRONMENTS:
        table = from_gymnasium(env)
        return Env(TABLE, 0.0, table, table.n_actions)
    right = mountain_car.BOOK_MAX_POSITION if env == "MountainCar-book" else mountain_car.MAX_POSITION
    return Env(MOUNTAIN_CAR, right, _NO_TABLE, mountain_car.N_ACTIONS)


def grid_of(env: str, bins: int) -> UniformGrid:
    return make_grid(*observation_bounds(env), bins)


def tiles_of(env: str, tilings: int, tiles: int, hash_size: int) -> TileCoding:
    low, high = observation_bounds(env)
    return make_tile_coding(low.astype(np.float64), high.astype(np.float64), tilings=tilings, tiles=tiles,
                            hash_size=hash_size or None)


def make_features(env: str, features: str, bins: int, tilings: int, tiles: int, hash_size: int) -> Features:
    """The grid (one active cell) or the tile coder (one active tile per tiling); the other slot is a stub.
    A table environment's state is its only active feature, whatever ``features`` says."""
    if env in TABLE_ENVIRONMENTS:
        table = from_gymnasium(env)
        return Features(ONE_HOT, grid_of("MountainCar-v0", 1), tiles_of("MountainCar-v0", 1, 1, 0),
                        table.n_states, 1)
    grid = grid_of(env, bins if features == "grid" else 1)
    coding = tiles_of(env, tilings if features == "tiles" else 1, tiles if features == "tiles" else 1,
                      hash_size if features == "tiles" else 0)
    if features == "grid":
        return Features(GRID, grid, coding, grid.n_cells, 1)
    return Features(TILES, grid, coding, coding.n_features, coding.offsets.shape[0])
