"""The compiled CartPole and Acrobot against Gymnasium's ``CartPole-v1`` and ``Acrobot-v1``, step by step."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from gymnasium_play import gymnasium_returns, resets

from rlcompare import ExperimentConfig, load_agent, run
from rlcompare.envs import acrobot, cartpole

ROLLOUT_STEPS = 60_000
ENVS = {cartpole: cartpole.CartPole(), acrobot: acrobot.Acrobot()}
"""The value each port's functions are given."""
NO_DRAWS = np.zeros(4, dtype=np.uint64)
"""The stream ``step`` is given; both ports are deterministic and never draw from it."""


def _numpy_trigonometry_is_libm() -> bool:
    """Gymnasium's Acrobot uses NumPy's sin and cos, the port the C library's; some NumPy builds use SIMD
    kernels (AVX-512) that differ from it in the last bit."""
    x = np.random.default_rng(0).uniform(-10, 10, 20_000)
    return all(np.cos(v) == math.cos(v) and np.sin(v) == math.sin(v) for v in x)


def _cartpole_policy(kind: str, state: tuple, generator: np.random.Generator) -> int:
    """Random pushes, or a balancing controller that keeps the pole up and lets the cart drift off the track
    (or reach the time limit), with 20% random pushes."""
    if kind == "random" or generator.random() < 0.2:
        return int(generator.integers(2))
    return int(state[2] + 0.5 * state[3] > 0.0)


def _acrobot_policy(kind: str, state: tuple, generator: np.random.Generator) -> int:
    """Random torques, or pumping energy (torque along the second joint's velocity): reaches the goal."""
    if kind == "random" or generator.random() < 0.1:
        return int(generator.integers(3))
    return 2 if state[3] >= 0 else 0


@pytest.mark.slow("steps long episodes beside Gymnasium")
@pytest.mark.parametrize(("port", "policy"), [(cartpole, _cartpole_policy), (acrobot, _acrobot_policy)],
                         ids=["CartPole-v1", "Acrobot-v1"])
def test_transitions_equal_gymnasium(port, policy) -> None:
    """Long rollouts from many seeds: start state, every state, observation, reward and termination equal
    (``==``) to Gymnasium's, episodes ending both ways (the goal or failure, and the time limit)."""
    if port is acrobot and not _numpy_trigonometry_is_libm():
        pytest.skip("this NumPy's sin and cos differ from the C library's; Gymnasium's Acrobot cannot be matched")
    limit = 500
    env = gym.make(port.ENV_ID, max_episode_steps=limit)
    ours = ENVS[port]
    generator = np.random.default_rng(7)
    total = terminations = truncations = 0
    for episodes, (observation, rng) in enumerate(resets(env, generator, every=3)):
        if total >= ROLLOUT_STEPS:
            break
        state = port.reset(ours, rng)
        assert len(state) == port.STATE_SIZE
        assert state == _gym_state(env)
        _assert_observation(port, state, observation, first=True)
        kind = "random" if episodes % 2 else "controlled"
        for steps in range(1, limit + 1):
            action = policy(kind, state, generator)
            observation, reward, terminated, truncated, _ = env.step(action)
            state, our_reward, done = port.step(ours, state, action, NO_DRAWS)
            total += 1
            assert state == _gym_state(env), (episodes, steps)
            _assert_observation(port, state, observation)
            assert (our_reward, done) == (reward, terminated)
            if terminated or truncated:
                terminations += terminated
                truncations += truncated
                break
    assert terminations > 30
    assert truncations > 3
    np.testing.assert_array_equal(NO_DRAWS, 0)


def _gym_state(env) -> tuple[float, ...]:
    """Gymnasium's state as a tuple of floats (Acrobot's start state is a float32 array, exact in float64)."""
    return tuple(float(x) for x in env.unwrapped.state)


