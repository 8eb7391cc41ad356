"""Any Gymnasium environment with discrete actions, stepped through Gymnasium's own API from the kernels.

The ports (Mountain Car, CartPole, Acrobot, the toy-text tables) are compiled; every other registered
environment runs through this adapter. The kernels are the same: where they would step a port they call
back into Python (numba's object mode) to :func:`reset` or :func:`step` a real ``gymnasium.make(env_id)``,
so every algorithm runs unchanged, at Python speed.

Each run holds two environments, one for training and one for evaluation. Each resets with its
``np_random`` a copy of the run's reset stream and steps with it a copy of the run's transition stream,
so start states never depend on what happened in earlier episodes. A port draws its randomness from the
same streams in the same order, so the adapter gives the ports' results bit for bit.

| observation space                          | what the kernels see                                    |
|--------------------------------------------|---------------------------------------------------------|
| ``Discrete(n)``                            | the index, one feature per state                         |
| ``Box`` with finite bounds                 | the flattened float32 vector, on the grid or tiles      |
| ``Box`` with infinite bounds               | the same, over bounds the user gives (``bounds``)        |
| anything else (``Tuple``, ``Dict``, images) | not supported: :class:`UnsupportedEnvironment` says why |

Actions must be ``Discrete(n)`` (starting at 0).
"""

from __future__ import annotations

import contextlib
import itertools
from collections.abc import Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from numba import objmode

from rlcompare.compiled import njit

if TYPE_CHECKING:
    import gymnasium as gym

Opened = tuple["gym.Env[Any, Any]", np.random.Generator, np.random.Generator]
"""An environment with the generators it resets and steps from."""
_OPEN: dict[int, list[Opened]] = {}
"""``(env, reset generator, transition generator)`` opened by :func:`opened`, by handle; instance ``2 * run``
trains, ``2 * run + 1`` evaluates."""
_HANDLES = itertools.count()


class UnsupportedEnvironment(ValueError):
    """An environment the adapter cannot run, with the reason."""


@dataclass(frozen=True)
class Spaces:
    """What the kernels need to know of an environment's spaces."""

    n_actions: int
    n_states: int
    """``n`` of a ``Discrete`` observation space; 0 for a ``Box``."""
    low: np.ndarray
    """``(dims,)`` float64 lower bounds of a ``Box`` (may be infinite); empty for ``Discrete``."""
    high: np.ndarray
    max_episode_steps: int | None
    """The step limit Gymnasium registers, if any."""

    @property
    def observation_size(self) -> int:
        return 1 if self.n_states else self.low.size


def describe(env_id: str) -> Spaces:
    """The spaces of ``env_id``, or :class:`UnsupportedEnvironment` naming what is wrong."""
    import gymnasium as gym

    if env_id.startswith("ALE/"):
        game = env_id.removeprefix("ALE/").split("-")[0]
        raise UnsupportedEnvironment(f"{env_id!r} is an Atari 2600 game, whose screens no table can hold: the "
                                     f"deep engine plays its games as NAME-Atari ({game}-Atari where docs/atari.md "
                                     "lists it), with the Atari extra")
    try:
        spec = gym.spec(env_id)
    except gym.error.Error as error:
        raise UnsupportedEnvironment(f"{env_id!r} is not a registered Gymnasium environment ({error})") from None
    try:
        env = gym.make(env_id, disable_env_checker=True)
    except Exception as error:  # a registered environment whose dependencies are missing, say
        raise UnsupportedEnvironment(f"{env_id!r} cannot be made: {error}") from None
    try:
        actions, observations = env.action_space, env.observation_space
    finally:
        env.close()
    if not isinstance(actions, gym.spaces.Discrete) or int(actions.start) != 0:
        raise UnsupportedEnvironment(f"{env_id!r} has actions {actions}; the algorithms need Discrete(n) "
                                     "actions starting at 0")
    limit = spec.max_episode_steps
    if isinstance(observations, gym.spaces.Discrete):
        if int(observations.start) != 0:
            raise UnsupportedEnvironment(f"{env_id!r} has observations {observations}; Discrete ones must "
                                         "start at 0")
        return Spaces(int(actions.n), int(observations.n), np.empty(0), np.empty(0), limit)
    if isinstance(observations, gym.spaces.Box) and len(observations.shape) == 1:
        low = observations.low.astype(np.float64).ravel()
        high = observations.high.astype(np.float64).ravel()
        return Spaces(int(actions.n), 0, low, high, limit)
    raise UnsupportedEnvironment(f"{env_id!r} has observations {observations}; supported: Discrete(n) or a "
                                 "one-dimensional Box")


