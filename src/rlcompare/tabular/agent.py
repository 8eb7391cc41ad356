"""Agents loaded from a tabular run that act on Gymnasium's own observations.

``act`` checks its observation before any compiled code reads it (:mod:`rlcompare.envs.observations`).
Finite observations outside the grid's or the tiles' box stay valid: they land in the edge cell, as with
Gymnasium's ``DiscretizeObservation``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from rlcompare.envs import mountain_car
from rlcompare.envs.chess.endgames import is_endgame_name
from rlcompare.envs.discretize import UniformGrid, cell_index
from rlcompare.envs.features import OneHot, make_features
from rlcompare.envs.observations import check_box_observation, check_observation, check_state
from rlcompare.envs.registry import Environment
from rlcompare.envs.tiles import TileCoding, active_tiles_nd
from rlcompare.tabular.results import Results
from rlcompare.validation import ConfigError

if TYPE_CHECKING:
    from rlcompare.players.endgame import ChessAgent


def observation_shape(env: Environment) -> tuple[int, ...]:
    """The shape of ``env``'s observations: ``()`` for a finite environment, ``(d,)`` for a Box."""
    return () if env.n_states else (env.observation_size,)


@dataclass
class GreedyAgent:
    """The greedy policy of stored weights: ``act(observation) -> int``, ties to the first action.

    With the grid the weights are the Q-table; with tiles, ``q(s, a)`` sums the active tiles' weights.
    A REINFORCE agent acts on its preferences: the most probable action of its softmax policy.
    """

    weights: np.ndarray
    features: UniformGrid | TileCoding | OneHot
    seed: int
    stage: str
    env: str
    """The environment's name, for error messages."""
    observation_shape: tuple[int, ...]
    """``(d,)`` of a Box environment; ``()`` for a finite one."""
    n_states: int
    """States of a finite environment; 0 for a Box."""

    def active(self, observation: np.ndarray | int) -> np.ndarray:
        """The active features: the grid cell ``DiscretizeObservation`` would give, or one tile per tiling (a
        finite environment's state is its one feature)."""
        if isinstance(self.features, OneHot):
            return np.array([check_state(observation, self.n_states, self.env)])
        valid = check_box_observation(observation, self.observation_shape, self.env)
        if isinstance(self.features, UniformGrid):
            return np.array([cell_index(self.features, valid)])
        out = np.empty(self.features.n_tilings, dtype=np.int64)
        active_tiles_nd(self.features, valid, out)
        return out

    def act(self, observation: np.ndarray | int) -> int:
        """The greedy action; :class:`ValueError` if ``observation`` is not one of the environment's."""
        return int(np.argmax(self.weights[self.active(observation)].sum(axis=0)))


@dataclass
class RandomAgent:
    """The random baseline: a uniform action whatever the (valid) observation."""

    seed: int
    stage: str
    env: str = "MountainCar-v0"
    observation_shape: tuple[int, ...] = (2,)
    n_states: int = 0
    n_actions: int = mountain_car.N_ACTIONS
    rng: np.random.Generator = field(init=False)

    def __post_init__(self) -> None:
        self.rng = np.random.default_rng(self.seed)

    def act(self, observation: np.ndarray | int) -> int:
        """A uniform action; :class:`ValueError` if ``observation`` is not one of the environment's."""
        check_observation(observation, self.observation_shape, self.n_states, self.env)
        return int(self.rng.integers(self.n_actions))


def check_actions(env: Any, n_actions: int, name: str) -> None:
    """One line naming ``env`` where its actions are not the ``n_actions`` the agent of ``name`` chooses among."""
    if is_endgame_name(name):
        raise ConfigError("env", type(env).__name__, "none for an agent that plays chess boards")
    if getattr(env.action_space, "n", None) != n_actions:
        raise ConfigError("env", f"an environment with the action space {env.action_space}",
                          f"one of {n_actions} actions, as gymnasium.make({name!r}) makes")


def agent(results: Results, seed: int, stage: str = "final", env: Any = None) -> GreedyAgent | RandomAgent | ChessAgent:
    """The agent of ``seed`` at ``stage`` of a tabular run, ready for ``gymnasium.make(config.env)``
    (``MountainCar-v0`` for the book's variant too, whose trajectories are the same; ``env``, where given, must
    have its actions); a chess endgame's plays python-chess boards (``agent.move(board)``)."""
    weights = results.q_table(seed, stage)
    c = results.config
    if env is not None:
        check_actions(env, weights.shape[1], c.env)
    if is_endgame_name(c.env) and c.algorithm != "random":
        from rlcompare.players.endgame import ChessAgent

        return ChessAgent(weights, c.env, seed, stage)
    env = c.environment
    shape = observation_shape(env)
    if c.algorithm == "random":
        return RandomAgent(seed=seed, stage=stage, env=c.env, observation_shape=shape, n_states=env.n_states,
                           n_actions=weights.shape[1])
    features = make_features(env, c.features, c.grid_bins, c.tilings, c.tiles, c.hash_size, c.bounds)
    return GreedyAgent(weights=weights, features=features, seed=seed, stage=stage, env=c.env,
                       observation_shape=shape, n_states=env.n_states)
