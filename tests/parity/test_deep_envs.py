"""The deep engine's JAX environments against Gymnasium's, transition for transition: physics, float32
observation, reward and termination equal (``==``), compiled the ways a training program compiles them."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from functools import cache, partial

import numpy as np
import pytest

pytest.importorskip("jax")

import gymnasium as gym
import jax
import jax.numpy as jnp

from rlcompare.deep.envs import DeepEnv, EnvState, jax_env, jax_env_names, step_autoreset
from rlcompare.envs import acrobot, cartpole, minatar, mountain_car
from rlcompare.envs.atari import games as atari
from rlcompare.envs.chess import games as chess_games

NAMES = [name for name in jax_env_names()
         if name not in minatar.NAMES and name not in atari.NAMES and name not in chess_games.GAMES]
"""Gymnasium's classic control, ported (MinAtar's games are checked against their reference in
tests/parity/test_minatar_games.py, Atari's against ALE's own loop in tests/parity/test_atari.py)."""
TRANSITIONS = 3000
"""Per environment, from Gymnasium's own episodes."""
ENVS_SIDE_BY_SIDE, SCANNED_STEPS = 4, 600
"""The training-shaped program: environments under ``vmap``, steps under ``lax.scan``."""


def _policy(name: str, state: np.ndarray, generator: np.random.Generator) -> int:
    """Episodes that end both ways: a controller that reaches the goal (MountainCar, Acrobot) or balances the
    pole until the cart drifts off or the limit comes (CartPole), with 20% random actions."""
    if generator.random() < 0.2:
        return int(generator.integers(jax_env(name).n_actions))
    if name == "CartPole-v1":
        return int(state[2] + 0.5 * state[3] > 0.0)
    velocity = state[1] if name == "MountainCar-v0" else state[3]
    return 2 if velocity >= 0 else 0


def _jax_policy(name: str, observation: jax.Array, explore: jax.Array, random_action: jax.Array) -> jax.Array:
    """:func:`_policy` on the float32 observation, inside the compiled program."""
    if name == "CartPole-v1":
        greedy = (observation[2] + 0.5 * observation[3] > 0.0).astype(random_action.dtype)
    else:
        velocity = observation[1] if name == "MountainCar-v0" else observation[5]
        greedy = jnp.where(velocity >= 0, 2, 0).astype(random_action.dtype)
    return jnp.where(explore, random_action, greedy)


def _gymnasium_observation(env: gym.Env) -> np.ndarray:
    return env._get_ob() if env.spec.id == "Acrobot-v1" else np.array(env.state, dtype=np.float32)


def _transition(env: DeepEnv, state: EnvState, action: jax.Array):
    state, reward, terminated, _ = env.step(state, action)
    return state.physics, env.observe(state), reward, terminated


@pytest.fixture(scope="module")
def same_trigonometry() -> None:
    """Gymnasium's sin and cos are NumPy's (C library's in MountainCar), the port's XLA's; both call the C
    library on x86-64 unless NumPy was built with its AVX-512 kernels."""
    x = np.random.default_rng(0).uniform(-30, 30, 20_000)
    cos, sin = jax.jit(lambda x: (jnp.cos(x), jnp.sin(x)))(x)
    if not (np.array_equal(np.cos(x), cos) and np.array_equal(np.sin(x), sin)):
        pytest.skip("this NumPy's or XLA's sin and cos differ from the C library's; Gymnasium cannot be matched")


@cache
def _gymnasium_transitions(name: str) -> dict[str, np.ndarray]:
    """Gymnasium's own episodes (seeded resets, the registered limit): each state, the action taken, and what
    followed."""
    env, generator = gym.make(name).unwrapped, np.random.default_rng(3)
    limit = jax_env(name).max_steps
    env.reset(seed=11)
    rows: dict[str, list] = {key: [] for key in ("state", "action", "next", "observation", "reward", "terminated")}
    length = 0
    for _ in range(TRANSITIONS):
        state = np.array(env.state, dtype=np.float64)
        action = _policy(name, state, generator)
        observation, reward, terminated, _, _ = env.step(action)
        length += 1
        for key, value in zip(rows, (state, action, np.array(env.state, dtype=np.float64), observation, reward,
                                     terminated), strict=True):
            rows[key].append(value)
        if terminated or length == limit:
            env.reset()
            length = 0
    return {key: np.array(value) for key, value in rows.items()}