@contextlib.contextmanager
def opened(env_id: str, training: np.ndarray, evaluation: np.ndarray, max_steps: int) -> Iterator[int]:
    """Open a training and an evaluation environment per run; yield the handle the kernels step them by.

    ``training`` and ``evaluation`` are ``(runs, 2, 4)`` uint64 states (see :mod:`rlcompare.rng`): each run's
    reset stream and transition stream, copied into the generators the environments draw from."""
    import gymnasium as gym

    environments: list[Opened] = []
    handle = next(_HANDLES)
    try:
        for streams in (stream for pair in zip(training, evaluation, strict=True) for stream in pair):
            env = gym.make(env_id, max_episode_steps=max_steps, disable_env_checker=True)
            resets, transitions = (np.random.Generator(_pcg64(s)) for s in streams)
            environments.append((env, resets, transitions))
        _OPEN[handle] = environments
        yield handle
    finally:
        _OPEN.pop(handle, None)
        for env, _, _ in environments:
            env.close()


def _pcg64(stream: np.ndarray) -> np.random.PCG64:
    """A ``PCG64`` in the state ``[state_high, state_low, increment_high, increment_low]``."""
    high, low, inc_high, inc_low = (int(v) for v in stream)
    bit_generator = np.random.PCG64()
    bit_generator.state = {"bit_generator": "PCG64", "has_uint32": 0, "uinteger": 0,
                           "state": {"state": high << 64 | low, "inc": inc_high << 64 | inc_low}}
    return bit_generator


class Adapted(NamedTuple):
    """Which of the environments opened by :func:`opened` the kernels step, and the length of its
    observation."""

    handle: int
    instance: int
    """``2 * run`` trains, ``2 * run + 1`` evaluates."""
    observation_size: int


@njit(inline="always")
def for_instance(env: Adapted, instance: int) -> Adapted:
    """The same environments, naming one instance."""
    return Adapted(env.handle, instance, env.observation_size)


@njit
def reset(env: Adapted, rng: np.ndarray) -> np.ndarray:
    """Reset the instance from its copy of the reset stream (``rng`` is not drawn from); its observation."""
    observation = np.empty(env.observation_size)
    with objmode():
        _reset(env.handle, env.instance, observation)
    return observation


@njit
def step(env: Adapted, state: np.ndarray, action: int, rng: np.ndarray) -> tuple[np.ndarray, float, bool]:
    """Step the instance (``rng`` is not drawn from): ``(observation, reward, terminated)``."""
    with objmode(reward="float64", terminated="boolean"):
        reward, terminated = _step(env.handle, env.instance, action, state)
    return state, reward, terminated


@njit(inline="always")
def observe(env: Adapted, state: np.ndarray) -> np.ndarray:
    return state


def _reset(handle: int, instance: int, x: np.ndarray) -> None:
    """Reset one environment from its reset stream and write its observation into ``x``."""
    env, resets, transitions = _OPEN[handle][instance]
    env.unwrapped.np_random = resets
    observation, _ = env.reset()
    env.unwrapped.np_random = transitions
    x[:] = np.ravel(observation)


def _step(handle: int, instance: int, action: int, x: np.ndarray) -> tuple[float, bool]:
    """Step one environment, write its observation into ``x``; ``(reward, terminated)``."""
    observation, reward, terminated, _, _ = _OPEN[handle][instance][0].step(int(action))
    x[:] = np.ravel(observation)
    return float(reward), bool(terminated)
