"""Seaquest (``rlcompare.deep.minatar.seaquest``) against the reference ``minatar`` package (1.0.15).

Whole episodes: the reference's state is translated into gymnax's ``EnvState`` at its reset, both then play the same
actions, and after every step the observation, the reward, the ending and every state field must be equal (entity
buffers over their live rows, in list order). The reference draws its spawns from a NumPy generator; here, step by
step, it is replaced by :class:`Served`, which serves the draws ``seaquest_draws`` gave for the key our step gets, so
every random outcome is compared too; the draws themselves are tested by distribution at the end. Constructed
states show each case where gymnax's own ``MinSeaquest`` departs from the reference and ours does not, and random
crowded states mix them.
"""

from __future__ import annotations

import copy
from collections import Counter

import numpy as np
import pytest

jax = pytest.importorskip("jax")
pytest.importorskip("gymnax")
pytest.importorskip("minatar")

import jax.numpy as jnp  # noqa: E402
from gymnax.environments.minatar.seaquest import MinSeaquest  # noqa: E402
from minatar.environments import seaquest as ref_seaquest  # noqa: E402
from scipy import stats  # noqa: E402

from rlcompare.deep.minatar.seaquest import EnvState, Seaquest, seaquest_draws, spawn_row  # noqa: E402

NOOP, LEFT, UP, RIGHT, DOWN, FIRE = range(6)
ROWS = 100
LISTS = {"f_bullets": ("f_bullet_count", 3), "e_bullets": ("e_bullet_count", 3), "e_fish": ("e_fish_count", 4),
         "e_subs": ("e_subs_count", 5), "divers": ("divers_count", 4)}
"""The reference's entity lists: gymnax's buffer of rows ``[x, y, left_to_right, move_timer, shot_timer]`` (as
wide as the list's entries) and its count."""
SCALARS = ("oxygen", "sub_x", "sub_y", "diver_count", "e_spawn_speed", "e_spawn_timer", "d_spawn_timer",
           "move_speed", "ramp_index", "shot_timer")
FLAGS = ("sub_or", "surface", "terminal")


# --- The reference's state as gymnax's fields (NumPy) ---

def reference_fields(ref: ref_seaquest.Env, time: int) -> dict[str, np.ndarray]:
    fields = {name: np.int32(getattr(ref, name)) for name in SCALARS}
    fields |= {name: np.bool_(getattr(ref, name)) for name in FLAGS}
    for name, (count, width) in LISTS.items():
        rows = np.zeros((ROWS, width), np.int32)
        for row, entity in enumerate(getattr(ref, name)):
            rows[row] = [int(value) for value in entity]
        fields[name], fields[count] = rows, np.int32(len(getattr(ref, name)))
    return fields | {"time": np.int32(time)}


def as_state(fields: dict[str, np.ndarray]) -> EnvState:
    return EnvState(**{name: jnp.asarray(value) for name, value in fields.items()})


def live_fields(state: EnvState) -> dict[str, np.ndarray]:
    """Our state's fields in NumPy, each buffer's rows past its count as zeros."""
    found = jax.device_get(state)
    fields = {name: np.asarray(getattr(found, name)) for name in (*SCALARS, *FLAGS, "time")}
    for name, (count, _) in LISTS.items():
        fields[count] = np.asarray(getattr(found, count))
        fields[name] = np.asarray(getattr(found, name)) * (np.arange(ROWS) < fields[count])[:, None]
    return fields


def differing(expected: dict[str, np.ndarray], found: dict[str, np.ndarray]) -> list[str]:
    return [name for name in expected if not np.array_equal(expected[name], found[name])]


class Served:
    """The reference's ``self.random`` for one step: ``rand`` and ``randint`` return, in the reference's order,
    the draws ``seaquest_draws`` gave for the step's key, those of the spawns due (enemy: side, kind, row; diver:
    side, row)."""

    def __init__(self, draws: np.ndarray, enemy: bool, diver: bool) -> None:
        self.queue = [float(u) for u in (*(draws[:3] if enemy else ()), *(draws[3:] if diver else ()))]

    def rand(self) -> float:
        return self.queue.pop(0)

    def randint(self, low: int, high: int) -> int:
        return low + min(int(self.queue.pop(0) * (high - low)), high - low - 1)


