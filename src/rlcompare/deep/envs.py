"""What the deep engine asks of an environment, and stepping many at once.

An environment is a hashable description (static under ``jax.jit``): ``reset(key) -> EnvState`` and
``step(state, action) -> (state, reward, terminated, truncated)``; :func:`step_autoreset` starts a new episode
where one ended and keeps the true last observation for bootstrapping at a time-limit cut. What the engine asks
of every environment, the classic-control ports (:mod:`rlcompare.deep.classic`), MinAtar's games
(:mod:`rlcompare.deep.minatar.games`), Atari's emulators (:mod:`rlcompare.deep.atari`) and pgx's chess
(:mod:`rlcompare.deep.chess.games`), is :data:`Environment`.
"""

from __future__ import annotations

import contextlib
import importlib
import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, NamedTuple, Protocol

import jax
import jax.numpy as jnp

from rlcompare.envs import minatar
from rlcompare.envs.atari import games as atari
from rlcompare.envs.chess import games as chess_games
from rlcompare.envs.registry import PORTS, environment
from rlcompare.validation import ConfigError

if TYPE_CHECKING:
    from typing_extensions import TypeIs


class EnvState(NamedTuple):
    """One environment's state: Gymnasium's float64 physics and the steps taken in this episode."""

    physics: jax.Array
    t: jax.Array


class Step(NamedTuple):
    """One step of :func:`step_autoreset`."""

    state: Any
    """The environment's state (a pytree) after a reset where the episode ended."""
    observation: jax.Array
    """float32, what the agent sees next (the first observation of a new episode where one ended)."""
    last_observation: jax.Array
    """float32, the observation the action led to, before any reset: what a time-limit cut bootstraps from."""
    reward: jax.Array
    terminated: jax.Array
    truncated: jax.Array


class Described(Protocol):
    """What every environment of the deep engine says of itself."""

    @property
    def name(self) -> str: ...

    @property
    def n_actions(self) -> int: ...

    @property
    def observation_shape(self) -> tuple[int, ...]: ...

    @property
    def max_steps(self) -> int | None:
        """Its episode limit; None where the game's own end is the only one."""
        ...


class VmappedEnv(Described, Protocol):
    """An environment written in JAX, one episode a state (any pytree), run many at once under ``vmap``."""

    def reset(self, key: jax.Array) -> Any: ...

    def step(self, state: Any, action: jax.Array, key: jax.Array) -> tuple[Any, jax.Array, jax.Array, jax.Array]:
        """``(state, reward, terminated, truncated)``."""
        ...

    def observe(self, state: Any) -> jax.Array: ...


class BatchedEnv(Described, Protocol):
    """An environment the host steps all at once (an emulator), not vmapped; ``role`` (training, evaluation) names
    which of its games play."""

    @property
    def batched(self) -> bool: ...

    def reset_batch(self, keys: jax.Array, role: str = "training") -> Any: ...

    def observe_batch(self, states: Any) -> jax.Array: ...

    def step_batch(self, states: Any, actions: jax.Array, keys: jax.Array, role: str = "training"
                   ) -> tuple[Any, jax.Array, jax.Array, jax.Array]: ...

    def step_autoreset_batch(self, states: Any, actions: jax.Array, keys: jax.Array, role: str = "training"
                             ) -> Step: ...


class GameEnv(VmappedEnv, Protocol):
    """A two-player game, its sides alternating (:mod:`rlcompare.deep.chess.games`): each step is the mover's, its
    reward the mover's, and the observation is the position from the side to move."""

    @property
    def players(self) -> int: ...

    def legal(self, state: Any) -> jax.Array:
        """``(n_actions,)`` bool: the moves the side to move may play."""
        ...

    def colour(self, state: Any) -> jax.Array:
        """The side to move: 0 the first player (White), 1 the second."""
        ...

    def captures(self, state: Any) -> jax.Array:
        """``(n_actions,)`` float32: the value of what each move takes."""
        ...


Environment = VmappedEnv | BatchedEnv
"""An environment of the deep engine."""


@dataclass(frozen=True)
class DeepEnv:
    """An environment the deep engine steps: Gymnasium's dynamics written in JAX, and its episode limit."""

    name: str
    n_actions: int
    observation_size: int
    max_steps: int
    start: Callable[[jax.Array], jax.Array]
    """``key -> physics``: a start state."""
    dynamics: Callable[[jax.Array, jax.Array], tuple[jax.Array, jax.Array, jax.Array]]
    """``(physics, action) -> (physics, reward, terminated)``."""
    observation_of: Callable[[jax.Array], jax.Array]
    """``physics -> float32 observation``."""

    @property
    def observation_shape(self) -> tuple[int, ...]:
        return (self.observation_size,)

    def reset(self, key: jax.Array) -> EnvState:
        return EnvState(self.start(key), jnp.zeros((), jnp.int32))

    def step(self, state: EnvState, action: jax.Array, key: jax.Array | None = None
             ) -> tuple[EnvState, jax.Array, jax.Array, jax.Array]:
        """One transition: ``(state, reward, terminated, truncated)``; truncated at the limit, unless terminated.
        The dynamics are deterministic: ``key`` is not used."""
        physics, reward, terminated = self.dynamics(state.physics, action)
        t = state.t + 1
        return EnvState(physics, t), reward, terminated, (t >= self.max_steps) & ~terminated

    def observe(self, state: EnvState) -> jax.Array:
        return self.observation_of(state.physics)


