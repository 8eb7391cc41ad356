"""The compiled Mountain Car against Gymnasium's ``MountainCar-v0``, transition by transition."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium_play import resets

from rlcompare.envs import mountain_car
from rlcompare.rng import stream_state

MAX_EPISODE_STEPS = 1000
TOTAL_STEPS = 100_000
ENV = mountain_car.MountainCar()
NO_DRAWS = np.zeros(4, dtype=np.uint64)
"""The stream ``step`` is given; Mountain Car is deterministic and never draws from it."""


@pytest.fixture
def env():
    """Gymnasium's Mountain Car with the paper's episode limit."""
    environment = gym.make(mountain_car.ENV_ID, max_episode_steps=MAX_EPISODE_STEPS)
    yield environment
    environment.close()


def _gym_state(env) -> tuple[float, float]:
    position, velocity = env.unwrapped.state
    return float(position), float(velocity)


def _policy(kind: str, velocity: float, generator: np.random.Generator) -> int:
    """Random actions, bang-bang (push along the velocity: reaches the goal, and the left wall on the way),
    or bang-bang with 30% random actions."""
    if kind == "random" or (kind == "noisy" and generator.random() < 0.3):
        return int(generator.integers(3))
    return 2 if velocity >= 0 else 0


@pytest.mark.slow("compiles or trains for a second or more")
def test_transitions_equal_gymnasium(env):
    """At least 100,000 steps: every state, reward, termination and truncation equal (``==``)."""
    generator = np.random.default_rng(2024)
    kinds = ("random", "bang_bang", "noisy")
    total = wall_hits = terminations = truncations = 0
    for episodes, (observation, rng_state) in enumerate(resets(env, generator, every=4)):
        if total >= TOTAL_STEPS:
            break
        state = mountain_car.reset(ENV, rng_state)
        assert state == _gym_state(env)
        _assert_observation(observation, state)
        kind = kinds[episodes % len(kinds)]
        for steps in range(1, MAX_EPISODE_STEPS + 1):
            action = _policy(kind, state[1], generator)
            observation, reward, terminated, truncated, _ = env.step(action)
            state, our_reward, done = mountain_car.step(ENV, state, action, NO_DRAWS)
            position, velocity = state
            total += 1
            assert state == _gym_state(env), (episodes, steps)
            _assert_observation(observation, state)
            assert our_reward == reward == mountain_car.REWARD == -1.0
            assert done == terminated
            assert truncated == (not done and steps == MAX_EPISODE_STEPS)
            if position == mountain_car.MIN_POSITION:
                assert velocity == 0.0  # the inelastic wall
                wall_hits += 1
            if terminated or truncated:
                terminations += terminated
                truncations += truncated
                break
    # The coverage is real: the goal, the left wall and the time limit were all reached many times.
    assert total >= TOTAL_STEPS
    assert terminations > 20
    assert wall_hits > 20
    assert truncations > 20
    np.testing.assert_array_equal(NO_DRAWS, 0)


def _assert_observation(observation: np.ndarray, state: tuple[float, float]) -> None:
    """``observe`` gives Gymnasium's observation (``==``): the state rounded to float32."""
    ours = mountain_car.observe(ENV, state)
    np.testing.assert_array_equal(observation, np.array(ours, dtype=np.float32))
    assert ours == tuple(float(np.float32(x)) for x in state)


def test_reset_stream_equals_seeded_then_plain_resets(env):
    """``reset(stream_state(seed))`` repeated equals ``env.reset(seed=seed)`` then plain ``env.reset()``."""
    for seed in (0, 1, 42, 2**31 - 1, 987654321):
        rng_state = stream_state(seed)
        starts = []
        for k in range(6):
            observation, _ = env.reset(seed=seed) if k == 0 else env.reset()
            start = mountain_car.reset(ENV, rng_state)
            assert start == _gym_state(env), (seed, k)
            assert observation[0] == np.float32(start[0])
            _assert_observation(observation, start)
            starts.append(start)
        positions = [p for p, _ in starts]
        assert all(mountain_car.RESET_LOW <= p < mountain_car.RESET_HIGH for p in positions)
        assert all(v == 0.0 for _, v in starts)
        assert len(set(positions)) == len(positions)


def test_reset_py_func_equals_compiled():
    """The Python source of ``reset``, ``step`` and ``observe`` give what the compiled versions give."""
    compiled_state, python_state = stream_state(7), stream_state(7)
    with np.errstate(over="ignore"):
        for _ in range(20):
            start = mountain_car.reset(ENV, compiled_state)
            assert mountain_car.reset.py_func(ENV, python_state) == start
            state = start
            for action in (0, 0, 2, 1, 2, 0):
                expected = mountain_car.step(ENV, state, action, NO_DRAWS)
                assert mountain_car.step.py_func(ENV, state, action, NO_DRAWS) == expected
                state = expected[0]
                assert mountain_car.observe.py_func(ENV, state) == mountain_car.observe(ENV, state)
    np.testing.assert_array_equal(compiled_state, python_state)


@pytest.mark.parametrize(
    ("position", "velocity", "action", "expected_terminated"),
    [
        (0.49, 0.07, 2, True),  # crosses the goal moving right
        (0.5, 0.0, 1, False),  # gravity pulls it back below the goal: velocity < 0
        (0.6, 0.07, 2, True),  # clipped at the right edge, velocity kept
        (-1.2, -0.07, 0, False),  # the left wall: velocity reset to 0
        (-1.19, -0.05, 0, False),
    ],
)
def test_edge_states_equal_gymnasium(env, position, velocity, action, expected_terminated):
    """Hand-picked states at the goal and at both edges."""
    env.reset(seed=0)
    env.unwrapped.state = np.array([position, velocity])
    _, _, terminated, _, _ = env.step(action)
    (got_position, got_velocity), reward, got_terminated = mountain_car.step(ENV, (position, velocity), action,
                                                                             NO_DRAWS)
    assert (got_position, got_velocity) == _gym_state(env)
    assert got_terminated == terminated == expected_terminated
    assert reward == -1.0
    assert mountain_car.MIN_POSITION <= got_position <= mountain_car.MAX_POSITION
    assert -mountain_car.MAX_SPEED <= got_velocity <= mountain_car.MAX_SPEED


def test_observation_bounds_match_gymnasium(env):
    """The module's float32 bounds are Gymnasium's observation space."""
    np.testing.assert_array_equal(mountain_car.OBSERVATION_LOW, env.observation_space.low)
    np.testing.assert_array_equal(mountain_car.OBSERVATION_HIGH, env.observation_space.high)
    assert mountain_car.OBSERVATION_LOW.dtype == env.observation_space.dtype == np.float32
    assert env.action_space.n == mountain_car.N_ACTIONS