@pytest.mark.slow("steps the JAX ports beside Gymnasium")
@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("compiled", ["jit-vmap", "jit-map"])
def test_transitions_equal_gymnasium(name, compiled, same_trigonometry) -> None:
    """From each of Gymnasium's states, the jitted step (batched by ``vmap``, or unbatched in a loop) gives
    Gymnasium's next state, float32 observation, reward and termination, bit for bit."""
    env, ref = jax_env(name), _gymnasium_transitions(name)
    assert ref["terminated"].sum() >= 5, "the policy should reach the goal (or fail) several times"
    states = EnvState(jnp.asarray(ref["state"]), jnp.zeros(len(ref["state"]), jnp.int32))
    transition = partial(_transition, env)
    if compiled == "jit-vmap":
        run = jax.jit(jax.vmap(transition))
    else:
        run = jax.jit(lambda states, actions: jax.lax.map(lambda x: transition(*x), (states, actions)))
    physics, observation, reward, terminated = map(np.asarray, run(states, jnp.asarray(ref["action"])))
    assert physics.dtype == np.float64
    assert observation.dtype == np.float32
    np.testing.assert_array_equal(physics, ref["next"], strict=True)
    np.testing.assert_array_equal(observation, ref["observation"], strict=True)
    np.testing.assert_array_equal(reward, ref["reward"])
    np.testing.assert_array_equal(terminated, ref["terminated"])


@cache
def _scanned_rollout(name: str) -> Callable:
    """A program shaped like training: environments side by side under ``vmap``, stepped with
    :func:`step_autoreset` under ``lax.scan``, acting on the float32 observation. The random draws other than
    the resets' come in as arrays, which keeps the program quick to compile."""
    env = jax_env(name)

    def one_step(state: EnvState, draws: tuple[jax.Array, jax.Array, jax.Array]):
        explore, random_action, reset_key = draws
        action = _jax_policy(name, env.observe(state), explore, random_action)
        step = step_autoreset(env, state, action, jax.random.wrap_key_data(reset_key))
        return step.state, (action, step)

    def rollout(start: jax.Array, explore: jax.Array, random_actions: jax.Array, reset_keys: jax.Array):
        state = EnvState(start, jnp.zeros(start.shape[0], jnp.int32))
        return jax.lax.scan(jax.vmap(one_step), state, (explore, random_actions, reset_keys))[1]

    return jax.jit(rollout)


@pytest.mark.slow("steps the JAX ports beside Gymnasium")
@pytest.mark.parametrize("name", NAMES)
def test_scanned_autoreset_rollout_equals_gymnasium(name, same_trigonometry) -> None:
    """Gymnasium, started from its own reset, given the same actions, and each new episode's start state copied
    from the port, follows the scanned rollout step for step: observation before and after each reset,
    physics, reward, termination, and truncation at the registered limit."""
    env, generator = jax_env(name), np.random.default_rng(5)
    theirs = [gym.make(name).unwrapped for _ in range(ENVS_SIDE_BY_SIDE)]
    for b, one in enumerate(theirs):
        one.reset(seed=b)
    start = np.array([np.asarray(one.state, dtype=np.float64) for one in theirs])
    shape = (SCANNED_STEPS, ENVS_SIDE_BY_SIDE)
    actions, steps = jax.tree.map(np.asarray, _scanned_rollout(name)(
        start, generator.random(shape) < 0.2, generator.integers(env.n_actions, size=shape, dtype=np.int32),
        generator.integers(2**32, size=(*shape, 2), dtype=np.uint32)))
    endings = {"terminated": 0, "truncated": 0}
    for b, one in enumerate(theirs):
        length = 0
        for t in range(SCANNED_STEPS):
            observation, reward, terminated, _, _ = one.step(int(actions[t, b]))
            length += 1
            truncated = length == env.max_steps and not terminated
            assert np.array_equal(steps.last_observation[t, b], observation), (t, b)
            assert steps.reward[t, b] == reward, (t, b)
            assert steps.terminated[t, b] == terminated, (t, b)
            assert steps.truncated[t, b] == truncated, (t, b)
            if terminated or truncated:
                endings["terminated" if terminated else "truncated"] += 1
                one.reset()
                one.state = steps.state.physics[t, b].copy()
                length = 0
            else:
                assert np.array_equal(steps.state.physics[t, b], np.asarray(one.state, dtype=np.float64)), (t, b)
            assert steps.state.t[t, b] == length
            assert np.array_equal(steps.observation[t, b], _gymnasium_observation(one)), (t, b)
    assert endings["terminated"] >= 2


