"""DQN on MinAtar as ``rlcompare bench deep`` times it: the seeds trained side by side under ``vmap`` train as each
alone does, and Stable-Baselines3's counterpart (the ``bench`` extra) has the same network: our weights carried
into it give our Q-values."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

jax = pytest.importorskip("jax")
pytest.importorskip("gymnax")

import jax.numpy as jnp  # noqa: E402

from rlcompare.deep import dqn  # noqa: E402
from rlcompare.deep.envs import jax_env  # noqa: E402
from rlcompare.deep.presets import dqn as dqn_config  # noqa: E402

ENV = "Breakout-MinAtar"


@pytest.mark.slow("compiles MinAtar's DQN")
def test_seeds_side_by_side_train_as_each_alone_across_learning_starts() -> None:
    """Two seeds under ``vmap``, one short of ``learning_starts`` and one past it, then both past it: each seed's
    runner after an update is the one its own unbatched update gives (the first keeps its parameters)."""
    env = jax_env(ENV)
    config = dataclasses.replace(dqn_config.MINATAR, buffer_size=64, learning_starts=20, hidden=(8,))
    update = dqn.make_update(config, env)
    with jax.enable_x64(True):
        alone = jax.jit(update)
        side_by_side = jax.jit(jax.vmap(update))
        runners = [dqn.init_runner(config, env, jax.random.key(seed)) for seed in (0, 1)]
        for index, runner in enumerate(runners):  # 25 steps, trained from the 21st (the program compared below)
            for key in jax.random.split(jax.random.key(9), 25):
                runner = alone(runner, key)[0]
            runners[index] = runner
        runners[0] = runners[0]._replace(steps=jnp.asarray(config.learning_starts - 1, jnp.int64))
        batched = jax.tree.map(lambda *leaves: jnp.stack(leaves), *runners)
        keys = jnp.stack([jax.random.key(3), jax.random.key(4)])
        before = [runner.params for runner in runners]
        trained = []
        for _ in range(2):  # one seed trains, then both
            expected = [alone(runner, key)[0] for runner, key in zip(runners, keys, strict=True)]
            batched, _ = side_by_side(batched, keys)
            for seed, runner in enumerate(expected):
                jax.tree.map(lambda a, b, seed=seed: np.testing.assert_allclose(a, b[seed], rtol=1e-6, atol=1e-7),
                             runner, batched)
            trained.append([not moved_none(old, runner.params) for old, runner in zip(before, expected, strict=True)])
            before = [runner.params for runner in expected]
            runners, keys = expected, jax.vmap(lambda key: jax.random.fold_in(key, 1))(keys)
    assert trained == [[False, True], [True, True]]


def moved_none(params, other) -> bool:
    return all(np.array_equal(a, b) for a, b in zip(jax.tree.leaves(params), jax.tree.leaves(other), strict=True))


# --- Stable-Baselines3's counterpart ---

def carried_over(params: dict, policy) -> None:
    """Our ConvNet's weights into SB3's Q-network (``net_arch=[]``): the convolution's kernel rows are ordered
    channel, row, column (``patches_3x3``); our flattening puts the 16 channels last, torch's first."""
    import torch

    layers = jax.tree.map(np.array, params["params"])  # writable copies: torch takes no read-only arrays
    q_net = policy.q_net
    conv, dense = q_net.features_extractor.conv, q_net.features_extractor.dense
    kernel = layers["Conv3x3_0"]["Dense_0"]["kernel"]  # (9 C, 16)
    depth, channels = conv.in_channels, conv.out_channels
    side = round(np.sqrt(dense.in_features // channels))
    with torch.no_grad():
        conv.weight.copy_(torch.from_numpy(kernel.reshape(depth, 3, 3, channels).transpose(3, 0, 1, 2).copy()))
        conv.bias.copy_(torch.from_numpy(layers["Conv3x3_0"]["Dense_0"]["bias"]))
        hidden = layers["Dense_0"]["kernel"].reshape(side, side, channels, -1).transpose(2, 0, 1, 3)
        dense.weight.copy_(torch.from_numpy(hidden.reshape(dense.in_features, -1).T.copy()))
        dense.bias.copy_(torch.from_numpy(layers["Dense_0"]["bias"]))
        head = q_net.q_net[0]
        head.weight.copy_(torch.from_numpy(layers["Dense_1"]["kernel"].T.copy()))
        head.bias.copy_(torch.from_numpy(layers["Dense_1"]["bias"]))


@pytest.mark.slow("builds Stable-Baselines3's DQN")
def test_sb3s_dqn_has_our_network_and_settings() -> None:
    pytest.importorskip("stable_baselines3")
    import torch

    from rlcompare.bench import minatar as bench

    config = dqn.PRESETS["default"][ENV]
    model = bench.sb3_minatar_dqn(config)
    env = jax_env(ENV)
    assert model.observation_space.shape == env.observation_shape
    assert model.action_space.n == env.n_actions == 3
    q_net = model.policy.q_net
    assert len(q_net.q_net) == 1  # net_arch=[]: the head is one linear layer
    assert isinstance(q_net.q_net[0], torch.nn.Linear)
    assert (q_net.features_extractor.conv.kernel_size, q_net.features_extractor.dense.in_features) == ((3, 3), 1024)
    optimizer = model.policy.optimizer
    assert isinstance(optimizer, torch.optim.RMSprop)
    assert {key: optimizer.defaults[key] for key in ("lr", "alpha", "eps", "centered", "momentum")} == {
        "lr": 0.00025, "alpha": 0.95, "eps": 0.01, "centered": True, "momentum": 0}
    assert (model.buffer_size, model.batch_size, model.learning_starts, model.target_update_interval,
            model.gamma, model.max_grad_norm) == (100_000, 32, 5_000, 1_000, 0.99, float("inf"))
    assert (model.train_freq.frequency, model.gradient_steps) == (1, 1)
    assert (model.exploration_initial_eps, model.exploration_final_eps) == (1.0, 0.1)
    gym_env = model.get_env().envs[0]
    assert gym_env.spec.max_episode_steps == 1000
    assert gym_env.unwrapped.game.sticky_action_prob == 0.0

    net = dqn.network(config, env)
    params = net.init(jax.random.key(5), jnp.zeros((1, *env.observation_shape)))
    carried_over(params, model.policy)
    images = np.array(jax.random.bernoulli(jax.random.key(6), 0.3, (64, *env.observation_shape)))
    with torch.no_grad():
        theirs = q_net(torch.as_tensor(images, dtype=torch.float32)).numpy()
    ours = np.asarray(jax.jit(net.apply)(params, images))
    assert np.abs(ours).max() > 0.05  # not vacuous
    np.testing.assert_allclose(theirs, ours, rtol=1e-5, atol=1e-5)
