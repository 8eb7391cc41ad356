"""Why one method wins: what the greedy policies do where every episode starts."""

from __future__ import annotations

import numpy as np

from rlcompare.analysis.plots import MapFrame
from rlcompare.envs import mountain_car
from rlcompare.envs.discretize import UniformGrid, cell_indices, make_grid
from rlcompare.envs.features import grid_bounds
from rlcompare.experiment.config import ExperimentConfig
from rlcompare.experiment.results import Results


def map_frame(config: ExperimentConfig) -> MapFrame | None:
    """The frame of the maps a report draws over two observation dimensions, where the environment names them
    and the features are the grid; None elsewhere."""
    env = config.environment
    if env.map_axes is None or config.features != "grid":
        return None
    low, high = grid_bounds(env, config.bounds)
    return MapFrame((float(low[0]), float(high[0]), float(low[1]), float(high[1])), env.map_axes, env.action_names)


def on_position_velocity_grid(config: ExperimentConfig) -> bool:
    """Mountain Car on a grid: the start region, the first actions and the maps over position x velocity apply."""
    frame = map_frame(config)
    return frame is not None and frame.axes == ("position", "velocity")


def start_cells(grid: UniformGrid, points: int = 2001) -> np.ndarray:
    """Cells of start states ``(p, 0)`` for ``p`` evenly spread over the reset range [-0.6, -0.4]."""
    positions = np.linspace(mountain_car.RESET_LOW, mountain_car.RESET_HIGH, points)
    return cell_indices(grid, np.column_stack([positions, np.zeros(points)]))


def first_action_shares(q_tables: np.ndarray, grid: UniformGrid) -> np.ndarray:
    """``(seeds, actions)``: for each seed, the share of start states whose first greedy action is each
    action. The paper says Q-Learning "accelerates forward in the first few frames while SARSA
    accelerates backwards"; this counts it over every start state and every seed."""
    cells = start_cells(grid)
    first = q_tables[:, cells].argmax(axis=2)  # (seeds, start states)
    return np.stack([(first == a).mean(axis=1) for a in range(q_tables.shape[2])], axis=1)


def final_first_action_shares(results: Results) -> np.ndarray:
    """:func:`first_action_shares` of the final Q-tables, on the grid the run was trained on."""
    c = results.config
    return first_action_shares(results.records.snapshots[:, -1], make_grid(*grid_bounds(c.environment, c.bounds),
                                                                            c.bins))