def serve(ref: ref_seaquest.Env, draws: np.ndarray) -> Served:
    ref.random = Served(draws, ref.e_spawn_timer == 0, ref.d_spawn_timer == 0)
    return ref.random


OURS = Seaquest(use_minimal_action_set=False)
GYMNAX = MinSeaquest(use_minimal_action_set=False)
PARAMS = OURS.default_params


def jitted_step(env: MinSeaquest):
    return jax.jit(lambda key, state, action: (lambda out: (out[1], out[2], out[3], out[0]))(
        env.step_env(key, state, action, PARAMS)))


STEP = jitted_step(OURS)
GYMNAX_ALONE = jitted_step(GYMNAX)
GYMNAX_STEP = jax.jit(lambda key, state, action: (lambda out: (out[1], out[2], out[3], out[0]))(GYMNAX.step_env(
    key, OURS.spawn(seaquest_draws(key), state, PARAMS), action, PARAMS)))
"""gymnax's step after our spawn phase (which leaves it none to make): its other phases, with our draws."""


# --- A policy that keeps an episode going: it rescues divers, surfaces with them, and shoots ---

def _after(ref: ref_seaquest.Env, action: int) -> ref_seaquest.Env:
    """The reference after one action, spawns left out (they are served one step at a time)."""
    env = copy.copy(ref)
    for name in LISTS:
        setattr(env, name, [list(entity) for entity in getattr(ref, name)])
    env._spawn_enemy = env._spawn_diver = lambda: None
    env.act(action)
    return env


def _survives(env: ref_seaquest.Env, depth: int) -> bool:
    return not env.terminal and (depth == 0 or any(_survives(_after(env, action), depth - 1) for action in range(6)))


def _enemy_ahead(ref: ref_seaquest.Env) -> bool:
    return any(enemy[1] == ref.sub_y and (enemy[0] > ref.sub_x if ref.sub_or else enemy[0] < ref.sub_x)
               for enemy in ref.e_fish + ref.e_subs)


def _toward(ref: ref_seaquest.Env, x: int, y: int) -> int:
    if y != ref.sub_y:
        return DOWN if y > ref.sub_y else UP
    return NOOP if x == ref.sub_x else RIGHT if x > ref.sub_x else LEFT


def rescue(ref: ref_seaquest.Env, rng: np.random.Generator, ending: bool) -> int:
    """Surface when six divers are aboard or the oxygen runs low, else shoot what is ahead, chase the nearest
    diver or wander; that action if it survives two steps (spawns left out), else another, away from the edge
    columns where enemies appear where one can. Once ``ending``, it surfaces until no diver is aboard (picking one
    up where the count is below 0) and then surfaces again, which ends the episode."""
    at_rest = ref.sub_y == 0 and ref.surface
    nearest = min(ref.divers, key=lambda d: abs(d[0] - ref.sub_x) + abs(d[1] - ref.sub_y), default=None)
    if ending and ref.diver_count == 0 and ref.sub_y == 1:
        return UP
    if (ending and ref.diver_count > 0) or (ref.diver_count != 0 and (ref.oxygen < 40 or ref.diver_count >= 6)):
        goal = DOWN if at_rest else UP
    elif ref.shot_timer == 0 and _enemy_ahead(ref) and rng.random() < 0.8:
        goal = FIRE
    elif nearest is not None and ref.diver_count < 6 and (ending or rng.random() < 0.8):
        goal = _toward(ref, nearest[0], nearest[1])
    elif ending and ref.diver_count == 0:
        goal = UP
    else:
        goal = int(rng.choice([NOOP, LEFT, RIGHT, DOWN, FIRE] + [UP] * (ref.sub_y > 1)))
    if at_rest and goal == NOOP:
        goal = DOWN
    safe = [(after.sub_x in (0, 9) and after.sub_y > 0, int(action)) for action in (goal, *rng.permutation(6))
            if _survives(after := _after(ref, int(action)), 1)]
    return min(safe, key=lambda edge_action: edge_action[0])[1] if safe else goal