def step_autoreset(env: VmappedEnv, state: Any, action: jax.Array, key: jax.Array) -> Step:
    """One step (its random parts, if any, drawn from ``key`` folded with 1), and a reset (drawn from ``key``)
    where the episode ended, as Gymnasium's vector environments do with ``autoreset_mode=SAME_STEP``."""
    state, reward, terminated, truncated = env.step(state, action, jax.random.fold_in(key, 1))
    last_observation = env.observe(state)
    fresh = env.reset(key)
    done = terminated | truncated
    state = jax.tree.map(lambda new, old: jnp.where(done, new, old), fresh, state)
    return Step(state, env.observe(state), last_observation, reward, terminated, truncated)


# --- Many environments at once: vmapped, or stepped together by the host where the environment is batched ---

def is_batched(env: object) -> TypeIs[BatchedEnv]:
    """Stepped all at once outside JAX (an emulator: :class:`rlcompare.deep.atari.AtariEnv`), not vmapped."""
    return bool(getattr(env, "batched", False))


_EMULATORS_IN_USE = threading.RLock()


@contextlib.contextmanager
def playing(env: object) -> Iterator[None]:
    """Held while a program that steps ``env`` runs: a batched environment's emulators are the process's (one per
    game, role and width), so programs that play them take turns. Two trainings on two threads would otherwise
    step and reset each other's games (and crash ale-py). Vmapped environments run side by side freely."""
    if not is_batched(env):
        yield
        return
    with _EMULATORS_IN_USE:
        yield


def evaluation_epsilon(env: object) -> float:
    """The chance of a random action in the evaluations during training: 0 (greedy), or the environment's
    protocol's (Atari's 0.05, Mnih et al. 2015)."""
    return float(getattr(env, "eval_epsilon", 0.0))


def is_game(env: object) -> TypeIs[GameEnv]:
    """A two-player game whose sides alternate (:class:`GameEnv`): chosen moves are masked to the legal ones and
    the opponent's value is negated in every bootstrap."""
    return getattr(env, "players", 1) == 2


def legal_all(env: Environment, states: Any) -> jax.Array | None:
    """``(envs, n_actions)`` bool: the legal moves in each game's position; None where every action is legal."""
    return jax.vmap(env.legal)(states) if is_game(env) else None


def reset_all(env: Environment, keys: jax.Array, role: str = "training") -> Any:
    """``len(keys)`` environments started; ``role`` (training, evaluation) keeps a batched environment's games
    for one use apart from another's."""
    return env.reset_batch(keys, role) if is_batched(env) else jax.vmap(env.reset)(keys)


def observe_all(env: Environment, states: Any) -> jax.Array:
    return env.observe_batch(states) if is_batched(env) else jax.vmap(env.observe)(states)


def step_all(env: Environment, states: Any, actions: jax.Array, keys: jax.Array, role: str = "training"
             ) -> tuple[Any, jax.Array, jax.Array, jax.Array]:
    """One step of each environment (its ``step``): ``(states, rewards, terminated, truncated)``."""
    if is_batched(env):
        return env.step_batch(states, actions, keys, role)
    return jax.vmap(env.step)(states, actions, keys)


def step_autoreset_all(env: Environment, states: Any, actions: jax.Array, keys: jax.Array) -> Step:
    """:func:`step_autoreset` of each environment, one key each."""
    if is_batched(env):
        return env.step_autoreset_batch(states, actions, keys)
    return jax.vmap(step_autoreset, in_axes=(None, 0, 0, 0))(env, states, actions, keys)


def learning_reward(env: Environment, reward: jax.Array) -> jax.Array:
    """The reward a method learns from: the environment's own, or what its protocol makes of it (Atari's sign)."""
    transform = getattr(env, "learning_reward", None)
    return reward if transform is None else transform(reward)


def jax_env_names() -> tuple[str, ...]:
    """The environments the deep engine steps: those whose registry entry names a JAX port."""
    names = (*PORTS, *minatar.NAMES, *atari.NAMES, *chess_games.GAMES)
    return tuple(name for name in names if environment(name).jax_port)


def jax_env(name: str) -> Environment:
    """The JAX port of ``name``, from its registry entry (:mod:`rlcompare.envs.registry`); a
    :class:`~rlcompare.tabular.config.ConfigError` naming those there are."""
    if name not in jax_env_names():
        raise ConfigError("env", name, ", ".join(jax_env_names()))
    module, _, attribute = environment(name).jax_port.partition(":")
    port = getattr(importlib.import_module(module), attribute)
    return port if isinstance(port, DeepEnv) else port(name)
