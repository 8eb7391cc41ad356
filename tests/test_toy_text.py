"""Gymnasium's toy-text environments stepped from their own tables: FrozenLake-v1 and Taxi-v4."""

from __future__ import annotations

import gymnasium as gym
import numpy as np

from rlcompare import ExperimentConfig, run
from rlcompare.envs.table import from_gymnasium, reset, step
from rlcompare.rng import stream_state


def test_taxi_resets_and_steps_as_gymnasium() -> None:
    """Taxi is deterministic; its start state is drawn as Gymnasium draws it (``cumsum > random()``), so
    the first reset of stream ``PCG64(s)`` equals ``env.reset(seed=s)``."""
    table = from_gymnasium("Taxi-v4")
    env = gym.make("Taxi-v4")
    rng = np.random.default_rng(1)
    for seed in range(20):
        observation, _ = env.reset(seed=seed)
        ours_rng = stream_state(seed)
        state = reset(table, ours_rng)
        assert state == observation
        for _ in range(100):
            action = int(rng.integers(6))
            observation, reward, terminated, _, _ = env.step(action)
            state, our_reward, ends = step(table, state, action, ours_rng)
            assert (state, our_reward, ends) == (observation, reward, terminated)
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
    success = run(config).records.eval_returns[:, -1].mean()
    assert success > 0.6  # the optimal policy of the slippery 4x4 lake reaches the goal about 74% of the time