def hardest(ref: ref_seaquest.Env) -> None:
    """Seaquest as it is after its last ramp (19 surfacings): an enemy every other step, moving every third."""
    ref.e_spawn_speed, ref.e_spawn_timer, ref.move_speed, ref.ramp_index = 1, 1, 2, 19


def play_both(seed: int, steps: int, end_after: int, start=None) -> Counter:
    """One episode in both from the reference's reset (or ``start`` applied to it), compared at every step; what
    it reached, and on how many steps gymnax's ``MinSeaquest`` (with our spawns) would have stepped otherwise."""
    ref = ref_seaquest.Env()
    ref.random = np.random.RandomState(seed)
    ref.reset()
    if start is not None:
        start(ref)
    state = as_state(reference_fields(ref, 0))
    keys = jax.random.split(jax.random.PRNGKey(seed), steps)
    draws = np.stack(jax.device_get(jax.vmap(seaquest_draws)(keys)), axis=1)
    keys = np.asarray(keys)
    rng = np.random.default_rng(seed)
    seen = Counter()
    for t in range(steps):
        action = rescue(ref, rng, ending=t >= end_after)
        aboard, surfaced, enemies = ref.diver_count, ref.surface, ref.e_subs + ref.e_fish
        spawning = ref.e_spawn_timer == 0
        left_to_right, row = draws[t, 0] < 1 / 2, 1 + min(int(draws[t, 2] * 8), 7)  # the enemy's, if due
        gymnax_state, gymnax_reward, _, gymnax_observation = GYMNAX_STEP(keys[t], state, action)
        served = serve(ref, draws[t])
        reward, terminal = ref.act(action)
        assert not served.queue, (seed, t)
        seen["gymnax_differs"] += bool(float(gymnax_reward) != reward or differing(
            reference_fields(ref, t + 1), live_fields(gymnax_state)) or not np.array_equal(
            np.asarray(gymnax_observation).astype(bool), ref.state()))
        state, our_reward, our_terminal, observation = STEP(keys[t], state, action)
        assert np.array_equal(np.asarray(observation).astype(bool), ref.state()), (seed, t)
        assert (float(our_reward), bool(our_terminal)) == (reward, terminal), (seed, t)
        assert not (differs := differing(reference_fields(ref, t + 1), live_fields(state))), (seed, t, differs)
        surfacing = ref.sub_y == 0 and not surfaced
        seen["steps"] += 1
        seen["reward"] += reward
        seen["surfaced_with_divers"] += surfacing and aboard != 0
        seen["full_rescues"] += surfacing and aboard == 6
        seen["ended_surfacing_empty"] += surfacing and aboard == 0
        seen["rescued"] += max(0, ref.diver_count - aboard) if not surfacing else 0
        seen["spawns_blocked"] += spawning and any(enemy[1] == row and enemy[2] != left_to_right for enemy in enemies)
        seen["subs_seen"] += bool(ref.e_subs)
        seen["enemy_bullets_seen"] += bool(ref.e_bullets)
        seen["ramp_index"] = max(seen["ramp_index"], ref.ramp_index)
        if terminal:
            break
    return seen


EPISODES = [(seed, 1000, None) for seed in range(3)] + [(seed, 700, hardest) for seed in range(3, 6)]
"""(seed, steps before the policy ends the episode, start): three from the reset, three after the last ramp."""


@pytest.mark.slow("plays whole episodes beside the reference package")
def test_whole_episodes_equal_the_reference():
    played = [play_both(seed, 3000, end_after, start) for seed, end_after, start in EPISODES]
    total = sum(played, Counter())
    assert total["steps"] >= 3000, played
    assert all(episode["steps"] >= 300 for episode in played), played
    # The episodes reach what matters: divers rescued and brought up (six at once too), the ramp to its end, enemy
    # subs and their bullets, spawns refused for an enemy going the other way, and episodes ended by surfacing
    # with no diver aboard, where gymnax's own step differs (SQ-6; it also lists enemy bullets in another order).
    assert total["surfaced_with_divers"] >= 20, played
    assert total["full_rescues"] >= 5, played
    assert max(episode["ramp_index"] for episode in played[:3]) >= 8, played
    assert min(episode["ramp_index"] for episode in played[3:]) == 19, played
    assert total["subs_seen"] > 0, played
    assert total["enemy_bullets_seen"] > 0, played
    assert total["spawns_blocked"] > 0, played
    assert total["ended_surfacing_empty"] >= 3, played
    assert total["gymnax_differs"] >= total["ended_surfacing_empty"], played


