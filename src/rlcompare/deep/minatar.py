"""MinAtar's five games (Young and Tian 2019, arXiv 1903.03176) for the deep engine, under two named protocols.

The games are gymnax's JAX ports (pinned, 1.0.1), checked against the reference ``minatar`` package (1.0.15) in
``tests/test_minatar_games.py``; where gymnax departs from the reference the port here follows the reference
(``docs/minatar.md`` lists each case). Around the game, a protocol fixes what the agent plays:

| protocol  | sticky actions | actions               | episode ends                                         |
|-----------|----------------|-----------------------|------------------------------------------------------|
| ``minatar`` | 0.1            | all 6                 | the game's own end only (the MinAtar paper's)        |
| ``gymnax``  | none           | the game's minimal set | the game's end, or gymnax's limit (PQN's curves)   |

An environment is named as its library names it: ``MinAtar/Breakout-v0`` is the reference's Gymnasium
registration with the full action set and the paper's protocol, ``Breakout-MinAtar`` gymnax's. The state carries
the last action taken, which a sticky action repeats. Observations are booleans, ``(10, 10, channels)``, until
the network.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
from gymnax.environments.minatar import asterix, breakout, freeway, seaquest, space_invaders

ACTION_NAMES = ("no-op", "left", "up", "right", "down", "fire")
"""MinAtar's six actions, in the reference's order (``n l u r d f``)."""


@dataclass(frozen=True)
class Protocol:
    """How the agent plays a game: the MinAtar paper's or gymnax's (PQN's)."""

    name: str
    sticky_action_prob: float
    """The chance that the previous action is repeated in place of the one chosen (Machado et al. 2018)."""
    full_action_set: bool
    """All six actions; otherwise the game's minimal set."""
    time_limit: bool
    """Truncate at gymnax's ``max_steps_in_episode``; otherwise only the game ends an episode."""
    summary: str


PROTOCOLS = {
    "minatar": Protocol("minatar", 0.1, True, False,
                        "the MinAtar paper's: sticky actions 0.1, all 6 actions, difficulty ramping, no time limit"),
    "gymnax": Protocol("gymnax", 0.0, False, True,
                       "gymnax's and PQN's: no sticky actions, the minimal action set, gymnax's time limits"),
}


class _Asterix(asterix.MinAsterix):
    """gymnax's Asterix with the reference's spawn: a new enemy or treasure takes a free row drawn uniformly, and
    none spawns when every row is taken (gymnax never draws the first row of its shuffled order, and with no row
    free overwrites a taken one)."""

    def step_env(self, key: jax.Array, state: asterix.EnvState, action: jax.Array, params: asterix.EnvParams
                 ) -> tuple[jax.Array, asterix.EnvState, jax.Array, jax.Array, dict]:
        spawn_now = state.spawn_timer == 0
        state = state.replace(entities=jnp.where(spawn_now, asterix_spawn(key, state.entities), state.entities),
                              spawn_timer=jnp.where(spawn_now, state.spawn_speed, state.spawn_timer))
        state = asterix.step_agent(state, self.action_set[action])
        state, reward, done = asterix.step_entities(state)
        state = asterix.step_timers(state, params)
        state = state.replace(time=state.time + 1, terminal=done)
        return self.get_obs(state), state, reward.astype(jnp.float32), done, {}


class SpawnDraws(NamedTuple):
    """The draws of one Asterix spawn, in the reference's order (``rand``, ``rand``, ``randint``)."""

    left_to_right: jax.Array
    """uniform in [0, 1): from the left edge, moving right, where below 1/2"""
    gold: jax.Array
    """uniform in [0, 1): treasure where below 1/3, else an enemy"""
    slot_rank: jax.Array
    """uniform in [0, 1): which free row, by rank among the free rows"""


def asterix_spawn_draws(key: jax.Array) -> SpawnDraws:
    return SpawnDraws(*jax.random.uniform(key, (3,)))


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


@dataclass(frozen=True)
class Game:
    """One game: its gymnax class, its observation channels and its minimal action set (indices into the six)."""

    title: str
    """``Breakout``: as the Gymnasium names spell it."""
    module_name: str
    """``breakout``: as the reference package names it."""
    gymnax_class: type
    channels: tuple[str, ...]
    minimal_actions: tuple[int, ...]


GAMES = {game.module_name: game for game in (
    Game("Asterix", "asterix", _Asterix, ("player", "enemy", "trail", "gold"), (0, 1, 2, 3, 4)),
    Game("Breakout", "breakout", breakout.MinBreakout, ("paddle", "ball", "trail", "brick"), (0, 1, 3)),
    Game("Freeway", "freeway", freeway.MinFreeway,
         ("chicken", "car", "speed1", "speed2", "speed3", "speed4", "speed5"), (0, 2, 4)),
    Game("Seaquest", "seaquest", seaquest.MinSeaquest,
         ("sub_front", "sub_back", "friendly_bullet", "trail", "enemy_bullet", "enemy_fish", "enemy_sub",
          "oxygen_guage", "diver_guage", "diver"), (0, 1, 2, 3, 4, 5)),
    Game("SpaceInvaders", "space_invaders", space_invaders.MinSpaceInvaders,
         ("cannon", "alien", "alien_left", "alien_right", "friendly_bullet", "enemy_bullet"), (0, 1, 3, 5)),
)}
FREEWAY_STEPS = 2501
"""The reference's Freeway ends its episode (terminal) after this many steps; gymnax truncates one step earlier."""


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

    @property
    def _env(self) -> Any:
        return self.game.gymnax_class(use_minimal_action_set=False)

    @property
    def _params(self) -> Any:
        return self._env.default_params

    @property
    def actions(self) -> tuple[int, ...]:
        """The agent's actions, as indices into MinAtar's six."""
        return tuple(range(len(ACTION_NAMES))) if self.protocol.full_action_set else self.game.minimal_actions

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
    def observation_size(self) -> int:
        return 10 * 10 * len(self.game.channels)

    @property
    def max_steps(self) -> int | None:
        """gymnax's limit under its protocol; None where only the game ends an episode."""
        return int(self._params.max_steps_in_episode) if self.protocol.time_limit else None

    def reset(self, key: jax.Array) -> MinAtarState:
        _, game = self._env.reset_env(key, self._params)
        return MinAtarState(game, jnp.zeros((), jnp.int32))

    def step(self, state: MinAtarState, action: jax.Array, key: jax.Array
             ) -> tuple[MinAtarState, jax.Array, jax.Array, jax.Array]:
        """One step: the chosen action, or with the protocol's chance the last one again (the reference's
        ``Environment.act``), then the game's transition."""
        sticky_key, game_key = jax.random.split(key)
        chosen = jnp.asarray(self.actions, jnp.int32)[action]
        if self.protocol.sticky_action_prob > 0.0:
            sticky = jax.random.uniform(sticky_key) < self.protocol.sticky_action_prob
            chosen = jnp.where(sticky, state.last_action, chosen)
        _, game, reward, terminated, _ = self._env.step_env(game_key, state.game, chosen, self._params)
        if self.game.module_name == "freeway" and not self.protocol.time_limit:
            terminated = terminated | (game.time >= FREEWAY_STEPS)
        truncated = ~terminated & (game.time >= self.max_steps) if self.protocol.time_limit else jnp.zeros((), bool)
        return MinAtarState(game, chosen), reward, terminated, truncated

    def observe(self, state: MinAtarState) -> jax.Array:
        return self._env.get_obs(state.game).astype(bool)


def minatar_env(name: str) -> MinAtarEnv:
    """``MinAtar/<Game>-v0`` (the paper's protocol) or ``<Game>-MinAtar`` (gymnax's)."""
    for game in GAMES.values():
        if name == f"MinAtar/{game.title}-v0":
            return MinAtarEnv(name, game, PROTOCOLS["minatar"])
        if name == f"{game.title}-MinAtar":
            return MinAtarEnv(name, game, PROTOCOLS["gymnax"])
    raise KeyError(name)


MINATAR_ENV_NAMES = tuple(name for game in GAMES.values()
                          for name in (f"MinAtar/{game.title}-v0", f"{game.title}-MinAtar"))