def _assert_observation(port, state: tuple, observation: np.ndarray, first: bool = False) -> None:
    """``observe`` equals Gymnasium's observation, but for Acrobot's first: Gymnasium computes it from the
    float32 start state with NumPy's float32 sin and cos (SIMD approximations), the port in float64 rounded
    once; they may differ in the last bit of the float32 (about 0.2% of resets; the start state itself is
    equal)."""
    ours = port.observe(ENVS[port], state)
    assert len(ours) == (acrobot.OBSERVATION_SIZE if port is acrobot else cartpole.STATE_SIZE)
    ours = np.array(ours, dtype=np.float64)
    np.testing.assert_array_equal(ours, ours.astype(np.float32))  # observe rounds to float32 itself
    if port is acrobot and first:
        np.testing.assert_array_max_ulp(observation, ours.astype(np.float32), maxulp=1)
    else:
        np.testing.assert_array_equal(observation, ours.astype(np.float32))


def test_acrobot_clips_velocities_and_wraps_angles() -> None:
    """From a fast spin the port clips ``dtheta2`` at 9 pi and keeps the angles in [-pi, pi]."""
    ours = ENVS[acrobot]
    start = (3.0, 3.1, 4 * math.pi, 9 * math.pi)
    state = start
    for _ in range(20):
        state, _, _ = acrobot.step(ours, state, 2, NO_DRAWS)
        assert -math.pi <= state[0] <= math.pi
        assert -math.pi <= state[1] <= math.pi
        assert abs(state[2]) <= acrobot.MAX_VEL_1
        assert abs(state[3]) <= acrobot.MAX_VEL_2
    env = gym.make("Acrobot-v1").unwrapped
    env.reset(seed=0)
    env.state = np.array(start)
    state = start
    for _ in range(20):
        env.step(2)
        state, _, _ = acrobot.step(ours, state, 2, NO_DRAWS)
    if _numpy_trigonometry_is_libm():
        np.testing.assert_array_equal(np.array(state), env.state)


def test_sarsa_learns_cartpole_and_its_agent_balances_as_well_in_gymnasium(tmp_path) -> None:
    """On the default grid (1 x 1 x 6 x 12) SARSA with ε decaying goes from about 24 steps to hundreds; the
    loaded agent, in Gymnasium's own CartPole from the evaluation stream, returns what our evaluation did."""
    config = ExperimentConfig(env="CartPole-v1", algorithm="sarsa", seeds=(0, 1, 2), episodes=1500,
                              eval_every=1500, eval_episodes=10)
    results = run(config, out=tmp_path / "run")
    returns = results.records.returns
    # Recorded from these seeds (sums of integer rewards; exact where the C library's sin and cos give this
    # machine's bits, glibc 2.36 on x86-64, as for the golden digests): about 24 steps an episode at
    # first, hundreds at the end (the third seed 115), against about 22 for random actions.
    np.testing.assert_array_equal(returns[:, :100].sum(axis=1), [2295, 2360, 2496])
    np.testing.assert_array_equal(returns[:, -100:].sum(axis=1), [50000, 49762, 11542])
    for run_index, seed in enumerate(config.seeds):
        _, eval_env, _ = np.random.SeedSequence(seed).spawn(3)
        agent = load_agent(tmp_path / "run", seed=seed)
        theirs = gymnasium_returns(agent, eval_env, 10, env_id="CartPole-v1", limit=config.max_steps)
        np.testing.assert_array_equal(theirs, results.records.eval_returns[run_index, -1])


def test_q_learning_learns_to_swing_the_acrobot_up() -> None:
    """On the default grid (4 cells per cosine and sine, 8 per velocity) the episodes shorten from the 500-step
    limit to a few hundred steps, and the greedy policy reaches the goal."""
    config = ExperimentConfig(env="Acrobot-v1", algorithm="q_learning", seeds=(0, 1, 2), episodes=800,
                              eval_every=800, eval_episodes=5)
    results = run(config)
    records = results.records
    # Recorded from these seeds (sums of integer rewards; exact where the C library's sin and cos give this
    # machine's bits, glibc 2.36 on x86-64, as for the golden digests): about 500 steps an episode at
    # first, 280 to 380 at the end, and 11 of the 15 greedy episodes reach the goal.
    np.testing.assert_array_equal(records.returns[:, :50].sum(axis=1), [-24775, -25000, -25000])
    np.testing.assert_array_equal(records.returns[:, -100:].sum(axis=1), [-28215, -37896, -32405])
    np.testing.assert_array_equal(records.eval_terminated[:, -1].sum(axis=1), [3, 5, 3])
