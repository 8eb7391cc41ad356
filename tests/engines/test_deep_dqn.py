"""DQN and Double DQN in the deep engine: the TD target and loss by hand, the replay buffer, an update's
bookkeeping (time-limit cuts, target refresh, learning_starts), learning on CartPole, configuration checks."""

from __future__ import annotations

import dataclasses

import pytest

jax = pytest.importorskip("jax")

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

from rlcompare.deep import dqn, replay, use_compilation_cache  # noqa: E402
from rlcompare.deep.classic import CARTPOLE  # noqa: E402
from rlcompare.deep.presets import dqn as dqn_config  # noqa: E402
from rlcompare.envs import minatar  # noqa: E402
from rlcompare.envs.atari import games as atari  # noqa: E402
from rlcompare.validation import ConfigError  # noqa: E402


@pytest.fixture(autouse=True, scope="module")
def _compilation_cache() -> None:
    """JAX's persistent compilation cache, as the deep engine's own entry points use it: the programs below compile
    once on a machine, not in every run of this file."""
    use_compilation_cache()


# --- the target and the loss, by hand ---

NEXT_Q_ONLINE = jnp.array([[1.0, 5.0], [1.0, 5.0], [1.0, 5.0]])
NEXT_Q_TARGET = jnp.array([[3.0, 2.0], [3.0, 2.0], [3.0, 2.0]])
REWARD = jnp.array([1.0, 1.0, 1.0])
TERMINATED = jnp.array([False, True, False])
"""Row 0 continues, row 1 ended in a terminal state, row 2 was cut by the time limit (not terminated)."""


def test_dqn_target_maxes_the_target_network() -> None:
    target = dqn.td_target(REWARD, None, NEXT_Q_TARGET, TERMINATED, 0.5, double=False)
    np.testing.assert_allclose(target, [1 + 0.5 * 3, 1, 1 + 0.5 * 3])


def test_double_dqn_target_evaluates_the_online_argmax_with_the_target_network() -> None:
    # the online network prefers action 1 (5 > 1); the target network values it at 2, not its own max 3
    target = dqn.td_target(REWARD, NEXT_Q_ONLINE, NEXT_Q_TARGET, TERMINATED, 0.5, double=True)
    np.testing.assert_allclose(target, [1 + 0.5 * 2, 1, 1 + 0.5 * 2])


def test_loss_is_the_mean_huber_error_of_the_taken_actions() -> None:
    batch = replay.Transitions(observations=jnp.array([[1.0, 2.0], [0.0, 0.0]]), actions=jnp.array([1, 0]),
                            rewards=jnp.array([0.0, 3.0]), next_observations=jnp.array([[0.0, 4.0], [9.0, 9.0]]),
                            terminated=jnp.array([False, True]))
    identity = lambda params, observations: observations  # noqa: E731 - Q-values are the observations
    # row 0: Q = 2, target 0 + 0.5 * 4 = 2, error 0; row 1: Q = 0, target 3 (terminal), Huber(3) = 3 - 0.5
    settings = dqn_config.DQNConfig(gamma=0.5)
    assert float(dqn.q_loss(None, None, batch, identity, settings)) == pytest.approx(2.5 / 2)


# --- the replay buffer ---

def _rows(actions: list[int]) -> replay.Transitions:
    a = jnp.array(actions)
    obs = jnp.stack([a, -a], axis=1).astype(jnp.float32)
    return replay.Transitions(obs, a, a.astype(jnp.float32), obs + 1, a % 2 == 0)


@pytest.mark.slow("trains networks on classic control")
def test_buffer_wraps_around_overwriting_the_oldest() -> None:
    buffer = replay.buffer_add(replay.buffer_add(replay.buffer_init(3, 2), _rows([0, 1])), _rows([2, 3]))
    np.testing.assert_array_equal(buffer.data.actions, [3, 1, 2])
    np.testing.assert_array_equal(buffer.data.observations[:, 0], [3, 1, 2])
    assert (int(buffer.position), int(buffer.size)) == (1, 3)
    assert buffer.data.observations.dtype == jnp.float32
    assert buffer.data.actions.dtype == jnp.int32


@pytest.mark.slow("trains networks on classic control")
def test_buffer_samples_only_filled_slots() -> None:
    buffer = replay.buffer_add(replay.buffer_init(10, 2), _rows([5, 6, 7]))
    batch = replay.buffer_sample(buffer, jax.random.key(0), 600)
    assert set(np.asarray(batch.actions).tolist()) == {5, 6, 7}
    np.testing.assert_array_equal(batch.observations[:, 0], batch.actions)  # rows stay whole
    np.testing.assert_array_equal(batch.next_observations[:, 1], 1 - batch.actions)


# --- an update's bookkeeping ---