# --- Constructed states: where gymnax's MinSeaquest departs from the reference, and ours does not ---

def quiet(**fields) -> ref_seaquest.Env:
    """A reference state with no spawn due this step, the player at (5, 0) unless given."""
    ref = ref_seaquest.Env()
    ref.e_spawn_timer, ref.d_spawn_timer = 15, 25
    for name, value in fields.items():
        setattr(ref, name, value)
    return ref


CASES = {
    # A sub moving onto a friendly bullet with its shot timer at 0 is destroyed and still fires.
    "SQ-1": (lambda: quiet(e_subs=[[7, 3, False, 0, 0]], f_bullets=[[5, 3, True]]), NOOP),
    # Two bullets reach a cell with two fish: newest first, each takes the first fish left (gymnax: one fish).
    "SQ-3": (lambda: quiet(e_fish=[[5, 3, True, 2], [5, 3, True, 0]], f_bullets=[[4, 3, True], [6, 3, False]]),
             NOOP),
    # Five aboard: the player moves onto a diver as another moves onto the player; the newer one is picked up.
    "SQ-4": (lambda: quiet(sub_x=4, sub_y=3, diver_count=5, surface=False,
                           divers=[[5, 3, True, 3], [6, 3, False, 0]]), RIGHT),
    # Surfacing with no diver aboard ends the episode and changes nothing else (the oxygen gauge stays).
    "SQ-6": (lambda: quiet(sub_y=1, oxygen=123, surface=False), UP),
    # A fish moves into a cell with two friendly bullets: it takes the first in list order.
    "SQ-2": (lambda: quiet(e_fish=[[6, 3, False, 0]], f_bullets=[[4, 3, True], [6, 3, False]]), NOOP),
    # Two subs move into one bullet's cell: the newer takes it.
    "SQ-2b": (lambda: quiet(e_subs=[[5, 4, False, 0, 3], [5, 4, False, 0, 7]], f_bullets=[[3, 4, True]]), NOOP),
    # A fish moves onto the player and onto a friendly bullet: the episode ends, no reward, the fish stays.
    "SQ-5": (lambda: quiet(sub_y=3, surface=False, e_fish=[[6, 3, False, 0]], f_bullets=[[6, 3, False]]), NOOP),
    # Two subs fire in one step: the newer sub's bullet is listed first.
    "SQ-8": (lambda: quiet(e_subs=[[2, 3, True, 3, 0], [7, 6, False, 3, 0]]), NOOP),
    # A terminal state is left as it is.
    "terminal": (lambda: quiet(terminal=True, sub_y=2, surface=False, e_fish=[[4, 3, True, 0]]), LEFT),
}


def outcome(step, state: EnvState, action: int) -> dict[str, np.ndarray]:
    stepped, reward, terminal, observation = step(jax.random.PRNGKey(0), state, action)
    return live_fields(stepped) | {"reward": np.float32(reward), "done": np.bool_(terminal),
                                   "observation": np.asarray(observation).astype(bool)}


@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.slow("steps the reference game from constructed states")
def test_constructed_states_step_as_the_reference_where_gymnax_does_not(case: str):
    build, action = CASES[case]
    ref = build()
    state = as_state(reference_fields(ref, 0))
    served = serve(ref, np.full(5, np.nan))
    reward, terminal = ref.act(action)
    assert not served.queue
    expected = reference_fields(ref, 0 if case == "terminal" else 1) | {
        "reward": np.float32(reward), "done": np.bool_(terminal), "observation": ref.state()}
    assert differing(expected, outcome(STEP, state, action)) == []
    assert differing(expected, outcome(GYMNAX_ALONE, state, action)) != []


