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
from gymnax.environments.minatar import asterix, breakout, freeway, space_invaders

from rlcompare.deep.minatar.seaquest import Seaquest
from rlcompare.envs import minatar
from rlcompare.envs.minatar import ACTION_NAMES, FREEWAY_STEPS, NAMES, Game, Protocol


class _Asterix(asterix.MinAsterix):
    """gymnax's Asterix with the reference's spawn: a new enemy or treasure takes a free row drawn uniformly, and
    none spawns when every row is taken (gymnax never draws the first row of its shuffled order, and with no row
    free overwrites a taken one)."""

    def step_env(self, key: jax.Array, state: asterix.EnvState, action: jax.Array, params: asterix.EnvParams
                 ) -> tuple[jax.Array, asterix.EnvState, jax.Array, jax.Array, dict[str, Any]]:
        spawn_now = state.spawn_timer == 0
        state = state.replace(entities=jnp.where(spawn_now, asterix_spawn(key, state.entities), state.entities),
                              spawn_timer=jnp.where(spawn_now, state.spawn_speed, state.spawn_timer))
        state = asterix.step_agent(state, self.action_set[action])
        state, reward, done = asterix.step_entities(state)
        state = asterix.step_timers(state, params)
        state = state.replace(time=state.time + 1, terminal=done)
        return self.get_obs(state), state, reward.astype(jnp.float32), done, {}


class AsterixDraws(NamedTuple):
    """The draws of one Asterix spawn, in the reference's order (``rand``, ``rand``, ``randint``)."""

    left_to_right: jax.Array
    """uniform in [0, 1): from the left edge, moving right, where below 1/2"""
    gold: jax.Array
    """uniform in [0, 1): treasure where below 1/3, else an enemy"""
    slot_rank: jax.Array
    """uniform in [0, 1): which free row, by rank among the free rows"""


def asterix_spawn_draws(key: jax.Array) -> AsterixDraws:
    return AsterixDraws(*jax.random.uniform(key, (3,)))


def asterix_spawn(key: jax.Array, entities: jax.Array) -> jax.Array:
    """The entities after a spawn (the reference's ``_spawn_entity``): rows are ``[x, y, lr, gold, alive]``."""
    draws = asterix_spawn_draws(key)
    free = entities[:, 4] == 0
    n_free = jnp.sum(free)
    rank = jnp.minimum((draws.slot_rank * n_free).astype(jnp.int32), n_free - 1)
    slot = jnp.argmax(jnp.cumsum(free) == rank + 1)
    left_to_right = draws.left_to_right < 0.5
    entity = jnp.array([jnp.where(left_to_right, 0, 9), slot + 1, left_to_right, draws.gold < 1 / 3, 1],
                       entities.dtype)
    return jnp.where(n_free > 0, entities.at[slot].set(entity), entities)


class MinAtarState(NamedTuple):
    game: Any
    """gymnax's state of the game (its ``time`` counts this episode's steps)."""
    last_action: jax.Array
    """The last action taken, among all six (a sticky action repeats it); no-op at a reset."""


GYMNAX_CLASSES = {"asterix": _Asterix, "breakout": breakout.MinBreakout, "freeway": freeway.MinFreeway,
                  "seaquest": Seaquest, "space_invaders": space_invaders.MinSpaceInvaders}
"""Each game's port: gymnax's class, or one here where gymnax departs from the reference."""


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
            return GYMNAX_CLASSES[self.game.module_name](use_minimal_action_set=False)

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


def minatar_env(name: str) -> MinAtarEnv:
    """``MinAtar/<Game>-v0`` (the paper's protocol) or ``<Game>-MinAtar`` (gymnax's)."""
    game, protocol = NAMES[name]
    return MinAtarEnv(name, game, protocol)
