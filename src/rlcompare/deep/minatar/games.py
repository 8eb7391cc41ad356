"""MinAtar's five games for the deep engine: gymnax's JAX ports (pinned, 1.0.1) under the protocols of
:mod:`rlcompare.envs.minatar`.

The ports are checked against the reference ``minatar`` package (1.0.15), whole episodes at a time, in
``tests/parity/test_minatar_games.py``; where gymnax departs from the reference the port here follows the reference
(``docs/minatar.md`` lists each case). The state carries the last action taken, which a sticky action repeats.
Observations are booleans, ``(10, 10, channels)``, until the network.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp

from rlcompare.envs import minatar
from rlcompare.envs.minatar import ACTION_NAMES, FREEWAY_STEPS, NAMES, Game, Protocol


class MinAtarState(NamedTuple):
    game: Any
    """gymnax's state of the game (its ``time`` counts this episode's steps)."""
    last_action: jax.Array
    """The last action taken, among all six (a sticky action repeats it); no-op at a reset."""


@dataclass(frozen=True)
class MinAtarEnv:
    """One game under one protocol, with the deep engine's interface: ``reset(key)``, ``step(state, action, key)
    -> (state, reward, terminated, truncated)``, ``observe(state)``."""

    name: str
    game: Game
    protocol: Protocol

    @functools.cached_property
    def _env(self) -> Any:
        """gymnax's game, built outside any trace: its constructor makes arrays, which, made first inside a jitted
        function, would be that trace's tracers, cached here and leaked into the next trace."""
        with jax.ensure_compile_time_eval():
            return gymnax_classes()[self.game.module_name](use_minimal_action_set=False)

    @functools.cached_property
    def _params(self) -> Any:
        with jax.ensure_compile_time_eval():
            return self._env.default_params

    @property
    def actions(self) -> tuple[int, ...]:
        """The agent's actions, as indices into MinAtar's six."""
        return minatar.actions(self.game, self.protocol)

    @property
    def n_actions(self) -> int:
        return len(self.actions)

    @property
    def action_names(self) -> tuple[str, ...]:
        return tuple(ACTION_NAMES[action] for action in self.actions)

    @property
    def observation_shape(self) -> tuple[int, int, int]:
        return (10, 10, len(self.game.channels))

    @property
    def max_steps(self) -> int | None:
        return minatar.max_steps(self.game, self.protocol)

    def reset(self, key: jax.Array) -> MinAtarState:
        with jax.enable_x64(False):  # gymnax's games mix int32 and the default int; 32 bits throughout
            _, game = self._env.reset_env(key, self._params)
            return MinAtarState(_thirty_two_bits(game), jnp.zeros((), jnp.int32))

    def step(self, state: MinAtarState, action: jax.Array, key: jax.Array
             ) -> tuple[MinAtarState, jax.Array, jax.Array, jax.Array]:
        """One step: the chosen action, or with the protocol's chance the last one again (the reference's
        ``Environment.act``), then the game's transition."""
        with jax.enable_x64(False):
            sticky_key, game_key = jax.random.split(key)
            chosen = jnp.asarray(self.actions, jnp.int32)[jax.lax.convert_element_type(action, jnp.int32)]
            if self.protocol.sticky_action_prob > 0.0:
                sticky = jax.random.uniform(sticky_key) < self.protocol.sticky_action_prob
                chosen = jnp.where(sticky, state.last_action, chosen)
            _, game, reward, terminated, _ = self._env.step_env(game_key, state.game, chosen, self._params)
            if self.max_steps is None:
                if self.game.module_name == "freeway":
                    terminated = terminated | (game.time >= FREEWAY_STEPS)
                truncated = jnp.zeros((), bool)
            else:
                truncated = ~terminated & (game.time >= self.max_steps)
            return MinAtarState(_thirty_two_bits(game), chosen), reward, terminated, truncated

    def observe(self, state: MinAtarState) -> jax.Array:
        with jax.enable_x64(False):
            observation: jax.Array = self._env.get_obs(state.game).astype(bool)
            return observation


def _thirty_two_bits(state: Any) -> Any:
    """Every field of a game's state as a 32-bit (or boolean) array of fixed type: gymnax leaves Python numbers
    in its states, which JAX's 64-bit mode, on in the deep engine for classic control's physics, would widen."""

    def fixed(value: Any) -> jax.Array:
        value = jnp.asarray(value)
        kind = jnp.bool_ if value.dtype == jnp.bool_ else jnp.int32 if jnp.issubdtype(value.dtype, jnp.integer) \
            else jnp.float32
        return jax.lax.convert_element_type(value, kind)

    return jax.tree.map(fixed, state)


@functools.cache
def gymnax_classes() -> dict[str, Any]:
    """Each game's port (:data:`rlcompare.deep.minatar.gymnax_games.GYMNAX_CLASSES`), loaded once per process where a
    game is first built: outside any trace and in JAX's 32-bit default, as at an import."""
    with jax.ensure_compile_time_eval(), jax.enable_x64(False):
        from rlcompare.deep.minatar.gymnax_games import GYMNAX_CLASSES

    return GYMNAX_CLASSES


def minatar_env(name: str) -> MinAtarEnv:
    """``MinAtar/<Game>-v0`` (the paper's protocol) or ``<Game>-MinAtar`` (gymnax's)."""
    game, protocol = NAMES[name]
    return MinAtarEnv(name, game, protocol)