class ByIdentity(list):
    """A reference entity list whose ``remove`` takes out the very entry given, not the first equal to it."""

    def remove(self, entity: list) -> None:
        del self[next(row for row, entry in enumerate(self) if entry is entity)]


def crowded(rng: np.random.RandomState) -> ref_seaquest.Env:
    """A random state, most of it unreachable: up to five of each entity, most near the player, so that bullets,
    enemies and divers meet in one cell (timers at 0 more often than not)."""
    ref = ref_seaquest.Env()
    ref.sub_x, ref.sub_y, ref.sub_or = rng.randint(10), rng.randint(9), bool(rng.rand() < 0.5)
    ref.sub_or = ref.sub_x == 9 or (ref.sub_x != 0 and ref.sub_or)
    ref.move_speed, ref.e_spawn_speed, ref.ramp_index = rng.randint(2, 6), rng.randint(1, 21), rng.randint(20)
    ref.e_spawn_timer, ref.d_spawn_timer = rng.choice([0, rng.randint(3)]), rng.choice([0, rng.randint(3)])
    ref.oxygen, ref.diver_count, ref.surface = rng.randint(-1, 201), rng.randint(-2, 7), bool(rng.rand() < 0.5)
    ref.shot_timer = rng.randint(6)

    def cell() -> list:
        row = rng.choice([max(ref.sub_y, 1), rng.randint(1, 9)])
        return [int(np.clip(ref.sub_x + rng.randint(-2, 3), 0, 9)), int(row), bool(rng.rand() < 0.5)]

    def timer(most: int) -> int:
        return int(rng.choice([0, rng.randint(most + 1)]))

    ref.e_fish = [[*cell(), timer(ref.move_speed)] for _ in range(rng.randint(6))]
    ref.e_subs = [[*cell(), timer(ref.move_speed), timer(10)] for _ in range(rng.randint(6))]
    ref.divers = [[*cell(), timer(5)] for _ in range(rng.randint(6))]
    ref.f_bullets = [cell() for _ in range(rng.randint(6))]
    ref.e_bullets = [cell() for _ in range(rng.randint(6))]
    return ref


@pytest.mark.slow("plays whole episodes beside the reference package")
def test_crowded_states_step_as_the_reference_removing_by_identity():
    """Random crowded states (SQ-1 to SQ-6 and their mixtures): one step of ours equals the reference's, where the
    reference's lists remove by identity, and gymnax's MinSeaquest (with our spawns) scores or ends otherwise on
    some. The reference's own ``list.remove`` takes the first entry equal in value, which among equal entities
    reorders the list; in play that needs an unmoved friendly bullet sharing a cell with an enemy, which no step
    leaves (the whole episodes above)."""
    rng = np.random.RandomState(0)
    keys = jax.random.split(jax.random.PRNGKey(11), 1500)
    draws = np.stack(jax.device_get(jax.vmap(seaquest_draws)(keys)), axis=1)
    seen = Counter()
    for n, key in enumerate(np.asarray(keys)):
        ref = crowded(rng)
        state = as_state(reference_fields(ref, 0))
        for name in LISTS:
            setattr(ref, name, ByIdentity(getattr(ref, name)))
        action = int(rng.randint(6))
        served = serve(ref, draws[n])
        reward, terminal = ref.act(action)
        assert not served.queue
        expected = reference_fields(ref, 1) | {"reward": np.float32(reward), "done": np.bool_(terminal),
                                                "observation": ref.state()}
        stepped, our_reward, our_terminal, observation = STEP(key, state, action)
        assert differing(expected, live_fields(stepped) | {
            "reward": np.float32(our_reward), "done": np.bool_(our_terminal),
            "observation": np.asarray(observation).astype(bool)}) == [], n
        _, gymnax_reward, gymnax_terminal, _ = GYMNAX_STEP(key, state, action)
        seen["gymnax_reward_or_end_differs"] += (float(gymnax_reward), bool(gymnax_terminal)) != (reward, terminal)
        seen["reward"] += reward > 1
        seen["terminal"] += terminal
    assert seen["reward"] > 50, seen
    assert 100 < seen["terminal"] < 1400, seen
    assert seen["gymnax_reward_or_end_differs"] > 20, seen


