"""Gymnasium's toy-text environments stepped from their own tables: FrozenLake (4x4 and 8x8) and Taxi-v4."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from rlcompare import ExperimentConfig, run
from rlcompare.envs.table import from_gymnasium, observe, reset, step
from rlcompare.rng import stream_state


def test_taxi_resets_and_steps_as_gymnasium() -> None:
    """Taxi is deterministic; its start state is drawn as Gymnasium draws it (``cumsum > random()``), so
    the first reset of stream ``PCG64(s)`` equals ``env.reset(seed=s)``; ``observe`` gives Gymnasium's
    observation, the state's index."""
    table = from_gymnasium("Taxi-v4")
    env = gym.make("Taxi-v4")
    rng = np.random.default_rng(1)
    for seed in range(20):
        observation, _ = env.reset(seed=seed)
        ours_rng = stream_state(seed)
        state = reset(table, ours_rng)
        assert state == observation
        assert observe(table, state) == (observation,)
        for _ in range(100):
            action = int(rng.integers(6))
            observation, reward, terminated, _, _ = env.step(action)
            state, our_reward, ends = step(table, state, action, ours_rng)
            assert (state, our_reward, ends) == (observation, reward, terminated)
            assert observe(table, state) == (observation,)
            if terminated:
                break


def test_frozen_lake_table_is_gymnasiums_and_q_learning_learns_it() -> None:
    table = from_gymnasium("FrozenLake-v1")
    model = gym.make("FrozenLake-v1").unwrapped.P
    for state, actions in model.items():
        for action, outcomes in actions.items():
            probabilities = np.cumsum([p for p, *_ in outcomes])
            np.testing.assert_allclose(table.cumulative[state, action, : len(outcomes)], probabilities)
            assert list(table.next_state[state, action, : len(outcomes)]) == [o[1] for o in outcomes]
    config = ExperimentConfig(env="FrozenLake-v1", algorithm="q_learning", alpha=0.1, gamma=0.99, episodes=3000,
                              seeds=(0, 1, 2), eval_every=3000, eval_episodes=200, max_steps=100)
    # Recorded from these seeds, compared exactly (the lake's table holds no arithmetic that varies by machine):
    # 70% to 75% of the greedy episodes reach the goal, where the optimal policy of the slippery lake reaches it 74%.
    np.testing.assert_array_equal(run(config).records.eval_returns[:, -1].sum(axis=1), [140, 149, 150])


@pytest.mark.slow("compiles or trains for a second or more")
def test_tables_stay_in_step_with_gymnasium_over_many_episodes() -> None:
    """Seeded once, then plain resets: every reset and step draws one uniform from the environment stream,
    as Gymnasium's ``categorical_sample`` does, so starts (Taxi) and slips (FrozenLake) stay equal episode
    after episode, not only until the first reset."""
    rng = np.random.default_rng(5)
    for env_id, limit in (("Taxi-v4", 200), ("FrozenLake-v1", 100), ("FrozenLake8x8-v1", 200)):
        table, env = from_gymnasium(env_id), gym.make(env_id, max_episode_steps=limit)
        observation, _ = env.reset(seed=11)
        ours_rng = stream_state(11)
        starts = set()
        for episode in range(300):
            if episode:
                observation, _ = env.reset()
            state = reset(table, ours_rng)
            assert state == observation, (env_id, episode)
            starts.add(state)
            for _ in range(limit):
                action = int(rng.integers(table.n_actions))
                observation, reward, terminated, truncated, _ = env.step(action)
                state, our_reward, ends = step(table, state, action, ours_rng)
                assert (state, our_reward, ends) == (observation, reward, terminated), (env_id, episode)
                if terminated or truncated:
                    break
        assert len(starts) > (50 if env_id == "Taxi-v4" else 0)
        np.testing.assert_array_equal(ours_rng, _generator_state(env.unwrapped.np_random))


def _generator_state(generator: np.random.Generator) -> np.ndarray:
    state = generator.bit_generator.state["state"]
    mask = (1 << 64) - 1
    return np.array([state["state"] >> 64, state["state"] & mask, state["inc"] >> 64, state["inc"] & mask],
                    dtype=np.uint64)


def test_every_method_sees_the_same_start_states_on_stochastic_tables() -> None:
    """Resets draw from the environment stream and slips from a stream of their own, so after the same number
    of episodes every method has drawn the same starts, however long its episodes were and however often it
    slipped: the start state of episode k of seed s is the same for every method (common random numbers)."""
    from rlcompare.algorithms.registry import rule_for as method_rule
    from rlcompare.envs.features import make_features
    from rlcompare.envs.registry import make_env
    from rlcompare.tabular.config import ExperimentConfig
    from rlcompare.tabular.runs import train_runs
    from rlcompare.tabular.state import ENV_STREAM, TRANSITION_STREAM, allocate_records, initial_state
    from rlcompare.tabular.train import epsilon_schedule, kernel_settings

    for env_id in ("FrozenLake-v1", "Taxi-v4"):
        table, streams, lengths = from_gymnasium(env_id), {}, {}
        for algorithm in ("random", "q_learning", "sarsa", "expected_sarsa"):
            config = ExperimentConfig(env=env_id, algorithm=algorithm, episodes=40, seeds=(3, 4), eval_every=20,
                                      schedule="constant", epsilon=0.3)
            features = make_features(config.environment, "grid", config.bins, 1, 1, 0)
            state = initial_state(list(config.seeds), features.n_features, table.n_actions)
            records = allocate_records(2, 40, 2, config.eval_episodes, np.array([40]), state.w.shape[1:])
            train_runs(method_rule(config), kernel_settings(config), make_env(config.environment), features, state,
                       epsilon_schedule(config), 0, 40, records)
            streams[algorithm], lengths[algorithm] = state.rng.copy(), records.lengths.copy()
        for seed_index, seed in enumerate((3, 4)):
            expected = stream_state(seed)
            for _ in range(40):
                reset(table, expected)
            for algorithm, rng in streams.items():
                np.testing.assert_array_equal(rng[seed_index, ENV_STREAM], expected, err_msg=algorithm)
        assert not np.array_equal(lengths["random"], lengths["q_learning"])  # the episodes did differ
        assert not np.array_equal(streams["random"][:, TRANSITION_STREAM], streams["q_learning"][:, TRANSITION_STREAM])


def test_the_adapter_draws_starts_and_slips_from_the_same_streams_as_the_table() -> None:
    """FrozenLake through Gymnasium's own environment (reset and transition generators swapped in) equals
    the table port bit for bit, slips included."""
    from rlcompare.tabular.config import ExperimentConfig

    config = ExperimentConfig(env="FrozenLake-v1", algorithm="sarsa", episodes=60, seeds=(0, 1), eval_every=30,
                              eval_episodes=3, schedule="constant", epsilon=0.3, alpha=0.1)
    port = run(config).records
    adapter = run(ExperimentConfig(**{**config.to_dict(), "adapter": True})).records
    for name in port._fields:
        np.testing.assert_array_equal(getattr(port, name), getattr(adapter, name), err_msg=name)
