"""DQN and Double DQN on MinAtar (Young and Tian 2019, arXiv 1903.03176): the replay buffer keeps the games' boolean
images, the preset is the paper's (its reference code, ``examples/dqn.py`` in github.com/kenjyoung/MinAtar), both
methods train on ``MinAtar/Breakout-v0`` through the deep engine's ``run``, and the RMSProp step is torch's centered
one, computed by hand."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

jax = pytest.importorskip("jax")
pytest.importorskip("gymnax")

import jax.numpy as jnp  # noqa: E402

from rlcompare.deep import dqn, replay  # noqa: E402
from rlcompare.deep.config import DeepConfig  # noqa: E402
from rlcompare.deep.minatar.games import minatar_env  # noqa: E402
from rlcompare.deep.networks import ConvNet  # noqa: E402
from rlcompare.deep.presets import dqn as dqn_config  # noqa: E402
from rlcompare.deep.results import DeepResults  # noqa: E402
from rlcompare.envs import minatar  # noqa: E402
from rlcompare.experiment.runner import run as deep_run  # noqa: E402
from rlcompare.validation import ConfigError  # noqa: E402

ENV = "MinAtar/Breakout-v0"
"""Four channels (paddle, ball, trail, brick), six actions under the paper's protocol."""


# --- the replay buffer keeps the images as booleans ---

@pytest.mark.slow("trains networks on MinAtar")
def test_buffer_stores_boolean_images_as_the_environment_gives_them() -> None:
    env = minatar_env(ENV)
    config = dataclasses.replace(dqn_config.MINATAR, buffer_size=50, learning_starts=1_000)
    with jax.enable_x64(True):
        runner = dqn.init_runner(config, env, jax.random.key(0))
        data = runner.buffer.data
        assert data.observations.dtype == data.next_observations.dtype == jnp.bool_
        assert data.observations.shape == data.next_observations.shape == (50, 10, 10, 4)
        first = runner.observations
        runner, _ = jax.jit(dqn._collect_step(config, env))(runner, jax.random.key(1))
    assert int(runner.buffer.size) == 1
    np.testing.assert_array_equal(runner.buffer.data.observations[0], first[0])
    np.testing.assert_array_equal(runner.buffer.data.next_observations[0], runner.observations[0])  # not ended yet
    assert runner.buffer.data.observations.dtype == jnp.bool_


def test_classic_control_buffer_is_unchanged() -> None:
    buffer = replay.buffer_init(3, 4)
    assert buffer.data.observations.shape == (3, 4)
    assert buffer.data.observations.dtype == jnp.float32


# --- the preset is the paper's ---

def test_every_minatar_name_has_the_papers_preset() -> None:
    c = dqn_config.MINATAR
    assert all(dqn.PRESETS["default"][name] == c for name in minatar.NAMES)
    # examples/dqn.py: NUM_FRAMES, one environment, REPLAY_BUFFER_SIZE, BATCH_SIZE, TARGET_NETWORK_UPDATE_FREQ,
    # TRAINING_FREQ, REPLAY_START_SIZE
    assert (c.total_steps, c.n_envs, c.buffer_size, c.batch_size, c.target_update_interval, c.train_freq,
            c.gradient_steps, c.learning_starts) == (5_000_000, 1, 100_000, 32, 1_000, 1, 1, 5_000)
    # STEP_SIZE, SQUARED_GRAD_MOMENTUM, MIN_SQUARED_GRAD in torch's centered RMSprop; GAMMA; no clipping; 128 units
    assert (c.optimizer, c.learning_rate) == ("rmsprop", 0.00025)
    assert (dqn_config.RMSPROP_DECAY, dqn_config.RMSPROP_EPS) == (0.95, 0.01)
    assert (c.gamma, c.max_grad_norm, c.hidden, c.double) == (0.99, 0.0, (128,), False)
    # ε: 1 while t < REPLAY_START_SIZE, then ((END_EPSILON - 1) / FIRST_N_FRAMES) (t - REPLAY_START_SIZE) + 1
    with jax.enable_x64(True):
        eps = [float(dqn.epsilon(c, jnp.asarray(t, jnp.int64))) for t in (0, 5_000, 55_000, 105_000, 4_000_000)]
    np.testing.assert_allclose(eps, [1.0, 1.0, 0.55, 0.1, 0.1], rtol=1e-6)
    net = dqn.network(c, minatar_env(ENV))
    assert net == ConvNet(6, hidden=(128,), layer_norm=False)  # MinAtar's network, without PQN's LayerNorm
    assert DeepConfig(algorithm="dqn", env=ENV).method_config() == c
    assert DeepConfig(algorithm="double_dqn", env=ENV).method_config() == dataclasses.replace(c, double=True)


def test_a_bad_optimizer_is_refused_naming_the_field() -> None:
    with pytest.raises(ConfigError, match="adam, rmsprop") as error:
        dqn_config.DQNConfig(optimizer="sgd")
    assert error.value.field_name == "optimizer"
    with pytest.raises(ConfigError) as error:
        DeepConfig(algorithm="dqn", env=ENV, hyperparameters={"optimizer": "RMSProp"})
    assert error.value.field_name == "optimizer"
    with pytest.raises(ConfigError) as error:
        dqn_config.DQNConfig(max_grad_norm=-1.0)
    assert error.value.field_name == "max_grad_norm"
    assert dqn_config.DQNConfig().optimizer == "adam"


