"""Agents loaded from a run directory that act on Gymnasium's own observations."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rlcompare.envs import mountain_car
from rlcompare.envs.discretize import UniformGrid, cell_index, make_grid
from rlcompare.experiment.results import Results


@dataclass
class GreedyAgent:
    """The greedy policy of a stored Q-table: ``act(observation) -> int``, ties to the first action."""

    q_table: np.ndarray
    grid: UniformGrid
    seed: int
    stage: str

    def cell(self, observation: np.ndarray) -> int:
        """The grid cell of an observation, as ``DiscretizeObservation`` would give it."""
        return cell_index(self.grid, np.asarray(observation, dtype=np.float64))

    def act(self, observation: np.ndarray) -> int:
        return int(np.argmax(self.q_table[self.cell(observation)]))


@dataclass
class RandomAgent:
    """The random baseline: a uniform action whatever the observation."""

    seed: int
    stage: str
    rng: np.random.Generator = field(init=False)

    def __post_init__(self) -> None:
        self.rng = np.random.default_rng(self.seed)

    def act(self, observation: np.ndarray) -> int:
        return int(self.rng.integers(mountain_car.N_ACTIONS))


def load_agent(run_dir: Path, *, seed: int, stage: str = "final") -> GreedyAgent | RandomAgent:
    """The agent of ``seed`` at ``stage`` in a run directory, ready for ``gymnasium.make("MountainCar-v0")``."""
    results = Results.load(Path(run_dir))
    q_table = results.q_table(seed, stage)
    if results.config.algorithm == "random":
        return RandomAgent(seed=seed, stage=stage)
    grid = make_grid(mountain_car.OBSERVATION_LOW, mountain_car.OBSERVATION_HIGH, results.config.bins)
    return GreedyAgent(q_table=q_table, grid=grid, seed=seed, stage=stage)
