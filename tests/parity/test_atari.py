"""Atari 2600 through ale-py at a tiny scale: the games stepped from inside a jitted program equal ALE's own vector
environment stepped from Python (observations, rewards, episode ends, the last observation of an episode, the
resets), every deep method trains on one and gives the same bits twice, and what the engine cannot do is refused
with one line."""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest

jax = pytest.importorskip("jax")
ale_py = pytest.importorskip("ale_py")

import jax.numpy as jnp  # noqa: E402

from rlcompare.deep import dqn, ppo  # noqa: E402
from rlcompare.deep.atari import AtariEnv, NatureCNN, atari_env, reset_seed  # noqa: E402
from rlcompare.deep.config import DeepConfig  # noqa: E402
from rlcompare.deep.envs import evaluation_epsilon, jax_env, jax_env_names, learning_reward  # noqa: E402
from rlcompare.deep.presets import dqn as dqn_config  # noqa: E402
from rlcompare.deep.presets import ppo as ppo_config  # noqa: E402
from rlcompare.envs.atari import games as atari  # noqa: E402
from rlcompare.envs.registry import environment  # noqa: E402
from rlcompare.validation import ConfigError  # noqa: E402

pytestmark = pytest.mark.slow("trains on the Atari 2600's emulator")

SHORT = dataclasses.replace(atari.PROTOCOL, max_frames=600)
"""Episodes cut after 150 steps, so that a short test sees both ends of an episode."""
BREAKOUT = AtariEnv("Breakout-Atari", "breakout", SHORT)
GAMES, STEPS = 4, 400


def _rollout_in_jax(env: AtariEnv, key: jax.Array, actions: np.ndarray) -> tuple:
    def play(key: jax.Array, actions: jax.Array) -> tuple:
        start = env.reset_batch(jax.random.split(key, GAMES))

        def one_step(state: jax.Array, action: jax.Array) -> tuple:
            step = env.step_autoreset_batch(state, action, None)
            return step.state, (step.observation, step.last_observation, step.reward, step.terminated,
                                step.truncated)

        return start, jax.lax.scan(one_step, start, actions)[1]

    return jax.device_get(jax.jit(play)(key, jnp.asarray(actions)))


def _rollout_in_python(env: AtariEnv, seed: int, actions: np.ndarray) -> tuple:
    p = env.protocol
    library = ale_py.AtariVectorEnv(env.rom, GAMES, repeat_action_probability=p.sticky_action_prob,
                                    full_action_space=True, max_num_frames_per_episode=p.max_frames, noop_max=0,
                                    use_fire_reset=False, reward_clipping=False, autoreset_mode="SameStep")
    first, _ = library.reset(seed=seed)
    observations, lasts, rewards, terminated, truncated = [], [], [], [], []
    for action in actions:
        observation, reward, term, trunc, info = library.step(action)
        last = observation.copy()
        for game in np.flatnonzero(term | trunc):
            last[game] = info["final_obs"][game]
        for kept, value in ((observations, observation), (lasts, last), (rewards, reward), (terminated, term),
                            (truncated, trunc)):
            kept.append(value)
    library.close()
    to_hwc = (0, 1, 3, 4, 2)  # (steps, games, stack, 84, 84) -> (steps, games, 84, 84, stack)
    return (first.transpose(0, 2, 3, 1), (np.stack(observations).transpose(to_hwc), np.stack(lasts).transpose(to_hwc),
                                          np.stack(rewards), np.stack(terminated), np.stack(truncated)))


def test_games_stepped_inside_jax_equal_the_library_stepped_from_python() -> None:
    key = jax.random.key(3)
    actions = np.random.default_rng(0).integers(0, 18, size=(STEPS, GAMES)).astype(np.int32)
    start, (observations, lasts, rewards, terminated, truncated) = _rollout_in_jax(BREAKOUT, key, actions)
    seed = int(reset_seed(jax.random.split(key, GAMES)))
    reference_start, reference = _rollout_in_python(BREAKOUT, seed, actions)
    np.testing.assert_array_equal(start, reference_start)
    np.testing.assert_array_equal(observations, reference[0])
    np.testing.assert_array_equal(lasts, reference[1])
    np.testing.assert_array_equal(rewards, reference[2])
    np.testing.assert_array_equal(terminated, reference[3])
    np.testing.assert_array_equal(truncated, reference[4])
    # the rollout saw what it is meant to check: points scored, games lost, games cut at the limit, and the
    # last observation of an ended episode differing from the next one's start
    assert rewards.sum() > 0
    assert terminated.any()
    assert truncated.any()
    ended = terminated | truncated
    assert (lasts[ended] != observations[ended]).any()
    assert (lasts[~ended] == observations[~ended]).all()
    assert observations.dtype == np.uint8
    assert observations.shape[2:] == (84, 84, 4)