@pytest.mark.slow("compiles environments' steps")
def test_step_autoreset_resets_exactly_where_an_episode_ended() -> None:
    """Terminated, truncated, both on one step (terminated only) or neither: a fresh start exactly where the
    episode ended, the steps counted from 0 again, and the observation the action led to kept."""
    env = dataclasses.replace(jax_env("CartPole-v1"), max_steps=5)
    edge = [cartpole.X_THRESHOLD - 1e-3, 1.0, 0.0, 0.0]
    middle = [0.0, 0.0, 0.01, 0.0]
    state = EnvState(jnp.asarray([middle, edge, middle, edge]), jnp.asarray([0, 0, 4, 4], jnp.int32))
    actions = jnp.ones(4, jnp.int32)
    keys = np.random.default_rng(0).integers(2**32, size=(4, 2), dtype=np.uint32)

    def run(state: EnvState, actions: jax.Array, keys: jax.Array):
        keys = jax.random.wrap_key_data(keys)
        return (jax.vmap(partial(step_autoreset, env))(state, actions, keys), jax.vmap(env.step)(state, actions),
                jax.vmap(env.reset)(keys))

    step, (stepped, _, _, _), fresh = jax.jit(run)(state, actions, keys)
    np.testing.assert_array_equal(step.terminated, [False, True, False, True])
    np.testing.assert_array_equal(step.truncated, [False, False, True, False])
    done = np.array([False, True, True, True])
    np.testing.assert_array_equal(step.state.physics[~done], stepped.physics[~done])
    np.testing.assert_array_equal(step.state.physics[done], fresh.physics[done])
    np.testing.assert_array_equal(step.state.t, [1, 0, 0, 0])
    np.testing.assert_array_equal(step.observation, step.state.physics.astype(np.float32))
    np.testing.assert_array_equal(step.last_observation, stepped.physics.astype(np.float32))
    assert step.observation.dtype == step.last_observation.dtype == jnp.float32


GOALS = {"MountainCar-v0": [mountain_car.GOAL_POSITION, 0.07], "CartPole-v1": [2.5, 1.0, 0.0, 0.0],
         "Acrobot-v1": [np.pi, 0.0, 0.0, 0.0]}
"""A state each environment's next step terminates from (Acrobot's: upside down, the free end above the bar)."""
RESTS = {"MountainCar-v0": [-0.5, 0.0], "CartPole-v1": [0.0, 0.0, 0.01, 0.0], "Acrobot-v1": [0.0, 0.0, 0.0, 0.0]}
"""A state far from any ending."""
LAST_REWARDS = {"MountainCar-v0": -1.0, "CartPole-v1": 1.0, "Acrobot-v1": 0.0}


@pytest.mark.parametrize("name", NAMES)
def test_truncated_at_the_limit_unless_terminated(name) -> None:
    """Truncated on the step that reaches the registered limit, not before, and not when that step terminates."""
    env = jax_env(name)
    physics = np.array([GOALS[name]] + [RESTS[name]] * 3)
    limit = env.max_steps
    state = EnvState(jnp.asarray(physics), jnp.asarray([limit - 1, 0, limit - 2, limit - 1], jnp.int32))
    state, reward, terminated, truncated = jax.jit(jax.vmap(env.step))(state, jnp.ones(4, jnp.int32))
    np.testing.assert_array_equal(state.t, [limit, 1, limit - 1, limit])
    np.testing.assert_array_equal(terminated, [True, False, False, False])
    np.testing.assert_array_equal(truncated, [False, False, False, True])
    assert float(reward[0]) == LAST_REWARDS[name]


BOUNDS = {"MountainCar-v0": ([mountain_car.RESET_LOW, 0.0], [mountain_car.RESET_HIGH, 0.0]),
          "CartPole-v1": ([cartpole.RESET_LOW] * 4, [cartpole.RESET_HIGH] * 4),
          "Acrobot-v1": ([np.float32(acrobot.RESET_LOW)] * 4, [np.float32(acrobot.RESET_HIGH)] * 4)}
"""Gymnasium's start-state bounds (Acrobot's rounded to float32, as its draws are)."""


@pytest.mark.parametrize("name", NAMES)
def test_start_states_fill_gymnasiums_bounds(name) -> None:
    """Start states lie within Gymnasium's bounds and come within 1% of each end; Acrobot's are float32 values."""
    keys = np.random.default_rng(2).integers(2**32, size=(20_000, 2), dtype=np.uint32)
    start = jax.vmap(jax_env(name).start)
    physics = np.asarray(jax.jit(lambda keys: start(jax.random.wrap_key_data(keys)))(keys))
    low, high = (np.asarray(bound, dtype=np.float64) for bound in BOUNDS[name])
    assert physics.dtype == np.float64
    assert physics.shape == (20_000, len(low))
    assert (physics >= low).all()
    assert (physics <= high).all()
    drawn = high > low
    margin = 0.01 * (high - low)[drawn]
    assert (physics.min(axis=0)[drawn] < low[drawn] + margin).all()
    assert (physics.max(axis=0)[drawn] > high[drawn] - margin).all()
    if name == "Acrobot-v1":
        np.testing.assert_array_equal(physics, physics.astype(np.float32).astype(np.float64))
