"""PPO in the deep engine: its pieces by hand and against Stable-Baselines3's loop, its settings' validation,
and a short CartPole training that learns and repeats itself exactly."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

pytest.importorskip("jax")

import jax
import jax.numpy as jnp

from rlcompare.deep import ppo, use_compilation_cache
from rlcompare.deep.classic import CARTPOLE, MOUNTAIN_CAR
from rlcompare.deep.envs import jax_env_names
from rlcompare.deep.presets import ppo as ppo_config
from rlcompare.deep.rollout import TrainOutput
from rlcompare.envs.chess import games as chess_games
from rlcompare.validation import ConfigError

F, T = False, True


@pytest.fixture(autouse=True, scope="module")
def _compilation_cache() -> None:
    """JAX's persistent compilation cache, as the deep engine's own entry points use it: the programs below compile
    once on a machine, not in every run of this file."""
    use_compilation_cache()


def test_gae_by_hand() -> None:
    """Env 0 terminates at step 1 (no bootstrap, trace cut); env 1 is cut by the time limit at step 0 (bootstraps
    from V(last observation) = 7, not from the next episode's first value, 2; trace cut)."""
    rewards = jnp.array([[1.0, 2.0], [3.0, 4.0], [5.0, 6.0]], jnp.float32)
    values = jnp.array([[0.5, 1.0], [0.25, 2.0], [1.5, 0.5]], jnp.float32)
    next_values = jnp.array([[0.25, 7.0], [9.0, 0.5], [2.0, 3.0]], jnp.float32)
    terminated = jnp.array([[F, F], [T, F], [F, F]])
    dones = jnp.array([[F, T], [T, F], [F, F]])
    advantages = ppo.gae(rewards, values, next_values, terminated, dones, gamma=0.9, lam=0.5)
    # env 0: δ2 = 5 + .9*2 - 1.5; δ1 = 3 - .25 (terminated); δ0 = 1 + .9*.25 - .5, plus .45 * A1
    # env 1: δ2 = 6 + .9*3 - .5; δ1 = 4 + .9*.5 - 2, plus .45 * A2; δ0 = 2 + .9*7 - 1 (truncated: no carry)
    expected = [[0.725 + 0.45 * 2.75, 7.3], [2.75, 2.45 + 0.45 * 8.2], [5.3, 8.2]]
    assert advantages.dtype == jnp.float32
    np.testing.assert_allclose(advantages, expected, rtol=1e-6)


def _sb3_advantages(rewards, values, next_values, terminated, truncated, last_values, gamma, lam):
    """SB3's ``collect_rollouts`` timeout bootstrap and ``RolloutBuffer.compute_returns_and_advantage``, in NumPy."""
    rewards = rewards + gamma * next_values * truncated
    dones = terminated | truncated
    advantages, last = np.zeros_like(rewards), 0.0
    for t in reversed(range(len(rewards))):
        following = last_values if t == len(rewards) - 1 else values[t + 1]
        delta = rewards[t] + gamma * following * (1.0 - dones[t]) - values[t]
        last = advantages[t] = delta + gamma * lam * (1.0 - dones[t]) * last
    return advantages


def test_gae_matches_sb3_on_random_rollouts() -> None:
    rng = np.random.default_rng(0)
    steps, envs = 24, 5
    rewards, values, last_obs_values = (rng.normal(size=(steps, envs)).astype(np.float32) for _ in range(3))
    terminated = rng.random((steps, envs)) < 0.15
    truncated = (rng.random((steps, envs)) < 0.15) & ~terminated
    dones = terminated | truncated
    # V(last observation) is the next step's value except where an episode ended, and at the end of the rollout
    next_values = np.where(dones, last_obs_values, np.roll(values, -1, axis=0))
    next_values[-1] = last_obs_values[-1]
    ours = ppo.gae(jnp.asarray(rewards), jnp.asarray(values), jnp.asarray(next_values), jnp.asarray(terminated),
                   jnp.asarray(dones), 0.98, 0.8)
    theirs = _sb3_advantages(rewards, values, next_values, terminated, truncated, last_obs_values[-1], 0.98, 0.8)
    np.testing.assert_allclose(ours, theirs, rtol=1e-5, atol=1e-5)


@pytest.mark.slow("trains networks on classic control")
def test_clipped_surrogate_by_hand() -> None:
    """ε = 0.2: inside the range the ratio counts as it is; outside, the pessimistic (smaller) term counts."""
    ratios = jnp.array([1.1, 1.5, 0.5, 1.5, 0.5], jnp.float32)
    advantages = jnp.array([2.0, 2.0, 2.0, -1.0, -1.0], jnp.float32)
    # min(rA, clip(r)A): 2.2 (inside), 2.4 (clipped at 1.2), 1.0 (0.5 * 2 < 0.8 * 2), -1.5 (1.5 * -1 < 1.2 * -1),
    # -0.8 (clipped at 0.8)
    terms = np.array([2.2, 2.4, 1.0, -1.5, -0.8])
    old = jnp.zeros(5, jnp.float32)
    loss = ppo.clipped_surrogate_loss(jnp.log(ratios), old, advantages, 0.2)
    np.testing.assert_allclose(loss, -terms.mean(), rtol=1e-6)
    # no gradient through the clipped terms; -rA/n through the others
    grad = jax.grad(ppo.clipped_surrogate_loss)(jnp.log(ratios), old, advantages, 0.2)
    np.testing.assert_allclose(grad, -np.array([2.2, 0.0, 1.0, -1.5, 0.0]) / 5, rtol=1e-6, atol=1e-7)


@pytest.mark.slow("trains networks on classic control")
def test_value_loss_entropy_and_advantage_normalisation() -> None:
    np.testing.assert_allclose(ppo.value_loss(jnp.array([1.0, 2.0]), jnp.array([2.0, 4.0])), 2.5)
    np.testing.assert_allclose(ppo.entropy(jnp.zeros((2, 3), jnp.float32)), [np.log(3)] * 2, rtol=1e-6)
    assert ppo.entropy(jnp.array([0.0, -1e9], jnp.float32)) == 0
    normalised = ppo.normalize_advantages(jnp.array([1.0, 2.0, 3.0], jnp.float32))
    np.testing.assert_allclose(normalised, [-1.0, 0.0, 1.0], rtol=1e-6)  # sample std of 1, 2, 3 is 1


def test_running_statistics_equal_those_of_all_batches() -> None:
    rng = np.random.default_rng(1)
    batches = [rng.normal(3.0, 2.0, size=(16, 2)) for _ in range(5)]
    stats = ppo.RunningMeanStd.start((2,))
    for batch in batches:
        stats = ppo.update_running(stats, jnp.asarray(batch))
    everything = np.concatenate(batches)
    np.testing.assert_allclose(stats.mean, everything.mean(axis=0), rtol=1e-4)
    np.testing.assert_allclose(stats.var, everything.var(axis=0), rtol=1e-4)


@pytest.mark.parametrize(("field", "value"), [
    ("learning_rate", 0.0), ("learning_rate", float("nan")), ("gamma", 0.0), ("gamma", 1.5), ("gae_lambda", -0.1),
    ("batch_size", 100), ("n_envs", 0), ("n_steps", 2.0), ("clip_range", -0.2), ("max_grad_norm", 0),
    ("activation", "gelu"), ("hidden", [64, 64]), ("hidden", (64, 0)), ("anneal_lr", 1), ("total_steps", 255),
])
def test_bad_values_are_refused_naming_the_field(field: str, value: object) -> None:
    with pytest.raises(ConfigError) as error:
        dataclasses.replace(ppo_config.ZOO["CartPole-v1"], **{field: value})
    assert error.value.field_name == field


def test_presets_are_the_zoos_for_every_deep_environment() -> None:
    assert ppo.PRESETS["default"] is ppo_config.ZOO
    assert set(ppo_config.ZOO) == set(jax_env_names()) - set(chess_games.GAMES)  # PPO plays no two-player game
    cartpole = ppo_config.ZOO["CartPole-v1"]
    assert (cartpole.n_envs, cartpole.n_steps, cartpole.batch_size, cartpole.n_epochs) == (8, 32, 256, 20)
    assert ppo_config.ZOO["MountainCar-v0"].normalize_observations


def test_each_round_needs_an_update() -> None:
    config = ppo_config.ZOO["CartPole-v1"]
    assert config.updates == 390  # 100_000 // (8 * 32)
    ppo.make_train(config, CARTPOLE, rounds=390, eval_episodes=1)
    with pytest.raises(ConfigError, match="total_steps"):
        ppo.make_train(config, CARTPOLE, rounds=391, eval_episodes=1)


ROUNDS, UPDATES, EVAL_EPISODES = 2, 40, 16
SMALL_CARTPOLE = dataclasses.replace(ppo_config.ZOO["CartPole-v1"], total_steps=UPDATES * 8 * 32)


@pytest.fixture(scope="module")
def cartpole_runs() -> tuple[TrainOutput, TrainOutput]:
    """The zoo's CartPole settings for 10,240 steps (40 updates, the schedules annealed over them), twice."""
    train = jax.jit(ppo.make_train(SMALL_CARTPOLE, CARTPOLE, rounds=ROUNDS, eval_episodes=EVAL_EPISODES))
    key = jax.random.key(3)
    return jax.block_until_ready(train(key)), jax.block_until_ready(train(key))


@pytest.mark.slow("trains networks on classic control")
def test_cartpole_learns(cartpole_runs: tuple[TrainOutput, TrainOutput]) -> None:
    out, _ = cartpole_runs
    assert out.eval_returns.shape == (ROUNDS, EVAL_EPISODES)
    assert out.finished.done.shape == (ROUNDS, UPDATES // ROUNDS, 32, 8)
    # Recorded from this key (integer step counts, the same bits on every x86-64 CPU as the golden records): the
    # last round's 16 greedy episodes last 154 steps on average, a random policy about 22.
    np.testing.assert_array_equal(out.eval_returns[-1].sum(), 2458)
    done = np.asarray(out.finished.done)
    assert done.sum() == 123
    assert np.all(np.asarray(out.finished.lengths)[done] >= 1)


@pytest.mark.slow("trains networks on classic control")
def test_same_key_same_training(cartpole_runs: tuple[TrainOutput, TrainOutput]) -> None:
    first, second = cartpole_runs
    for a, b in zip(jax.tree.leaves(first), jax.tree.leaves(second), strict=True):
        np.testing.assert_array_equal(a, b)


@pytest.mark.slow("trains networks on classic control")
def test_normalised_training_keeps_statistics_in_the_params() -> None:
    """The zoo's MountainCar settings (VecNormalize) for two updates: the observation statistics have seen the
    reset and every step, and the greedy policy reads raw observations through them."""
    config = dataclasses.replace(ppo_config.ZOO["MountainCar-v0"], total_steps=2 * 16 * 16)
    out = jax.jit(ppo.make_train(config, MOUNTAIN_CAR, rounds=1, eval_episodes=2))(jax.random.key(0))
    stats = out.params.observations
    np.testing.assert_allclose(stats.count, 1e-4 + 16 * (1 + 2 * 16))
    assert np.all(np.asarray(stats.var) < 0.1)  # MountainCar's positions and velocities, not the start's 1
    assert np.all(np.isfinite(np.asarray(out.eval_returns)))
    actions = ppo.act(config, MOUNTAIN_CAR)(out.params, jnp.zeros((3, 2), jnp.float32))
    assert actions.shape == (3,)
    assert actions.dtype.kind == "i"