def test_the_registry_lists_each_game_under_the_protocol() -> None:
    entry = environment("Pong-Atari")
    assert entry.observation_shape == (84, 84, 4)
    assert entry.n_actions == 18
    assert not entry.tabular
    assert entry.max_steps == 27_000
    assert entry.action_names[1] == "fire"
    assert set(atari.NAMES) <= set(jax_env_names())
    assert jax_env("Breakout-Atari") == atari_env("Breakout-Atari")


def test_the_methods_learn_from_the_sign_of_the_score_and_record_the_score() -> None:
    reward = jnp.asarray([0.0, 1.0, 4.0, -7.0])
    np.testing.assert_array_equal(learning_reward(BREAKOUT, reward), [0.0, 1.0, 1.0, -1.0])
    np.testing.assert_array_equal(learning_reward(jax_env("CartPole-v1"), reward), reward)


def test_mnih_network_has_its_layers_and_reads_uint8_frames() -> None:
    net = NatureCNN(18)
    frames = jnp.zeros((2, 84, 84, 4), jnp.uint8)
    params = net.init(jax.random.key(0), frames)
    kernels = [leaf.shape for path, leaf in jax.tree_util.tree_flatten_with_path(params)[0]
               if "kernel" in jax.tree_util.keystr(path)]
    assert sorted(kernels) == sorted([(8, 8, 4, 32), (4, 4, 32, 64), (3, 3, 64, 64), (7 * 7 * 64, 512), (512, 18)])
    assert net.apply(params, frames).shape == (2, 18)


TINY = {
    # Q(λ)'s PQN: test_two_trainings_on_two_threads_equal_each_trained_alone, through the engine's train
    "dqn": (dqn, dataclasses.replace(dqn_config.ATARI, total_steps=2 * 48, n_envs=2, buffer_size=200,
                                     learning_starts=32, batch_size=8, hidden=(32,))),
    "ppo": (ppo, dataclasses.replace(ppo_config.ATARI, total_steps=2 * 4 * 16, n_envs=4, n_steps=16, batch_size=32,
                                      n_epochs=1, hidden=(32,))),
}


@pytest.mark.parametrize("method", list(TINY))
def test_each_method_trains_on_a_game_and_gives_the_same_bits_twice(method: str) -> None:
    module, config = TINY[method]
    with jax.enable_x64(True):
        train = jax.jit(module.make_train(config, BREAKOUT, rounds=2, eval_episodes=2))
        first = jax.device_get(train(jax.random.key(0)))
        second = jax.device_get(train(jax.random.key(0)))
        other = jax.device_get(train(jax.random.key(1)))
    for a, b in zip(jax.tree.leaves(first), jax.tree.leaves(second), strict=True):
        np.testing.assert_array_equal(a, b)
    assert any(not np.array_equal(a, b) for a, b in zip(jax.tree.leaves(first.params), jax.tree.leaves(other.params),
                                                        strict=True))
    assert first.eval_returns.shape == (2, 2)
    # every evaluation episode ended, by the game or at the protocol's limit
    assert (first.eval_lengths <= SHORT.max_steps).all()
    assert (first.eval_lengths > 0).all()


def test_several_seeds_side_by_side_are_refused_naming_the_field() -> None:
    with pytest.raises(ConfigError, match="vmap_width") as refused:
        DeepConfig(algorithm="pqn_q_lambda", env="Breakout-Atari", seeds=(0, 1), vmap_width=2)
    assert "Atari" in str(refused.value)
    with pytest.raises(ConfigError, match="env") as unknown:
        DeepConfig(algorithm="pqn_q_lambda", env="Tetris-Atari", vmap_width=1)
    assert "Breakout-Atari" in str(unknown.value)


def _tiny_config(seed: int) -> DeepConfig:
    return DeepConfig(algorithm="pqn_q_lambda", env="Breakout-Atari", seeds=(seed,), vmap_width=1, eval_rounds=1,
                      eval_episodes=1, hyperparameters={"total_steps": 128, "n_envs": 4, "n_steps": 16,
                                                        "n_minibatches": 2, "hidden": (32,)})


@pytest.fixture(scope="module")
def pqn_trainings() -> tuple[list, list]:
    """Q(λ)'s tiny training of seeds 0 and 1, each alone, then the two at once on two threads: one program,
    compiled once for the module."""
    from concurrent.futures import ThreadPoolExecutor

    from rlcompare.deep.train import train

    configs = [_tiny_config(0), _tiny_config(1)]
    alone = [train(config) for config in configs]
    with ThreadPoolExecutor(2) as pool:
        together = list(pool.map(train, configs))
    return alone, together


