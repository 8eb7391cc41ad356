"""Agents loaded from a run directory that act on Gymnasium's own observations."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rlcompare.engine.kernel import GRID, ONE_HOT, Features
from rlcompare.envs import mountain_car
from rlcompare.envs.discretize import cell_index
from rlcompare.envs.tiles import active_tiles_nd
from rlcompare.experiment.problem import make_features
from rlcompare.experiment.results import Results


@dataclass
class GreedyAgent:
    """The greedy policy of stored weights: ``act(observation) -> int``, ties to the first action.

    With the grid the weights are the Q-table; with tiles, ``q(s, a)`` sums the active tiles' weights.
    A REINFORCE agent acts on its preferences: the most probable action of its softmax policy.
    """

    weights: np.ndarray
    features: Features
    seed: int
    stage: str

    def active(self, observation: np.ndarray) -> np.ndarray:
        """The active features: the grid cell ``DiscretizeObservation`` would give, or one tile per tiling."""
        if self.features.kind == ONE_HOT:
            return np.array([int(observation)])
        observation = np.asarray(observation, dtype=np.float64)
        if self.features.kind == GRID:
            return np.array([cell_index(self.features.grid, observation)])
        out = np.empty(self.features.n_active, dtype=np.int64)
        active_tiles_nd(self.features.tiles, observation, out)
        return out

    def act(self, observation: np.ndarray) -> int:
        return int(np.argmax(self.weights[self.active(observation)].sum(axis=0)))


@dataclass
class RandomAgent:
    """The random baseline: a uniform action whatever the observation."""

    seed: int
    stage: str
    rng: np.random.Generator = field(init=False)

    def __post_init__(self) -> None:
        self.rng = np.random.default_rng(self.seed)

    n_actions: int = mountain_car.N_ACTIONS

    def act(self, observation: np.ndarray) -> int:
        return int(self.rng.integers(self.n_actions))


def load_agent(run_dir: Path, *, seed: int, stage: str = "final") -> GreedyAgent | RandomAgent:
    """The agent of ``seed`` at ``stage`` in a run directory, ready for ``gymnasium.make(config.env)``
    (``MountainCar-v0`` for the book's variant too, whose trajectories are the same)."""
    results = Results.load(Path(run_dir))
    weights = results.q_table(seed, stage)
    c = results.config
    if c.algorithm == "random":
        return RandomAgent(seed=seed, stage=stage, n_actions=weights.shape[1])
    features = make_features(c.environment, c.features, c.bins, c.tilings, c.tiles, c.hash_size, c.bounds)
    return GreedyAgent(weights=weights, features=features, seed=seed, stage=stage)
