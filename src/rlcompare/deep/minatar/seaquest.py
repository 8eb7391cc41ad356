"""Seaquest as the reference MinAtar plays it (Young and Tian 2019, arXiv:1903.03176), on gymnax's JAX port.

gymnax's ``MinSeaquest`` (1.0.1) keeps the reference's phases, constants and observation, with each entity list
as a buffer of 100 rows and a count (rows in list order). The reference (``minatar`` 1.0.15, ``Env.act``)
resolves each phase in a loop over a list, newest entity first, and gymnax's vectorised phases give other results
where several entities meet in one cell. :class:`Seaquest` keeps gymnax's state, observation, spawn rule, player,
enemy-bullet phase and buffer helpers, and replaces the other phases by ones equal to the reference's loops: within
each cell the k-th entity in the loop's order takes the k-th target in list order (``_pair_in_cells``).

Departures from gymnax, each to the reference:

- SQ-6: surfacing with no rescued diver only ends the episode (gymnax also refilled oxygen, took a diver, ramped).
- SQ-1: an enemy sub destroyed in its own phase still fires if its shot timer is 0.
- SQ-3: friendly bullets go newest first, each taking the first remaining fish in its cell, else the first sub.
- SQ-4: divers go newest first, each picked up before or after its own move while fewer than six are aboard.
- SQ-2: an enemy moving into a cell takes the first friendly bullet there in list order (gymnax: the last).
- SQ-2b: enemies moving into one bullet's cell go newest first, and the newest takes it (gymnax: the oldest).
- SQ-5: an enemy moving onto the player meets no bullet, nor does an enemy that did not move.
- SQ-8: enemy bullets fired in one step are listed newest sub first, as the reference appends them.
- Spawns: five uniforms from the step's key in the reference's order (:func:`seaquest_draws`).
- A terminal state steps to itself with reward 0, as the reference's ``act`` does.

Left as gymnax has it: each buffer holds 100 entities (the reference's lists are unbounded; play stays far below),
and entities are removed by identity, where the reference's ``list.remove`` takes the first entry equal in value
(among entities equal in every field this reorders a list; in play only an edge spawn can reach it, to no effect).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
from gymnax.environments.minatar.seaquest import EnvParams, EnvState, MinSeaquest
from gymnax.environments.minatar.seaquest_helpers import (
    BOARD_SIZE,
    MAX_ENTITIES,
    active_mask,
    append,
    append_many,
    compact,
    move_entities,
)

__all__ = ["EnvParams", "EnvState", "Seaquest", "SpawnDraws", "seaquest_draws", "spawn_row"]


class SpawnDraws(NamedTuple):
    """One step's spawn draws, uniforms in [0, 1) in the reference's order (``_spawn_enemy``'s ``rand``, ``rand``,
    ``randint(1, 9)``, then ``_spawn_diver``'s ``rand``, ``randint(1, 9)``); each is used only if its spawn is due."""

    enemy_left_to_right: jax.Array
    """from the left edge, moving right, where below 1/2"""
    enemy_is_sub: jax.Array
    """a sub where below 1/3, else a fish"""
    enemy_row: jax.Array
    """the row, by :func:`spawn_row`"""
    diver_left_to_right: jax.Array
    """from the left edge, moving right, where below 1/2"""
    diver_row: jax.Array
    """the row, by :func:`spawn_row`"""


def seaquest_draws(key: jax.Array) -> SpawnDraws:
    """The spawn draws of the step with this key."""
    return SpawnDraws(*jax.random.uniform(key, (5,)))


def spawn_row(uniform: jax.Array) -> jax.Array:
    """A row in 1..8, uniformly (the reference's ``randint(low=1, high=9)``): ``min(int(u * 8), 7) + 1``."""
    return jnp.minimum((uniform * 8).astype(jnp.int32), 7) + 1


def _direction(entities: jax.Array) -> jax.Array:
    return jnp.where(entities[:, 2] != 0, 1, -1)


def _at(entities: jax.Array, x: jax.Array, y: jax.Array) -> jax.Array:
    return (entities[:, 0] == x) & (entities[:, 1] == y)


def _pair_in_cells(hunters: jax.Array, hunting: jax.Array, prey: jax.Array, prey_live: jax.Array
                   ) -> tuple[jax.Array, jax.Array]:
    """Which hunters take prey and which prey are taken, as the reference's loops decide: hunters are visited
    newest first (``for ... in reversed(...)``), each taking the first prey still there in its cell in list order
    (``for x in ...: ... break``), so the k-th hunter of a cell (newest first) takes its k-th prey (list order).
    Only ``[:, :2]`` (x, y) of each row is read."""
    same_hunters = jnp.all(hunters[:, None, :2] == hunters[None, :, :2], -1) & hunting[:, None] & hunting[None, :]
    same_prey = jnp.all(prey[:, None, :2] == prey[None, :, :2], -1) & prey_live[:, None] & prey_live[None, :]
    met = jnp.all(hunters[:, None, :2] == prey[None, :, :2], -1) & hunting[:, None] & prey_live[None, :]
    hunter_index = jnp.arange(hunters.shape[0])
    prey_index = jnp.arange(prey.shape[0])
    hunter_rank = jnp.sum(same_hunters & (hunter_index[None, :] > hunter_index[:, None]), 1)
    prey_rank = jnp.sum(same_prey & (prey_index[None, :] < prey_index[:, None]), 1)
    return hunting & (hunter_rank < jnp.sum(met, 1)), prey_live & (prey_rank < jnp.sum(met, 0))


class EnemyMove(NamedTuple):
    """One enemy kind's phase (the reference's loop over its subs or its fish), before the survivors are kept."""

    entities: jax.Array
    """every row moved (x and move timer), the destroyed ones too"""
    survives: jax.Array
    """still on the board and not struck"""
    f_bullets: jax.Array
    f_bullet_count: jax.Array
    reward: jax.Array
    terminal: jax.Array


def _move_enemies(state: EnvState, entities: jax.Array, count: jax.Array) -> EnemyMove:
    """The reference's loop over subs or fish, but the shots: an enemy on the player ends the episode; one whose
    move timer is 0 moves (timer reset to ``move_speed``), leaves the board, ends the episode where it reaches the
    player, and otherwise is struck by the first friendly bullet in its new cell (newest enemies first)."""
    live = active_mask(count)
    on_player = live & _at(entities, state.sub_x, state.sub_y)
    moves = live & (entities[:, 3] == 0)
    x = jnp.where(moves, entities[:, 0] + _direction(entities), entities[:, 0])
    timer = jnp.where(moves, state.move_speed, jnp.maximum(entities[:, 3] - 1, 0))
    entities = entities.at[:, 0].set(x).at[:, 3].set(timer)
    on_board = (x >= 0) & (x < BOARD_SIZE)
    reaches_player = moves & on_board & _at(entities, state.sub_x, state.sub_y)
    bullets_live = active_mask(state.f_bullet_count)
    struck, spent = _pair_in_cells(entities, moves & on_board & ~reaches_player, state.f_bullets, bullets_live)
    bullets, bullet_count = compact(state.f_bullets, bullets_live & ~spent)
    return EnemyMove(entities, live & on_board & ~struck, bullets, bullet_count,
                     jnp.sum(struck, dtype=jnp.float32), jnp.any(on_player | reaches_player))


class Seaquest(MinSeaquest):
    """gymnax's ``MinSeaquest`` with the reference's transition (the module's docstring lists what differs)."""

    def step_env(self, key: jax.Array, state: EnvState, action: int | float | jax.Array, params: EnvParams
                 ) -> tuple[jax.Array, EnvState, jax.Array, jax.Array, dict[Any, Any]]:
        """One step of the reference's ``act``, its phases in its order."""
        stepped = self.spawn(seaquest_draws(key), state, params)
        stepped = self._step_agent(stepped, self.action_set[action], params)
        stepped, reward = self._step_friendly_bullets(stepped)
        stepped = self._step_divers(stepped, params)
        stepped, sub_reward, sub_terminal = self._step_enemy_subs(stepped, params)
        stepped, bullet_terminal = self._step_enemy_bullets(stepped)
        stepped, fish_reward, fish_terminal = self._step_enemy_fish(stepped)
        stepped, timer_reward, timer_terminal = self._step_timers(stepped, params)
        done = sub_terminal | bullet_terminal | fish_terminal | timer_terminal
        stepped = stepped.replace(time=state.time + 1, terminal=done)
        reward = reward + sub_reward + fish_reward + timer_reward
        # The reference's act leaves a terminal state as it is and returns (0, True).
        stepped = jax.tree.map(lambda old, new: jnp.where(state.terminal, old, new), state, stepped)
        reward = jnp.where(state.terminal, 0.0, reward).astype(jnp.float32)
        done = done | state.terminal
        return (jax.lax.stop_gradient(self.get_obs(stepped, params)), jax.lax.stop_gradient(stepped), reward, done,
                {"discount": self.discount(stepped, params)})

    def spawn(self, draws: SpawnDraws, state: EnvState, params: EnvParams) -> EnvState:
        """``_spawn_enemy`` when its timer is 0 (none where an enemy moves the other way in that row), then
        ``_spawn_diver`` when its timer is 0, with this step's draws."""
        left_to_right = draws.enemy_left_to_right < 0.5
        is_sub = draws.enemy_is_sub < 1 / 3
        row = spawn_row(draws.enemy_row)
        opposed = jnp.any(active_mask(state.e_subs_count) & (state.e_subs[:, 1] == row)
                          & ((state.e_subs[:, 2] != 0) != left_to_right)) | jnp.any(
            active_mask(state.e_fish_count) & (state.e_fish[:, 1] == row)
            & ((state.e_fish[:, 2] != 0) != left_to_right))
        due = state.e_spawn_timer == 0
        spawns = due & ~opposed
        enemy = jnp.stack([jnp.where(left_to_right, 0, BOARD_SIZE - 1), row, left_to_right.astype(jnp.int32),
                           jnp.asarray(state.move_speed, jnp.int32),
                           jnp.asarray(params.enemy_shot_interval, jnp.int32)]).astype(jnp.int32)
        subs, sub_count = append(state.e_subs, state.e_subs_count, enemy, spawns & is_sub)
        fish, fish_count = append(state.e_fish, state.e_fish_count, enemy[:4], spawns & ~is_sub)
        diver_left_to_right = draws.diver_left_to_right < 0.5
        diver = jnp.stack([jnp.where(diver_left_to_right, 0, BOARD_SIZE - 1), spawn_row(draws.diver_row),
                           diver_left_to_right.astype(jnp.int32),
                           jnp.asarray(params.diver_move_interval, jnp.int32)]).astype(jnp.int32)
        diver_due = state.d_spawn_timer == 0
        divers, divers_count = append(state.divers, state.divers_count, diver, diver_due)
        return state.replace(
            e_subs=subs, e_subs_count=sub_count, e_fish=fish, e_fish_count=fish_count, divers=divers,
            divers_count=divers_count, e_spawn_timer=jnp.where(due, state.e_spawn_speed, state.e_spawn_timer),
            d_spawn_timer=jnp.where(diver_due, params.diver_spawn_speed, state.d_spawn_timer))

    def _step_friendly_bullets(self, state: EnvState) -> tuple[EnvState, jax.Array]:
        """Each bullet moves (leaving the board past an edge); newest first, each takes the first fish still in its
        cell, else the first sub (SQ-3)."""
        bullets = state.f_bullets
        x = bullets[:, 0] + _direction(bullets)
        bullets = bullets.at[:, 0].set(x)
        flying = active_mask(state.f_bullet_count) & (x >= 0) & (x < BOARD_SIZE)
        fish_live = active_mask(state.e_fish_count)
        subs_live = active_mask(state.e_subs_count)
        targets = jnp.concatenate([state.e_fish[:, :2], state.e_subs[:, :2]])
        hit, taken = _pair_in_cells(bullets, flying, targets, jnp.concatenate([fish_live, subs_live]))
        bullets, bullet_count = compact(bullets, flying & ~hit)
        fish, fish_count = compact(state.e_fish, fish_live & ~taken[:MAX_ENTITIES])
        subs, sub_count = compact(state.e_subs, subs_live & ~taken[MAX_ENTITIES:])
        return state.replace(f_bullets=bullets, f_bullet_count=bullet_count, e_fish=fish, e_fish_count=fish_count,
                             e_subs=subs, e_subs_count=sub_count), jnp.sum(hit, dtype=jnp.float32)

    def _step_divers(self, state: EnvState, params: EnvParams) -> EnvState:
        """Newest first, a diver on the player, or reaching the player by its move, is picked up while fewer than
        six are aboard (SQ-4); the others move when their timer is 0."""
        divers = state.divers
        live = active_mask(state.divers_count)
        reaches = (divers[:, 3] == 0) & _at(divers.at[:, 0].add(_direction(divers)), state.sub_x, state.sub_y)
        candidate = live & (_at(divers, state.sub_x, state.sub_y) | reaches)
        newer_candidates = jnp.cumsum(candidate[::-1])[::-1] - candidate
        picked = candidate & (newer_candidates < jnp.maximum(6 - state.diver_count, 0))
        divers, divers_count = compact(divers, live & ~picked)
        divers, divers_count = move_entities(divers, divers_count, params.diver_move_interval)
        return state.replace(divers=divers, divers_count=divers_count,
                             diver_count=state.diver_count + jnp.sum(picked, dtype=jnp.int32))

    def _step_enemy_subs(self, state: EnvState, params: EnvParams) -> tuple[EnvState, jax.Array, jax.Array]:
        """:func:`_move_enemies` for the subs; then every sub of the loop whose shot timer is 0 fires from where it
        now is, a destroyed one too (SQ-1; a shot from off the board vanishes in the enemy-bullet phase and is
        left out), newest sub first (SQ-8)."""
        moved = _move_enemies(state, state.e_subs, state.e_subs_count)
        subs = moved.entities
        fires = active_mask(state.e_subs_count) & (subs[:, 4] == 0)
        subs = subs.at[:, 4].set(jnp.where(fires, params.enemy_shot_interval, jnp.maximum(subs[:, 4] - 1, 0)))
        on_board = (subs[:, 0] >= 0) & (subs[:, 0] < BOARD_SIZE)
        e_bullets, e_bullet_count = append_many(state.e_bullets, state.e_bullet_count, subs[::-1, :3],
                                                (fires & on_board)[::-1])
        subs, sub_count = compact(subs, moved.survives)
        return state.replace(e_subs=subs, e_subs_count=sub_count, f_bullets=moved.f_bullets,
                             f_bullet_count=moved.f_bullet_count, e_bullets=e_bullets,
                             e_bullet_count=e_bullet_count), moved.reward, moved.terminal

    def _step_enemy_fish(self, state: EnvState) -> tuple[EnvState, jax.Array, jax.Array]:
        """:func:`_move_enemies` for the fish."""
        moved = _move_enemies(state, state.e_fish, state.e_fish_count)
        fish, fish_count = compact(moved.entities, moved.survives)
        return state.replace(e_fish=fish, e_fish_count=fish_count, f_bullets=moved.f_bullets,
                             f_bullet_count=moved.f_bullet_count), moved.reward, moved.terminal

    def _step_timers(self, state: EnvState, params: EnvParams) -> tuple[EnvState, jax.Array, jax.Array]:
        """gymnax's timers, oxygen and surfacing, but surfacing with no rescued diver only ends the episode (SQ-6)."""
        stepped, reward, terminal = super()._step_timers(state, params)
        empty_handed = (state.sub_y == 0) & ~state.surface & (state.diver_count == 0)
        unchanged = stepped.replace(oxygen=state.oxygen, diver_count=state.diver_count, surface=state.surface,
                                    e_spawn_speed=state.e_spawn_speed, move_speed=state.move_speed,
                                    ramp_index=state.ramp_index)
        stepped = jax.tree.map(lambda kept, new: jnp.where(empty_handed, kept, new), unchanged, stepped)
        return stepped, jnp.where(empty_handed, 0.0, reward).astype(jnp.float32), terminal
