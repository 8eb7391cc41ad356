"""Why one method wins: what the greedy policies do where every episode starts."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from rlcompare.envs.features import grid_bounds
from rlcompare.report.map_frame import MapFrame
from rlcompare.tabular.config import ExperimentConfig

if TYPE_CHECKING:  # a plan asks has_start_region: numba and pandas only where a grid or a run is read
    from rlcompare.envs.discretize import UniformGrid
    from rlcompare.tabular.results import Results


def map_frame(config: ExperimentConfig) -> MapFrame | None:
    """The frame of the maps a report draws over two observation dimensions, where the environment names them
    and the features are the grid; None elsewhere."""
    env = config.environment
    if env.map_axes is None or config.features != "grid":
        return None
    low, high = grid_bounds(env, config.bounds)
    return MapFrame((float(low[0]), float(high[0]), float(low[1]), float(high[1])), env.map_axes, env.action_names)


def has_start_region(config: ExperimentConfig) -> bool:
    """Whether the report's start region, first actions and maps apply: the environment draws maps over two
    dimensions, says where its episodes start there, and the features are the grid."""
    return map_frame(config) is not None and config.environment.start_box is not None


def training_grid(config: ExperimentConfig) -> UniformGrid:
    """The uniform grid the runs of ``config`` were trained on: its bins over its bounds."""
    from rlcompare.envs.discretize import make_grid

    return make_grid(*grid_bounds(config.environment, config.bounds), config.grid_bins)


def map_of(config: ExperimentConfig) -> tuple[MapFrame, int]:
    """The frame of the maps over the grid of ``config`` (:func:`map_frame`) and the cells along each of their two
    axes; a :class:`ValueError` where it has no maps, or not as many cells along each axis."""
    frame = map_frame(config)
    if frame is not None:
        bins = {int(b) for b in training_grid(config).bins}
        if len(bins) == 1:
            return frame, bins.pop()
    raise ValueError(f"{config.name}: no map with as many cells along each axis over the grid of {config.env}")


def start_cells(grid: UniformGrid, start_box: tuple[tuple[float, float], ...], points: int = 2001) -> np.ndarray:
    """Cells of ``points`` start states spread evenly over each range of ``start_box`` together (Mountain Car's:
    ``(p, 0)`` for ``p`` in its reset range [-0.6, -0.4])."""
    from rlcompare.envs.discretize import cell_indices

    return cell_indices(grid, np.column_stack([np.linspace(low, high, points) for low, high in start_box]))


def start_region_cells(config: ExperimentConfig) -> np.ndarray:
    """:func:`start_cells` of the start region of ``config``'s environment on its :func:`training_grid`; a
    :class:`ValueError` where the environment says no start region (:func:`has_start_region`)."""
    start_box = config.environment.start_box
    if start_box is None:
        raise ValueError(f"{config.env} says no region where its episodes start")
    return start_cells(training_grid(config), start_box)


def first_action_shares(q_tables: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """``(seeds, actions)``: for each seed, the share of start states (their ``cells``, :func:`start_cells`) whose
    first greedy action is each action. The paper says Q-Learning "accelerates forward in the first few frames
    while SARSA accelerates backwards"; this counts it over every start state and every seed."""
    first = q_tables[:, cells].argmax(axis=2)  # (seeds, start states)
    return np.stack([(first == a).mean(axis=1) for a in range(q_tables.shape[2])], axis=1)


def final_first_action_shares(results: Results) -> np.ndarray:
    """:func:`first_action_shares` of the final Q-tables, from the start region on the grid the run was trained
    on."""
    return first_action_shares(results.records.snapshots[:, -1], start_region_cells(results.config))
