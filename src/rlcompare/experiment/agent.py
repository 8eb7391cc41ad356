"""Agents loaded from a run directory that act on Gymnasium's own observations.

``act`` checks its observation before any compiled code reads it: for a Box environment a real array of
exactly the environment's shape ``(d,)`` with finite entries, for a finite one an integer state in
``[0, n_states)``; anything else raises :class:`ValueError` naming what was expected and what came.
Finite observations outside the grid's or the tiles' box stay valid: they land in the edge cell, as with
Gymnasium's ``DiscretizeObservation``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rlcompare.envs import mountain_car
from rlcompare.envs.discretize import UniformGrid, cell_index
from rlcompare.envs.features import OneHot, make_features
from rlcompare.envs.registry import Environment
from rlcompare.envs.tiles import TileCoding, active_tiles_nd
from rlcompare.experiment.results import Results
from rlcompare.experiment.store import quote

_REAL = "iuf"
"""numpy dtype kinds ``act`` accepts in a Box observation: integers and floats (not bool, complex, object,
strings)."""


def _given(observation: object) -> str:
    """What came, briefly: the shape and dtype of an array, else the type and value."""
    if isinstance(observation, np.ndarray) and observation.ndim:
        return f"shape {observation.shape} {observation.dtype}"
    return f"{type(observation).__name__} {quote(observation, 40)}"


def _refuse(given: str, expected: str, env: str) -> ValueError:
    return ValueError(f"observation: got {given}; expected {expected}, as {env}'s env.step returns")


def check_box_observation(observation: object, shape: tuple[int, ...], env: str) -> np.ndarray:
    """``observation`` as a float64 array, if it is a real array of exactly ``shape`` with finite entries."""
    expected = f"shape {shape} of finite numbers"
    try:
        array = np.asarray(observation)
    except (TypeError, ValueError):  # a ragged sequence, say
        raise _refuse(_given(observation), expected, env) from None
    if array.shape != shape or array.dtype.kind not in _REAL:
        raise _refuse(_given(array if array.ndim else observation), expected, env)
    array = array.astype(np.float64)
    if not np.isfinite(array).all():
        raise _refuse(quote(array.tolist(), 40), expected, env)
    return array


def check_state(observation: object, n_states: int, env: str) -> int:
    """``observation`` as an int, if it is an integer (Python, numpy or a 0-d array) in ``[0, n_states)``."""
    value = observation
    if isinstance(value, np.ndarray) and value.ndim == 0 and value.dtype.kind in "iu":
        value = value[()]
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not 0 <= value < n_states:
        raise _refuse(_given(observation), f"an integer state in [0, {n_states})", env)
    return int(value)


def check_observation(observation: object, shape: tuple[int, ...], n_states: int, env: str) -> np.ndarray | int:
    """A valid observation of ``env`` in the form the features read: a finite state's int, a Box's float64
    array. ``n_states`` is 0 for a Box of ``shape``."""
    return check_state(observation, n_states, env) if n_states else check_box_observation(observation, shape, env)


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
        """The active features: the grid cell ``DiscretizeObservation`` would give, or one tile per tiling."""
        valid = check_observation(observation, self.observation_shape, self.n_states, self.env)
        if isinstance(self.features, OneHot):
            return np.array([valid])
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


def agent(results: Results, seed: int, stage: str = "final") -> GreedyAgent | RandomAgent:
    """The agent of ``seed`` at ``stage`` of a tabular run, ready for ``gymnasium.make(config.env)``
    (``MountainCar-v0`` for the book's variant too, whose trajectories are the same)."""
    weights = results.q_table(seed, stage)
    c = results.config
    env = c.environment
    observations = {"env": c.env, "observation_shape": observation_shape(env), "n_states": env.n_states}
    if c.algorithm == "random":
        return RandomAgent(seed=seed, stage=stage, n_actions=weights.shape[1], **observations)
    features = make_features(env, c.features, c.bins, c.tilings, c.tiles, c.hash_size, c.bounds)
    return GreedyAgent(weights=weights, features=features, seed=seed, stage=stage, **observations)
