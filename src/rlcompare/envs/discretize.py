"""A uniform grid over a box of observations, equal to ``gymnasium.wrappers.DiscretizeObservation``.

Gymnasium's wrapper splits each dimension of ``observation_space`` into ``bins`` even cells with
``np.linspace(low, high, bins + 1)[1:-1]`` computed in float32, finds a cell with ``np.digitize`` and
flattens the cell indices with the first dimension most significant. The compiled :func:`cell_index`
gives the same flat index for every float32 observation, so a table trained here acts the same inside
Gymnasium. A first guess from arithmetic is corrected against the exact edges, which costs a compare or
two instead of a search.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from rlcompare.compiled import njit


class UniformGrid(NamedTuple):
    """Arrays that describe the grid, passed as they are to compiled code."""

    edges: np.ndarray
    """``(dims, max_bins - 1)`` inner cell edges (float32 values held as float64), padded with +inf."""
    low: np.ndarray
    """``(dims,)`` lower bound of each dimension."""
    scale: np.ndarray
    """``(dims,)`` bins per unit of each dimension, for the first guess."""
    bins: np.ndarray
    """``(dims,)`` number of cells of each dimension."""

    @property
    def n_cells(self) -> int:
        return int(np.prod(self.bins))

    @property
    def n_features(self) -> int:
        """One feature per cell."""
        return self.n_cells


def make_grid(low: np.ndarray, high: np.ndarray, bins: int | tuple[int, ...]) -> UniformGrid:
    """The grid of ``DiscretizeObservation(env, bins)`` for a Box with bounds ``low`` and ``high``."""
    low = np.ravel(np.asarray(low))
    high = np.ravel(np.asarray(high))
    per_dim = np.broadcast_to(np.asarray(bins, dtype=np.int64), low.shape).copy()
    if not (np.all(np.isfinite(low)) and np.all(np.isfinite(high))):
        raise ValueError(f"a uniform grid needs finite bounds, got low={low}, high={high}")
    edges = np.full((low.size, max(int(per_dim.max()) - 1, 1)), np.inf)
    for dim in range(low.size):
        inner = np.linspace(low[dim], high[dim], per_dim[dim] + 1)[1:-1]
        edges[dim, : inner.size] = inner
    low64 = low.astype(np.float64)
    scale = per_dim / (high.astype(np.float64) - low64)
    return UniformGrid(edges=edges, low=low64, scale=scale, bins=per_dim)


def cell_indices(grid: UniformGrid, observations: np.ndarray) -> np.ndarray:
    """Flat cells of many observations ``(n, dims)`` at once, in numpy: ``np.digitize`` per dimension."""
    observations = np.asarray(observations, dtype=np.float32).reshape(-1, grid.bins.size)
    flat = np.zeros(observations.shape[0], dtype=np.int64)
    for dim, bins in enumerate(grid.bins):
        flat = flat * bins + np.searchsorted(grid.edges[dim, : bins - 1], observations[:, dim], side="right")
    return flat


@njit(inline="always")
def _bin(grid: UniformGrid, dim: int, x: np.float32) -> int:
    """Number of inner edges of dimension ``dim`` that are ``<= x``: ``np.digitize(x, edges)``."""
    bins = grid.bins[dim]
    guess = (x - grid.low[dim]) * grid.scale[dim]
    cell = 0 if guess < 0.0 else (bins - 1 if guess >= bins - 1 else int(guess))
    while cell > 0 and x < grid.edges[dim, cell - 1]:
        cell -= 1
    while cell < bins - 1 and x >= grid.edges[dim, cell]:
        cell += 1
    return cell


@njit(inline="always")
def cell_of(grid: UniformGrid, observation: np.ndarray | tuple[np.float32, ...]) -> int:
    """Flat cell of an observation of any dimension, as ``DiscretizeObservation.observation``."""
    flat = 0
    for dim in range(len(observation)):
        flat = flat * grid.bins[dim] + _bin(grid, dim, np.float32(observation[dim]))
    return flat


@njit(inline="always")
def states_buffer(features: UniformGrid, size: int) -> np.ndarray:
    """Room for the cells of ``size`` states."""
    return np.empty(size, np.int64)


@njit(inline="always")
def features_of(features: UniformGrid, observation: np.ndarray | tuple[np.float32, ...], buffer: np.ndarray,
                at: int) -> int:
    """The observation's cell, also kept in ``buffer[at]``."""
    cell = cell_of(features, observation)
    buffer[at] = cell
    return cell


@njit(cache=True)
def cell_index(grid: UniformGrid, observation: np.ndarray) -> int:
    """:func:`cell_of`, compiled once for callers outside the kernels."""
    return cell_of(grid, observation)