# --- the RMSProp step, by hand ---

@pytest.mark.slow("trains networks on MinAtar")
def test_rmsprop_steps_are_torchs_centered_rmsprop() -> None:
    """Two training steps of a tiny network equal torch's ``RMSprop(lr, alpha=0.95, eps=0.01, centered=True)``
    written out: ``v = 0.95 v + 0.05 g^2``, ``m = 0.95 m + 0.05 g``, ``θ -= lr g / (sqrt(v - m^2) + 0.01)``."""
    env = minatar_env(ENV)
    config = dataclasses.replace(dqn_config.MINATAR, hidden=(4,), buffer_size=16, batch_size=8, learning_rate=0.01)
    keys = jax.random.split(jax.random.key(2), 6)
    stored = replay.Transitions(jax.random.bernoulli(keys[0], 0.2, (16, 10, 10, 4)),
                             jax.random.randint(keys[1], (16,), 0, 6, jnp.int32),
                             jax.random.bernoulli(keys[2], 0.3, (16,)).astype(jnp.float32),
                             jax.random.bernoulli(keys[3], 0.2, (16, 10, 10, 4)),
                             jax.random.bernoulli(keys[4], 0.2, (16,)))
    apply = dqn.network(config, env).apply
    gradient = jax.jit(lambda params, target, batch: jax.grad(dqn.q_loss)(params, target, batch, apply, config))
    with jax.enable_x64(True):
        runner = dqn.init_runner(config, env, keys[5])
        runner = runner._replace(buffer=replay.buffer_add(runner.buffer, stored))
        train = jax.jit(dqn._train(config, env, dqn.dqn_targets))
        params = initial = jax.tree.map(np.asarray, runner.params)
        v = jax.tree.map(np.zeros_like, params)
        m = jax.tree.map(np.zeros_like, params)
        for step in range(2):
            key = jax.random.key(10 + step)
            batch = replay.buffer_sample(runner.buffer, jax.random.split(key, 1)[0], config.batch_size)
            g = jax.tree.map(np.asarray, gradient(params, runner.target_params, batch))
            v = jax.tree.map(lambda v, g: 0.95 * v + 0.05 * g * g, v, g)
            m = jax.tree.map(lambda m, g: 0.95 * m + 0.05 * g, m, g)
            params = jax.tree.map(lambda p, g, v, m: p - 0.01 * g / (np.sqrt(v - m * m) + 0.01), params, g, v, m)
            runner = train(runner, key)
    moved = jax.tree.map(lambda a, b: float(np.abs(a - b).max()), params, jax.tree.map(np.asarray, runner.params))
    assert max(jax.tree.leaves(moved)) < 1e-6
    steps = jax.tree.map(lambda a, b: float(np.abs(a - b).max()), params, initial)
    assert min(jax.tree.leaves(steps)) > 1e-3  # every layer moved: the comparison is not vacuous


# --- training through the deep engine ---

TINY = {"total_steps": 1_200, "learning_starts": 200, "buffer_size": 1_200, "target_update_interval": 100}


@pytest.fixture(scope="module")
def breakout_runs() -> dict[str, DeepResults]:
    return {algorithm: deep_run(DeepConfig(algorithm=algorithm, env=ENV, hyperparameters=TINY, seeds=(0,),
                                           vmap_width=1, eval_rounds=2, eval_episodes=3))
            for algorithm in ("dqn", "double_dqn")}


@pytest.mark.slow("trains networks on MinAtar")
@pytest.mark.parametrize("algorithm", ["dqn", "double_dqn"])
def test_dqn_and_double_dqn_train_on_breakout(breakout_runs: dict[str, DeepResults], algorithm: str) -> None:
    results = breakout_runs[algorithm]
    episodes, evaluations = results.episodes, results.evaluations
    assert len(episodes) >= 20  # a Breakout episode of a poor player lasts a few dozen steps at most
    assert episodes["env_step"].is_monotonic_increasing
    assert episodes["env_step"].max() <= 1_200
    assert episodes["length"].sum() <= 1_200
    assert episodes["terminated"].all()
    assert (episodes["return"] >= 0).all()
    assert (episodes["return"] == episodes["return"].round()).all()
    assert evaluations["after_step"].tolist() == [600] * 3 + [1_200] * 3
    assert (evaluations["length"] >= 1).all()
    assert results.params["['params']['Conv3x3_0']['Dense_0']['kernel']"].shape == (1, 36, 16)
    assert not any("LayerNorm" in name for name in results.params)
    assert results.config.method_config().optimizer == "rmsprop"


@pytest.mark.slow("trains networks on MinAtar")
def test_dqn_and_double_dqn_learn_differently(breakout_runs: dict[str, DeepResults]) -> None:
    kernel = "['params']['Dense_1']['kernel']"
    assert not np.array_equal(breakout_runs["dqn"].params[kernel], breakout_runs["double_dqn"].params[kernel])
