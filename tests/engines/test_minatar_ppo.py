"""PPO on MinAtar: the actor-critic reads an image through MinAtar's convolution, initialised as flax's orthogonal
without LAPACK; the presets are purejaxql's (``config/alg/ppo_minatar.yaml``); its clipped value loss by hand; and a
short run on Breakout through the run layer that records what it should and learns."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

jax = pytest.importorskip("jax")
pytest.importorskip("gymnax")

import flax.linen as nn  # noqa: E402
import jax.numpy as jnp  # noqa: E402

from rlcompare.deep import ppo, ppo_networks  # noqa: E402
from rlcompare.deep.classic import CARTPOLE  # noqa: E402
from rlcompare.deep.config import DeepConfig  # noqa: E402
from rlcompare.deep.envs import jax_env  # noqa: E402
from rlcompare.deep.presets import ppo as ppo_config  # noqa: E402
from rlcompare.envs.minatar import NAMES  # noqa: E402
from rlcompare.experiment.runner import run as deep_run  # noqa: E402
from rlcompare.validation import ConfigError  # noqa: E402

BREAKOUT = "MinAtar/Breakout-v0"


@pytest.fixture(autouse=True, scope="module")
def _float64():
    """The deep engine's internals in JAX's float64, as its entry points run them (``tests/conftest.py``)."""
    with jax.enable_x64(True):
        yield


@pytest.mark.slow("trains networks on MinAtar")
@pytest.mark.parametrize(("name", "channels", "n_actions"), [(BREAKOUT, 4, 6), ("Seaquest-MinAtar", 10, 6),
                                                              ("Freeway-MinAtar", 7, 3)])
def test_the_actor_critic_reads_an_image(name: str, channels: int, n_actions: int) -> None:
    env = jax_env(name)
    config = ppo.PRESETS["default"][name]
    params = ppo.init_params(config, env, jax.random.key(0))
    shapes = jax.tree.map(lambda array: array.shape, params.network["params"])
    for head, outputs in (("actor", n_actions), ("critic", 1)):  # separate networks, as purejaxql's
        assert shapes[head]["Conv3x3_0"]["Dense_0"]["kernel"] == (9 * channels, 16)
        assert shapes[head]["Dense_0"]["kernel"] == (8 * 8 * 16, 128)
        assert shapes[head]["Dense_1"]["kernel"] == (128, outputs)
    images = jax.random.bernoulli(jax.random.key(1), 0.2, (5, 10, 10, channels))
    logits, values = ppo.network(config, env).apply(params.network, images)
    assert logits.shape == (5, n_actions)
    assert values.shape == (5,)
    assert ppo.act(config, env)(params, images).shape == (5,)
    assert params.observations.mean.shape == (10, 10, channels)  # left at its start: never normalised


@pytest.mark.slow("trains networks on MinAtar")
def test_initialisation_scales_are_the_mlps() -> None:
    """Orthogonal with gain √2 for the dense layer, 0.01 for the policy head and 1 for the value head, zero biases;
    the convolution keeps flax's LeCun-normal (``nn.Conv``'s default)."""
    network = ppo.init_params(ppo_config.MINATAR, jax_env(BREAKOUT), jax.random.key(2)).network["params"]
    for head, gain in (("actor", 0.01), ("critic", 1.0)):
        for layer, scale in (("Dense_0", np.sqrt(2.0)), ("Dense_1", gain)):
            kernel = np.asarray(network[head][layer]["kernel"], np.float64)
            np.testing.assert_allclose(kernel.T @ kernel, scale**2 * np.eye(kernel.shape[1]), atol=1e-5 * scale**2)
            assert not np.any(np.asarray(network[head][layer]["bias"]))
        conv = np.asarray(network[head]["Conv3x3_0"]["Dense_0"]["kernel"])
        assert abs(conv.std() * np.sqrt(36) - 1.0) < 0.15
    classic = ppo.init_params(ppo_config.ZOO["CartPole-v1"], CARTPOLE, jax.random.key(0)).network["params"]
    assert "Conv3x3_0" not in classic["actor"]


@pytest.mark.parametrize(("shape", "scale"), [((1024, 128), np.sqrt(2.0)), ((128, 6), 0.01), ((4, 64), 1.0)])
@pytest.mark.slow("compiles flax's initialiser")
def test_gram_schmidt_initialisation_is_flaxs_orthogonal(shape: tuple[int, int], scale: float) -> None:
    """The same matrix as ``nn.initializers.orthogonal`` (LAPACK's QR) to float32 rounding, without LAPACK."""
    key = jax.random.key(7)
    ours = np.asarray(ppo_networks.orthogonal(scale)(key, shape, jnp.float32))
    theirs = nn.initializers.orthogonal(scale)(key, shape, jnp.float32)
    np.testing.assert_allclose(ours, theirs, atol=2e-6 * scale)


def test_presets_are_purejaxqls_for_every_minatar_name() -> None:
    """purejaxql ``config/alg/ppo_minatar.yaml`` (mttga/purejaxql at 0436c80): TOTAL_TIMESTEPS 1e7, NUM_ENVS 64,
    NUM_STEPS 128, UPDATE_EPOCHS 4, NUM_MINIBATCHES 8, LR 0.005, ANNEAL_LR, GAMMA 0.99, GAE_LAMBDA 0.95, CLIP_EPS 0.2,
    ENT_COEF 0.0001, VF_COEF 0.5, MAX_GRAD_NORM 0.5, relu."""
    source = {"n_envs": 64, "n_steps": 128, "n_epochs": 4, "learning_rate": 0.005, "anneal_lr": True, "gamma": 0.99,
              "gae_lambda": 0.95, "clip_range": 0.2, "anneal_clip_range": False, "ent_coef": 0.0001, "vf_coef": 0.5,
              "max_grad_norm": 0.5, "activation": "relu", "hidden": (128,), "total_steps": 10_000_000,
              "value_loss": "purejaxrl", "normalize_observations": False, "normalize_rewards": False,
              "normalize_advantage": True}
    for name in NAMES:
        config = ppo.PRESETS["default"][name]
        assert {field: getattr(config, field) for field in source} == source, name
        assert (config.minibatches, config.batch_size) == (8, 1024)
        assert config.updates == 1220  # purejaxql's NUM_UPDATES: 1e7 // 128 // 64


def test_clipped_value_loss_by_hand() -> None:
    """ε = 0.2. V_old 1, V 1.5, R 2: (1.5 - 2)² = .25, clipped V 1.2: .64 -> .64. V_old 1, V 0.9, R 0: .81 and
    (clipped, inside the range) .81. V_old 0, V -1, R -1: 0 and (-0.2 + 1)² = .64 -> .64. Halved mean."""
    values, old, returns = jnp.array([1.5, 0.9, -1.0]), jnp.array([1.0, 1.0, 0.0]), jnp.array([2.0, 0.0, -1.0])
    np.testing.assert_allclose(ppo.clipped_value_loss(values, old, returns, 0.2), 0.5 * (0.64 + 0.81 + 0.64) / 3,
                               rtol=1e-6)
    with pytest.raises(ConfigError) as error:
        dataclasses.replace(ppo_config.MINATAR, value_loss="huber")
    assert error.value.field_name == "value_loss"


def test_images_are_not_normalised() -> None:
    with pytest.raises(ConfigError) as error:
        DeepConfig(algorithm="ppo", env=BREAKOUT, hyperparameters={"normalize_observations": True})
    assert error.value.field_name == "normalize_observations"


@pytest.mark.slow("trains networks on MinAtar")
def test_ppo_trains_on_breakout() -> None:
    """Two seeds, 16 environments x 64 steps per update for 24 updates: the records are whole and finite, and the
    training episodes of the last third score a point above those of the first (a random policy's stay flat)."""
    rounds, eval_episodes, batch = 3, 4, 16 * 64
    found = deep_run(DeepConfig(algorithm="ppo", env=BREAKOUT, seeds=(0, 1), vmap_width=2, eval_rounds=rounds,
                                eval_episodes=eval_episodes,
                                hyperparameters={"n_envs": 16, "n_steps": 64, "batch_size": 256,
                                                 "total_steps": 24 * batch}))
    episodes, evaluations = found.episodes, found.evaluations
    assert set(episodes["seed"]) == {0, 1}
    assert (episodes["length"] >= 1).all()
    assert np.isfinite(episodes["return"]).all()
    assert episodes["env_step"].max() <= 24 * batch
    assert len(evaluations) == 2 * rounds * eval_episodes
    assert np.isfinite(evaluations["return"]).all()
    assert (evaluations["length"] >= 1).all()
    assert found.params[".network['params']['actor']['Conv3x3_0']['Dense_0']['kernel']"].shape == (2, 36, 16)
    for _, seed in episodes.groupby("seed"):
        first = seed[seed["env_step"] <= 8 * batch]["return"].mean()
        last = seed[seed["env_step"] > 16 * batch]["return"].mean()
        assert last > first + 1.0, (first, last)  # measured: 0.86 -> 3.5 and 0.88 -> 3.1
