"""MinAtar's games in JAX against the reference ``minatar`` package, whole episodes at a time.

The reference's state is translated into ours at its reset; from there both play the same actions, and after every
step the observation, the reward, the ending and the whole state must be equal. Each game draws its randomness
from a NumPy generator in the reference and from a JAX key in ours: here the reference's generator is replaced, step
by step, by one that serves the draws our port made from that step's key (:class:`Served`), so that the
deterministic rules are compared exactly and every random outcome too; the draws themselves are tested by
distribution at the end of the file. The policies play long episodes (the paddle follows the ball, the chicken
mostly climbs, the player of Asterix looks ahead), so that rows of bricks are refilled, cars redrawn and
Asterix's difficulty ramps to the end.
"""

from __future__ import annotations

import copy
import functools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pytest

jax = pytest.importorskip("jax")
pytest.importorskip("gymnax")
pytest.importorskip("minatar")

import jax.numpy as jnp  # noqa: E402
from gymnax.environments.minatar import asterix, breakout, freeway, space_invaders  # noqa: E402
from minatar.environments import asterix as ref_asterix  # noqa: E402
from minatar.environments import breakout as ref_breakout  # noqa: E402
from minatar.environments import freeway as ref_freeway  # noqa: E402
from minatar.environments import space_invaders as ref_space_invaders  # noqa: E402
from scipy import stats  # noqa: E402

from rlcompare.deep.minatar.games import minatar_env  # noqa: E402
from rlcompare.deep.minatar.gymnax_games import GYMNAX_CLASSES, asterix_spawn, asterix_spawn_draws  # noqa: E402
from rlcompare.envs.minatar import GAMES  # noqa: E402


class Served:
    """The reference's ``self.random`` for one step: ``rand`` and ``randint`` return, in order, the values our
    port drew from the step's key; :attr:`whole` tells whether the reference asked for all of them or none."""

    def __init__(self, rand: list, randint: list) -> None:
        self.values = {"rand": list(rand), "randint": list(randint)}
        self.total = len(rand) + len(randint)

    def rand(self, *shape: int):
        return self.values["rand"].pop(0)

    def randint(self, *args, **kwargs):
        return self.values["randint"].pop(0)

    @property
    def whole(self) -> bool:
        left = len(self.values["rand"]) + len(self.values["randint"])
        return left in (0, self.total)


# --- The reference's state as gymnax's fields (NumPy) ---

def asterix_fields(ref, time: int) -> dict[str, np.ndarray]:
    entities = np.zeros((8, 5), np.int32)
    for row, entity in enumerate(ref.entities):
        if entity is not None:
            entities[row] = [entity[0], entity[1], bool(entity[2]), bool(entity[3]), 1]
    names = ("player_x", "player_y", "shot_timer", "spawn_speed", "spawn_timer", "move_speed", "move_timer",
             "ramp_timer", "ramp_index")
    return {**{name: np.int32(getattr(ref, name)) for name in names}, "entities": entities,
            "time": np.int32(time), "terminal": np.bool_(ref.terminal)}


def breakout_fields(ref, time: int) -> dict[str, np.ndarray]:
    names = ("ball_y", "ball_x", "ball_dir", "pos", "last_y", "last_x")
    return {**{name: np.int32(getattr(ref, name)) for name in names},
            "brick_map": np.asarray(ref.brick_map, np.float32), "strike": np.bool_(ref.strike),
            "time": np.int32(time), "terminal": np.bool_(ref.terminal)}


def freeway_fields(ref, time: int) -> dict[str, np.ndarray]:
    assert time == ref_freeway.time_limit - ref.terminate_timer
    return {"pos": np.int32(ref.pos), "cars": np.array(ref.cars, np.int32), "move_timer": np.int32(ref.move_timer),
            "time": np.int32(time), "terminal": np.bool_(ref.terminal)}