@pytest.mark.slow("trains networks on classic control")
def test_update_stores_true_last_observations_refreshes_the_target_and_waits_for_learning_starts() -> None:
    env = dataclasses.replace(CARTPOLE, max_steps=2)  # every second step is a time-limit cut
    config = dqn_config.DQNConfig(n_envs=2, train_freq=3, learning_starts=6, target_update_interval=4, buffer_size=8,
                           batch_size=4, learning_rate=1e-2, hidden=(8,))
    update = jax.jit(dqn.make_update(config, env))
    runner = dqn.init_runner(config, env, jax.random.key(1))
    initial = runner.params
    after = []
    for key in jax.random.split(jax.random.key(2), 3):
        runner, finished = update(runner, key)
        after.append(runner)
    first, second, third = after

    # rows are (step, env): row 2 t + e; step 1 ended every episode by truncation
    data = first.buffer.data
    assert finished.done.shape == (3, 2)
    np.testing.assert_array_equal(data.next_observations[0:2], data.observations[2:4])  # within an episode
    assert not np.asarray(data.terminated[:6]).any()
    assert not np.array_equal(data.next_observations[2:4], data.observations[4:6])  # a reset came between
    np.testing.assert_allclose(data.next_observations[2:4, 0],  # x' = x + τ ẋ: CartPole's true next state
                               data.observations[2:4, 0] + 0.02 * data.observations[2:4, 1], atol=1e-6)

    same = lambda a, b: all(jax.tree.leaves(jax.tree.map(np.array_equal, a, b)))  # noqa: E731
    assert int(first.steps) == 6
    assert same(first.params, initial)  # 6 steps are not more than learning_starts
    assert not same(second.params, initial)  # 12 > 6: trained
    assert same(third.target_params, second.params)  # refreshed at step 16, before the third training
    assert not same(third.params, third.target_params)


# --- learning ---

LEARNING = dataclasses.replace(dqn.PRESETS["default"]["CartPole-v1"], total_steps=10_000)
"""The zoo's CartPole-v1 settings on a 2 x 64 network, a fifth of its steps."""


@pytest.fixture(scope="module")
def cartpole_runs() -> tuple:
    train = jax.jit(jax.vmap(dqn.make_train(LEARNING, CARTPOLE, rounds=2, eval_episodes=10)))
    keys = jax.random.split(jax.random.key(0), 2)
    return jax.block_until_ready(train(keys)), jax.block_until_ready(train(keys))


@pytest.mark.slow("trains networks on classic control")
def test_dqn_learns_cartpole(cartpole_runs: tuple) -> None:
    out, _ = cartpole_runs
    assert out.eval_returns.shape == (2, 2, 10)
    updates = LEARNING.updates_per_round(2)
    assert out.finished.done.shape == (2, 2, updates, LEARNING.train_freq, 1)
    # Recorded from these keys (integer step counts, the same bits on every x86-64 CPU as the golden records): per
    # seed and round, ten greedy episodes of 110 to 257 steps on average, where a random policy lasts about 22.
    np.testing.assert_array_equal(out.eval_returns.sum(axis=-1), [[2571, 1257], [2274, 1098]])
    assert out.finished.done.sum() == 311


@pytest.mark.slow("trains networks on classic control")
def test_same_key_same_training(cartpole_runs: tuple) -> None:
    first, second = cartpole_runs
    for a, b in zip(jax.tree.leaves(first), jax.tree.leaves(second), strict=True):
        np.testing.assert_array_equal(a, b)
    assert not np.array_equal(first.eval_returns[0], first.eval_returns[1])  # the seeds differ


# --- configuration ---

def test_presets_are_the_zoos_and_the_default_changes_only_the_network() -> None:
    zoo, default = dqn.PRESETS["zoo"], dqn.PRESETS["default"]
    classic = {env: config for env, config in default.items() if env not in minatar.NAMES and env not in atari.NAMES}
    assert set(classic) == {"CartPole-v1", "MountainCar-v0", "Acrobot-v1"}
    assert set(zoo) == set(classic) | set(atari.NAMES)
    assert set(default) - set(classic) == set(minatar.NAMES) | set(atari.NAMES)  # tests/engines/test_minatar_dqn.py
    assert all(zoo[env] == default[env] == dqn_config.ATARI for env in atari.NAMES)  # the zoo's atari entry
    assert zoo["CartPole-v1"].hidden == (256, 256)
    assert zoo["CartPole-v1"].gradient_steps == 128
    for env, config in classic.items():
        assert config.hidden == (64, 64)
        assert dataclasses.replace(config, hidden=(256, 256)) == zoo[env]


@pytest.mark.parametrize(("field", "value"), [
    ("double", "yes"), ("n_envs", 0), ("n_envs", True), ("total_steps", 0), ("learning_rate", 0.0),
    ("learning_rate", float("nan")), ("buffer_size", 2), ("learning_starts", -1), ("batch_size", 32.0),
    ("gamma", 1.5), ("train_freq", 0), ("gradient_steps", -1), ("target_update_interval", 0),
    ("epsilon_start", 2.0), ("epsilon_end", -0.1), ("decay_fraction", 0.0), ("max_grad_norm", float("inf")),
    ("hidden", (64, 0)), ("hidden", [64]),
])
def test_bad_values_name_their_field(field: str, value: object) -> None:
    with pytest.raises(ConfigError) as error:
        dqn_config.DQNConfig(**{"n_envs": 4, field: value})
    assert error.value.field_name == field


def test_make_train_checks_rounds() -> None:
    with pytest.raises(ConfigError, match="rounds"):
        dqn.make_train(dqn_config.DQNConfig(), CARTPOLE, rounds=0, eval_episodes=1)


def test_a_training_that_never_takes_a_gradient_step_is_refused_naming_total_steps() -> None:
    """Atari 100k's budget with the zoo's learning_starts of 100,000: DQN once filled its buffer and learnt nothing."""
    with pytest.raises(ConfigError, match="more than learning_starts") as refused:
        dqn_config.DQNConfig(total_steps=100_000, learning_starts=100_000)
    assert refused.value.field_name == "total_steps"
    assert dqn_config.DQNConfig(total_steps=100_001, learning_starts=100_000).total_steps == 100_001
