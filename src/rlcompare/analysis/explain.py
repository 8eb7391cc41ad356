"""Why one method wins: what the greedy policies do where every episode starts."""

from __future__ import annotations

import numpy as np

from rlcompare.envs import mountain_car
from rlcompare.envs.discretize import UniformGrid, cell_index_2d


def start_cells(grid: UniformGrid, points: int = 2001) -> np.ndarray:
    """Cells of start states ``(p, 0)`` for ``p`` evenly spread over the reset range [-0.6, -0.4]."""
    positions = np.linspace(mountain_car.RESET_LOW, mountain_car.RESET_HIGH, points)
    return np.array([cell_index_2d(grid, p, 0.0) for p in positions])


def first_action_shares(q_tables: np.ndarray, grid: UniformGrid) -> np.ndarray:
    """``(seeds, actions)``: for each seed, the share of start states whose first greedy action is each
    action. The paper says Q-Learning "accelerates forward in the first few frames while SARSA
    accelerates backwards"; this counts it over every start state and every seed."""
    cells = start_cells(grid)
    first = q_tables[:, cells].argmax(axis=2)  # (seeds, start states)
    return np.stack([(first == a).mean(axis=1) for a in range(q_tables.shape[2])], axis=1)
