"""MinAtar in the deep engine: the network computes a convolution, and the PQN pair trains on a game."""

from __future__ import annotations

import numpy as np
import pytest

jax = pytest.importorskip("jax")
pytest.importorskip("gymnax")

import flax.linen as nn  # noqa: E402
import jax.numpy as jnp  # noqa: E402

from rlcompare.deep.config import DeepConfig  # noqa: E402
from rlcompare.deep.networks import Conv3x3, ConvNet, patches_3x3  # noqa: E402
from rlcompare.experiment.runner import run as deep_run  # noqa: E402
from rlcompare.tabular.config import ExperimentConfig  # noqa: E402
from rlcompare.validation import ConfigError  # noqa: E402


@pytest.mark.slow("trains networks on MinAtar")
def test_image_patches_times_a_dense_layer_is_flaxs_convolution():
    images = jax.random.bernoulli(jax.random.PRNGKey(0), 0.3, (5, 10, 10, 7)).astype(jnp.float32)
    ours = Conv3x3(16)
    params = ours.init(jax.random.PRNGKey(1), images)["params"]["Dense_0"]
    # The dense kernel's rows are (channel, row, column); nn.Conv's kernel is (row, column, channel, feature).
    kernel = params["kernel"].reshape(7, 3, 3, 16).transpose(1, 2, 0, 3)
    theirs = nn.Conv(16, (3, 3), padding="VALID").apply({"params": {"kernel": kernel, "bias": params["bias"]}}, images)
    found = ours.apply({"params": {"Dense_0": params}}, images)
    assert found.shape == theirs.shape == (5, 8, 8, 16)
    np.testing.assert_allclose(found, theirs, rtol=1e-5, atol=1e-5)
    assert np.asarray(patches_3x3(images[0])).shape == (8, 8, 63)


@pytest.mark.slow("trains networks on MinAtar")
def test_minatars_network_has_its_papers_shape():
    params = ConvNet(6, layer_norm=True).init(jax.random.PRNGKey(0), jnp.zeros((1, 10, 10, 4)))["params"]
    shapes = jax.tree.map(lambda array: array.shape, params)
    assert shapes["Conv3x3_0"]["Dense_0"]["kernel"] == (36, 16)
    assert shapes["Dense_0"]["kernel"] == (8 * 8 * 16, 128)
    assert shapes["Dense_1"]["kernel"] == (128, 6)
    assert shapes["LayerNorm_0"]["scale"] == (16,)  # over each cell's channels, as purejaxql's
    assert "LayerNorm_0" not in ConvNet(6).init(jax.random.PRNGKey(0), jnp.zeros((1, 10, 10, 4)))["params"]


@pytest.mark.slow("trains networks on MinAtar")
def test_the_pqn_pair_trains_on_a_minatar_game():
    env, rollout, steps = "MinAtar/Breakout-v0", 128 * 32, 128 * 32 * 4
    results = {algorithm: deep_run(DeepConfig(algorithm=algorithm, env=env, seeds=(0, 1), vmap_width=2,
                                              eval_rounds=2, eval_episodes=3,
                                              hyperparameters={"total_steps": steps}))
               for algorithm in ("pqn_q_lambda", "pqn_sarsa_lambda")}
    for found in results.values():
        episodes = found.episodes
        assert set(episodes["seed"]) == {0, 1}
        assert episodes["env_step"].max() <= steps
        assert (episodes["length"] >= 1).all()
        assert np.isfinite(episodes["return"]).all()
        assert len(found.evaluations) == 2 * 2 * 3
        assert (found.evaluations["length"] >= 1).all()
        assert found.params["['params']['Conv3x3_0']['Dense_0']['kernel']"].shape[-2:] == (9 * 4, 16)
    # The two differ in the bootstrap alone: the same first rollout (every action random), then not.
    q, sarsa = (results[a].episodes for a in ("pqn_q_lambda", "pqn_sarsa_lambda"))
    first = [frame[frame["env_step"] <= rollout].reset_index(drop=True) for frame in (q, sarsa)]
    assert len(first[0]) > 50
    assert first[0].equals(first[1])
    assert not q.reset_index(drop=True).equals(sarsa.reset_index(drop=True))


def test_the_tabular_engine_refuses_an_image_environment_in_one_line():
    with pytest.raises(ConfigError) as refused:
        ExperimentConfig(env="MinAtar/Breakout-v0")
    assert refused.value.field_name == "env"
    assert "deep engine" in str(refused.value)
    with pytest.raises(ConfigError) as unknown:
        DeepConfig(env="MinAtar/Pong-v0")
    assert "MinAtar/Breakout-v0" in str(unknown.value)


@pytest.mark.slow("trains networks on MinAtar")
def test_one_game_object_serves_two_traces():
    """gymnax's game is built outside the first trace that asks for it, so the second trace does not meet the
    first one's leaked tracers (``UnexpectedTracerError``)."""
    from rlcompare.deep.minatar.games import minatar_env

    env = minatar_env("Breakout-MinAtar")

    def play(key: jax.Array) -> jax.Array:
        state, *_ = env.step(env.reset(key), jnp.int32(1), key)
        return env.observe(state)

    keys = jax.random.split(jax.random.key(0), 3)
    first = jax.jit(jax.vmap(play))(keys)
    second = jax.jit(play)(keys[0])
    np.testing.assert_array_equal(first[0], second)