# --- The random parts, by distribution ---

@pytest.mark.slow("plays whole episodes beside the reference package")
def test_spawn_draws_have_the_reference_probabilities():
    keys = jax.random.split(jax.random.PRNGKey(7), 8000)
    draws = jax.device_get(jax.vmap(seaquest_draws)(keys))
    ours = {"enemy side": draws.enemy_left_to_right < 1 / 2, "sub": draws.enemy_is_sub < 1 / 3,
            "enemy row": np.asarray(spawn_row(draws.enemy_row)), "diver side": draws.diver_left_to_right < 1 / 2,
            "diver row": np.asarray(spawn_row(draws.diver_row))}
    for name, probability in (("enemy side", 1 / 2), ("sub", 1 / 3), ("diver side", 1 / 2)):
        assert stats.binomtest(int(ours[name].sum()), len(keys), probability).pvalue > 1e-3, name
    for name in ("enemy row", "diver row"):
        assert set(np.unique(ours[name])) == set(range(1, 9)), name
        assert stats.chisquare(np.bincount(ours[name], minlength=9)[1:]).pvalue > 1e-3, name
    # The reference's spawns from its own generator, against its spawns from our draws served to it.
    reference = ref_seaquest.Env()
    generator, served = np.random.RandomState(0), np.stack(draws, axis=1)
    spawned = {"theirs": [], "ours": []}
    for n in range(4000):
        for source in spawned:
            reference.e_subs, reference.e_fish, reference.divers = [], [], []
            reference.random = generator if source == "theirs" else Served(served[n], enemy=True, diver=True)
            reference._spawn_enemy()
            reference._spawn_diver()
            enemy = (reference.e_subs + reference.e_fish)[0]
            spawned[source].append((bool(reference.e_subs), enemy[0], enemy[1], reference.divers[0][0],
                                    reference.divers[0][1]))
    theirs, ours_spawned = np.array(spawned["theirs"], int), np.array(spawned["ours"], int)
    for column, name in enumerate(("sub", "enemy x", "enemy row", "diver x", "diver row")):
        values = np.unique(np.concatenate([theirs[:, column], ours_spawned[:, column]]))
        table = [[np.sum(found[:, column] == value) for value in values] for found in (theirs, ours_spawned)]
        assert stats.chi2_contingency(table).pvalue > 1e-3, name


@pytest.mark.slow("plays whole episodes beside the reference package")
def test_spawns_under_vmap_follow_the_draws():
    """Our step, vmapped over keys from a state with both spawns due: each spawn is the one its draws name (its
    timers counted down once in the step)."""
    _, state = OURS.reset_env(jax.random.PRNGKey(0), PARAMS)
    state = state.replace(e_spawn_timer=jnp.int32(0), d_spawn_timer=jnp.int32(0), sub_y=jnp.int32(4))
    keys = jax.random.split(jax.random.PRNGKey(3), 2000)
    stepped = jax.device_get(jax.jit(jax.vmap(OURS.step_env, in_axes=(0, None, None, None)))(
        keys, state, 0, PARAMS)[1])
    draws = jax.device_get(jax.vmap(seaquest_draws)(keys))
    is_sub = draws.enemy_is_sub < 1 / 3
    assert np.array_equal(stepped.e_subs_count, is_sub)
    assert np.array_equal(stepped.e_fish_count, ~is_sub)
    enemy = np.where(is_sub[:, None], stepped.e_subs[:, 0, :4], stepped.e_fish[:, 0, :4])
    left_to_right = draws.enemy_left_to_right < 1 / 2
    assert np.array_equal(enemy, np.stack([np.where(left_to_right, 0, 9), spawn_row(draws.enemy_row),
                                           left_to_right, np.full(len(keys), 4)], 1))
    assert np.all(stepped.e_subs[is_sub, 0, 4] == 9)
    diver_left_to_right = draws.diver_left_to_right < 1 / 2
    assert np.array_equal(stepped.divers[:, 0], np.stack([np.where(diver_left_to_right, 0, 9),
                                                          spawn_row(draws.diver_row), diver_left_to_right,
                                                          np.full(len(keys), 4)], 1))