def space_invaders_fields(ref, time: int) -> dict[str, np.ndarray]:
    names = ("pos", "alien_dir", "enemy_move_interval", "alien_move_timer", "alien_shot_timer", "ramp_index",
             "shot_timer")
    maps = ("f_bullet_map", "e_bullet_map", "alien_map")
    return {**{name: np.int32(getattr(ref, name)) for name in names},
            **{name: np.asarray(getattr(ref, name), np.float32) for name in maps},
            "ramping": np.bool_(ref.ramping), "time": np.int32(time), "terminal": np.bool_(ref.terminal)}


def as_state(state_class: type, fields: dict[str, np.ndarray]):
    return state_class(**{name: jnp.asarray(value) for name, value in fields.items()})


def comparable(fields: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Asterix's rows that hold no entity compare as zeros, whatever gymnax left in them."""
    if "entities" in fields:
        fields = {**fields, "entities": fields["entities"] * (fields["entities"][:, 4:5] != 0)}
    return fields


# --- The draws our port makes from a step's key, served to the reference ---

SPAWN_DRAWS = jax.jit(asterix_spawn_draws)


def asterix_draws(key: jax.Array, state: asterix.EnvState) -> Served:
    draws = jax.device_get(SPAWN_DRAWS(key))
    n_free = int(np.sum(np.asarray(state.entities)[:, 4] == 0))
    rank = min(int(float(draws.slot_rank) * n_free), n_free - 1)
    return Served(rand=[float(draws.left_to_right), float(draws.gold)], randint=[rank] if n_free else [])


@jax.jit
def freeway_speeds_and_directions(key: jax.Array) -> tuple[jax.Array, jax.Array]:
    speed_key, direction_key = jax.random.split(key)
    return jax.random.randint(speed_key, (8,), 1, 6), jax.random.choice(direction_key, jnp.array([-1, 1]), (8,))


def freeway_draws(key: jax.Array, state: freeway.EnvState) -> Served:
    """gymnax draws eight speeds and directions at every step and keeps them where the chicken crossed."""
    speeds, directions = (np.asarray(draws) for draws in jax.device_get(freeway_speeds_and_directions(key)))
    return Served(rand=[0.5 + 0.25 * directions], randint=[np.array(speeds)])


# --- Policies that keep an episode going ---

def follow_the_ball(ref, rng: np.random.Generator) -> int:
    """Move under the column where the ball will next reach the paddle's row; a random action one step in 20."""
    if rng.random() < 0.05:
        return int(rng.integers(6))
    ahead = copy.deepcopy(ref)
    target = ref.ball_x
    for _ in range(30):
        if (ahead.ball_y == 8 and ahead.ball_dir in (2, 3)) or ahead.terminal:
            target = ahead.ball_x
            break
        ahead.act(0)
    return 1 if target < ref.pos else 3 if target > ref.pos else 0


def climb(ref, rng: np.random.Generator) -> int:
    return 2 if rng.random() < 0.7 else int(rng.integers(6))


def look_ahead(ref, rng: np.random.Generator) -> int:
    """A random action among those after which some action survives (spawns left out of the lookahead), away
    from the edge columns where enemies appear where one can."""

    def survives(env, depth: int) -> bool:
        if env.terminal:
            return False
        return depth == 0 or any(survives(_after(env, action), depth - 1) for action in range(5))

    def _after(env, action: int):
        env = copy.copy(env)
        env.entities = [None if entity is None else list(entity) for entity in env.entities]
        env._spawn_entity = lambda: None
        env.act(action)
        return env

    safe = [(after.player_x in (0, 9), int(action)) for action in rng.permutation(6)
            if survives(after := _after(ref, int(action)), 1)]
    return min(safe, key=lambda edge_action: edge_action[0])[1] if safe else int(rng.integers(6))


def shoot_and_dodge(ref, rng: np.random.Generator) -> int:
    """Fire where an alien of the lowest row is above, else move towards the nearest such column, never into a
    bullet that would end the episode next step."""

    def after(action: int):
        env = copy.copy(ref)
        for name in ("f_bullet_map", "e_bullet_map", "alien_map"):
            setattr(env, name, np.copy(getattr(ref, name)))
        env.act(action)
        return env

    rows, columns = np.nonzero(ref.alien_map)
    lowest = columns[rows == rows.max()] if rows.size else np.array([ref.pos])
    nearest = lowest[np.argmin(np.abs(lowest - ref.pos))]
    towards = 1 if nearest < ref.pos else 3 if nearest > ref.pos else 5
    for action in (towards, 5, *rng.permutation([0, 1, 3]).tolist()):
        if not after(int(action)).terminal:
            return int(action)
    return 0


def last_alien_about_to_fall(ref) -> None:
    """Space Invaders with one alien left, a bullet one row below it: the wave is cleared on the first step, the
    next one comes in faster."""
    ref.alien_map[:] = 0
    ref.alien_map[5, ref.pos] = 1
    ref.f_bullet_map[6, ref.pos] = 1
    ref.alien_move_timer = 3


def hardest_asterix(ref) -> None:
    """Asterix as it is after its last ramp (step 918): a spawn every step, entities moving every other step."""
    ref.spawn_speed, ref.move_speed, ref.ramp_index = 1, 1, 9


@dataclass(frozen=True)
class Case:
    module: object
    state_class: type
    fields: Callable
    draws: Callable | None
    policy: Callable
    episodes: int
    max_steps: int
    start: Callable | None = None
    """Where the last episode starts, if not at the reset (a state the reference reaches late)."""


CASES = {
    "breakout": Case(ref_breakout, breakout.EnvState, breakout_fields, None, follow_the_ball, 4, 3000),
    "freeway": Case(ref_freeway, freeway.EnvState, freeway_fields, freeway_draws, climb, 2, 3000),
    "space_invaders": Case(ref_space_invaders, space_invaders.EnvState, space_invaders_fields, None,
                           shoot_and_dodge, 5, 3000, last_alien_about_to_fall),
    "asterix": Case(ref_asterix, asterix.EnvState, asterix_fields, asterix_draws, look_ahead, 4, 3000,
                    hardest_asterix),
}


@functools.cache
def port_step(game: str) -> Callable:
    """Our port's step of ``game`` (no time limit), compiled once for all its episodes: ``(key, state, action) ->
    (state, reward, done, observation)``."""
    port = GYMNAX_CLASSES[game](use_minimal_action_set=False)
    params = port.default_params.replace(max_steps_in_episode=10**9)
    return jax.jit(lambda key, state, action: (lambda out: (*out[1:4], port.get_obs(out[1])))(
        port.step_env(key, state, action, params)))


@functools.partial(jax.jit, static_argnums=1)
def step_keys(base: jax.Array, steps: int) -> jax.Array:
    """Step ``t``'s key, ``jax.random.fold_in(base, t)``, for every step at once."""
    return jax.vmap(lambda t: jax.random.fold_in(base, t))(jnp.arange(steps))


def play_both(game: str, case: Case, seed: int) -> dict[str, int]:
    """One episode in both, compared at every step; how long it ran, what it scored and what it reached."""
    step = port_step(game)
    ref = case.module.Env()
    ref.random = np.random.RandomState(seed)
    ref.reset()
    if case.start and seed == case.episodes - 1:
        case.start(ref)
    ours = as_state(case.state_class, case.fields(ref, 0))
    seen = {"rows_full": 0, "ramp": 0}
    rng = np.random.default_rng(seed)
    keys = np.asarray(step_keys(jax.random.PRNGKey(seed), case.max_steps))
    score = 0
    for t in range(case.max_steps):
        key = keys[t]
        action = case.policy(ref, rng)
        served = case.draws(key, ours) if case.draws else None
        if served is not None:
            ref.random = served
        if game == "asterix":
            seen["rows_full"] += ref.spawn_timer == 0 and all(entity is not None for entity in ref.entities)
        reward, terminal = ref.act(action)
        assert served is None or served.whole, (game, seed, t)
        ours, our_reward, our_terminal, observation = step(key, ours, action)
        found = jax.device_get(ours)
        if game == "freeway":
            our_terminal = our_terminal | (found.time >= ref_freeway.time_limit + 1)
        assert np.array_equal(np.asarray(observation).astype(bool), ref.state()), (game, seed, t)
        assert (float(our_reward), bool(our_terminal)) == (reward, terminal), (game, seed, t)
        expected = comparable(case.fields(ref, t + 1))
        found = comparable({name: np.asarray(getattr(found, name)) for name in expected} | {"terminal": terminal})
        differs = [name for name in expected if not np.array_equal(found[name], expected[name])]
        assert not differs, (game, seed, t, differs)
        score += reward
        seen["ramp"] = max(seen["ramp"], getattr(ref, "ramp_index", 0))
        if terminal:
            return {"steps": t + 1, "score": score, **seen}
    return {"steps": case.max_steps, "score": score, **seen}


@pytest.mark.slow("plays whole episodes beside the reference package")
@pytest.mark.parametrize("game", sorted(CASES))
def test_whole_episodes_equal_the_reference(game: str):
    case = CASES[game]
    played = [play_both(game, case, seed) for seed in range(case.episodes)]
    steps = sum(episode["steps"] for episode in played)
    # The policies reach the parts of each game that matter: a refilled wall, cars redrawn after a crossing,
    # Asterix's ramps and a spawn with every row taken.
    if game == "breakout":
        assert max(episode["score"] for episode in played) > 30
    if game == "freeway":
        assert all(episode["steps"] == ref_freeway.time_limit + 1 for episode in played)
        assert min(episode["score"] for episode in played) >= 5
    if game == "space_invaders":
        assert played[-1]["ramp"] >= 1
        assert min(episode["score"] for episode in played) >= 20
    if game == "asterix":
        assert max(episode["ramp"] for episode in played[:-1]) >= 7
        assert played[-1]["rows_full"] > 0
    assert steps >= 1000


# --- The random parts, by distribution ---

@pytest.mark.slow("plays whole episodes beside the reference package")
def test_asterix_spawns_take_a_free_row_uniformly_and_none_when_all_are_taken():
    keys = jax.random.split(jax.random.PRNGKey(0), 4000)
    taken = jnp.zeros((8, 5), jnp.int32).at[jnp.array([0, 2, 5]), 4].set(1)
    spawn = jax.jit(jax.vmap(asterix_spawn, in_axes=(0, None)))
    spawned = np.asarray(spawn(keys, taken))
    new_rows = np.argmax(spawned[:, :, 4] != np.asarray(taken)[None, :, 4], axis=1)
    counts = np.bincount(new_rows, minlength=8)
    assert counts[[0, 2, 5]].sum() == 0
    assert stats.chisquare(counts[[1, 3, 4, 6, 7]]).pvalue > 1e-3
    entity = spawned[np.arange(len(keys)), new_rows]
    assert stats.binomtest(int(entity[:, 2].sum()), len(keys), 0.5).pvalue > 1e-3  # left to right
    assert stats.binomtest(int(entity[:, 3].sum()), len(keys), 1 / 3).pvalue > 1e-3  # treasure
    assert np.array_equal(entity[:, 0], np.where(entity[:, 2] == 1, 0, 9))
    full = jnp.zeros((8, 5), jnp.int32).at[:, 4].set(1)
    assert np.array_equal(np.asarray(asterix_spawn(keys[0], full)), np.asarray(full))
    one_free = full.at[6, 4].set(0)
    assert np.all(np.asarray(spawn(keys[:200], one_free))[:, 6, 4] == 1)


@pytest.mark.slow("plays whole episodes beside the reference package")
def test_freeway_speeds_and_directions_are_drawn_as_the_reference_draws_them():
    draws = [freeway_draws(key, None) for key in jax.random.split(jax.random.PRNGKey(1), 500)]
    speeds = np.concatenate([served.values["randint"][0] for served in draws])
    directions = np.sign(np.concatenate([served.values["rand"][0] for served in draws]) - 0.5)
    reference = np.random.RandomState(0)
    reference_speeds = reference.randint(1, 6, speeds.size)
    table = [np.bincount(speeds, minlength=6)[1:], np.bincount(reference_speeds, minlength=6)[1:]]
    assert stats.chi2_contingency(table).pvalue > 1e-3
    assert stats.binomtest(int((directions > 0).sum()), directions.size, 0.5).pvalue > 1e-3


@pytest.mark.slow("plays whole episodes beside the reference package")
def test_sticky_actions_repeat_the_last_action_one_step_in_ten():
    env = minatar_env("MinAtar/Breakout-v0")
    state = env.reset(jax.random.PRNGKey(0))
    state = state._replace(last_action=jnp.asarray(3, jnp.int32))
    keys = jax.random.split(jax.random.PRNGKey(2), 5000)
    stepped = jax.jit(jax.vmap(env.step, in_axes=(None, None, 0)))(state, jnp.asarray(1), keys)[0]
    taken = np.asarray(stepped.last_action)
    assert set(np.unique(taken)) == {1, 3}
    assert stats.binomtest(int((taken == 3).sum()), taken.size, 0.1).pvalue > 1e-3
    plain = minatar_env("Breakout-MinAtar")
    assert set(np.unique(np.asarray(jax.jit(jax.vmap(plain.step, in_axes=(None, None, 0)))(
        state, jnp.asarray(2), keys)[0].last_action))) == {3}  # gymnax's protocol: "right" is its third action


# --- The protocols ---

def endings(env, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """Whether each of ``steps`` steps (action 0, step ``t`` from ``fold_in(PRNGKey(0), t)``) from the reset
    terminated and whether it truncated, the steps played one after another in one compiled program."""

    def step(state, t):
        state, _, term, trunc = env.step(state, jnp.asarray(0), jax.random.fold_in(jax.random.PRNGKey(0), t))
        return state, (jnp.asarray(term), jnp.asarray(trunc))

    _, ended = jax.jit(lambda: jax.lax.scan(step, env.reset(jax.random.PRNGKey(0)), jnp.arange(steps)))()
    return tuple(np.asarray(flags) for flags in ended)


@pytest.mark.slow("plays whole episodes beside the reference package")
def test_each_protocol_ends_episodes_as_it_says():
    params_limit = {name: minatar_env(name).max_steps for name in ("Breakout-MinAtar", "Freeway-MinAtar")}
    assert params_limit == {"Breakout-MinAtar": 1000, "Freeway-MinAtar": 2500}
    assert minatar_env("MinAtar/Breakout-v0").max_steps is None
    for name, steps, terminated in (("MinAtar/Freeway-v0", 2501, True), ("Freeway-MinAtar", 2500, False)):
        term, trunc = endings(minatar_env(name), steps)
        ended = np.flatnonzero(term | trunc)
        assert ended.tolist() == [steps - 1], (name, ended)
        assert (bool(term[-1]), bool(trunc[-1])) == (terminated, not terminated), name


def test_action_sets_are_the_reference_games_minimal_sets_or_all_six():
    for game in GAMES.values():
        reference = __import__(f"minatar.environments.{game.module_name}", fromlist=["Env"]).Env()
        assert tuple(reference.minimal_action_set()) == game.minimal_actions
        assert minatar_env(f"{game.title}-MinAtar").actions == game.minimal_actions
        assert minatar_env(f"MinAtar/{game.title}-v0").actions == tuple(range(6))
        assert len(game.channels) == reference.state_shape()[2]
        assert tuple(reference.channels) == game.channels
        assert GYMNAX_CLASSES[game.module_name]().default_params.max_steps_in_episode == game.time_limit
