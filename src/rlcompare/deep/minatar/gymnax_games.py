"""gymnax's MinAtar games as the deep engine builds them (:mod:`rlcompare.deep.minatar.games`): gymnax's classes, or
one here where gymnax departs from the reference (Asterix's spawn; Seaquest in
:mod:`rlcompare.deep.minatar.seaquest`). Loaded where a game is first built, not where one is named: gymnax's package
loads every environment it has as it loads, seaborn and scipy's statistics among them (seconds), while a
configuration's checks and a plan read only a game's sizes.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
from gymnax.environments.minatar import asterix, breakout, freeway, space_invaders

from rlcompare.deep.minatar.seaquest import Seaquest


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


GYMNAX_CLASSES = {"asterix": _Asterix, "breakout": breakout.MinBreakout, "freeway": freeway.MinFreeway,
                  "seaquest": Seaquest, "space_invaders": space_invaders.MinSpaceInvaders}
"""Each game's port: gymnax's class, or one here where gymnax departs from the reference."""