def test_two_trainings_on_two_threads_equal_each_trained_alone(pqn_trainings) -> None:
    """Also Q(λ)'s case of test_each_method_trains_on_a_game_and_gives_the_same_bits_twice, through the engine: a
    seed trained twice gives the same bits (episodes, evaluations, parameters at every stage), another seed other
    parameters."""
    alone, together = pqn_trainings
    for a, b in zip(alone, together, strict=True):
        pd.testing.assert_frame_equal(a.episodes, b.episodes)
        pd.testing.assert_frame_equal(a.evaluations, b.evaluations)
        assert list(a.params) == list(b.params)
        for name in a.params:
            np.testing.assert_array_equal(a.params[name], b.params[name])
        assert a.snapshots.keys() == b.snapshots.keys()
        for stage in a.snapshots:
            for name in a.snapshots[stage]:
                np.testing.assert_array_equal(a.snapshots[stage][name], b.snapshots[stage][name])
    # the two seeds learnt differently, so a training that played the other's games would show
    assert any(not np.array_equal(alone[0].params[n], alone[1].params[n]) for n in alone[0].params)


def test_evaluations_play_at_the_protocols_epsilon_and_end_by_the_game(pqn_trainings) -> None:
    assert evaluation_epsilon(BREAKOUT) == 0.05
    assert evaluation_epsilon(jax_env("CartPole-v1")) == 0.0
    alone, _ = pqn_trainings
    evaluations = alone[1].evaluations  # seed 1
    assert len(evaluations) == 1  # one round of one episode
    # an untrained greedy network that never presses FIRE would play every episode to the 27,000-step cut
    assert evaluations["terminated"].all()
    assert (evaluations["length"] < atari.PROTOCOL.max_steps).all()
    assert (evaluations["length"] > 0).all()


def test_gymnasiums_own_game_shows_the_frames_the_engine_sees() -> None:
    """Gymnasium's ALE/Breakout-v5 through its AtariPreprocessing and FrameStackObservation, set as training is,
    gives the engine's observations for the same actions (sticky actions off: their draws come from each
    library's own generator)."""
    no_sticky = dataclasses.replace(atari.PROTOCOL, sticky_action_prob=0.0)
    env = AtariEnv("Breakout-Atari", "breakout", no_sticky)
    actions = np.random.default_rng(5).integers(0, 18, size=(STEPS, 1)).astype(np.int32)

    def play(key: jax.Array, actions: jax.Array) -> tuple:
        start = env.reset_batch(jax.random.split(key, 1))

        def one_step(state: jax.Array, action: jax.Array) -> tuple:
            step = env.step_autoreset_batch(state, action, None)
            return step.state, (step.last_observation, step.terminated | step.truncated)

        return start, jax.lax.scan(one_step, start, actions)[1]

    start, (lasts, ended) = jax.device_get(jax.jit(play)(jax.random.key(0), jnp.asarray(actions)))
    gym_env = atari.gymnasium_env("Breakout-Atari", no_sticky)
    try:
        observation, _ = gym_env.reset(seed=0)
        np.testing.assert_array_equal(np.moveaxis(observation, 0, -1), start[0])
        for t, action in enumerate(actions[:, 0]):
            observation, _, terminated, truncated, _ = gym_env.step(int(action))
            np.testing.assert_array_equal(np.moveaxis(observation, 0, -1), lasts[t, 0])
            assert bool(terminated or truncated) == bool(ended[t, 0])
            if terminated or truncated:
                break
    finally:
        gym_env.close()
    assert t > 100  # the comparison saw the ball served and lost


@pytest.mark.parametrize(("features", "size", "stride", "shape"), [
    (32, 8, 4, (3, 84, 84, 4)), (64, 4, 2, (3, 20, 20, 32)), (64, 3, 1, (3, 9, 9, 64))])  # Mnih et al.'s three layers
def test_the_convolution_is_flaxs_with_the_kernels_gradient_taken_apart(features, size, stride, shape) -> None:
    """The same parameters, outputs and input gradients as flax's, bit for bit; the kernel's gradient, a sum taken in
    another order, within 2e-6 of flax's relative to its norm (measured: at most 4.9e-7, on the first layer)."""
    import flax.linen as nn

    from rlcompare.deep.atari import Conv

    x = jnp.asarray(np.random.default_rng(0).random(shape), jnp.float32)
    ours, flaxs = Conv(features, size, stride), nn.Conv(features, (size, size), (stride, stride), padding="VALID")
    params, reference = ours.init(jax.random.key(1), x), flaxs.init(jax.random.key(1), x)
    for a, b in zip(jax.tree.leaves(params), jax.tree.leaves(reference), strict=True):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(ours.apply(params, x), flaxs.apply(reference, x))

    def gradient(net: nn.Module, p: dict) -> tuple:
        return jax.grad(lambda p, x: (jnp.sin(net.apply(p, x)) ** 2).sum(), argnums=(0, 1))(p, x)

    (ours_p, ours_x), (flax_p, flax_x) = gradient(ours, params), gradient(flaxs, reference)
    kernel, flax_kernel = (np.asarray(g["params"]["kernel"], np.float64) for g in (ours_p, flax_p))
    assert np.linalg.norm(kernel - flax_kernel) <= 2e-6 * np.linalg.norm(flax_kernel)
    np.testing.assert_array_equal(ours_p["params"]["bias"], flax_p["params"]["bias"])
    np.testing.assert_array_equal(ours_x, flax_x)
