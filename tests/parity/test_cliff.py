"""Cliff Walking (Sutton and Barto, Example 6.6): the table equals Gymnasium's, and the book's contrast holds."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from rlcompare import ExperimentConfig, run
from rlcompare.envs.table import from_gymnasium, reset, step
from rlcompare.rng import stream_state
from rlcompare.studies.book.figures import CLIFF, greedy_path


@pytest.mark.slow("steps Gymnasium's Cliff Walking")
def test_table_steps_exactly_as_gymnasium_cliff_walking() -> None:
    table = from_gymnasium("CliffWalking-v1")
    env = gym.make("CliffWalking-v1")
    rng = np.random.default_rng(0)
    ours_rng = stream_state(0)
    falls = goals = 0
    for episode in range(200):
        observation, _ = env.reset(seed=episode)
        state = reset(table, ours_rng)
        assert state == observation == 36
        for _ in range(200):
            action = int(rng.integers(4))
            observation, reward, terminated, _, _ = env.step(action)
            state, our_reward, ends = step(table, state, action, ours_rng)
            assert (state, our_reward, ends) == (observation, reward, terminated)
            falls += reward == -100
            goals += terminated
            if terminated:
                break
    assert falls > 100  # the cliff sends the agent back to the start without ending the episode
    assert goals > 0


@pytest.fixture(scope="module")
def cliff_runs() -> dict[str, object]:
    return {name: run(ExperimentConfig(algorithm=name, seeds=tuple(range(50)), **CLIFF))
            for name in ("sarsa", "q_learning")}


def test_sarsa_collects_more_online_reward_than_q_learning(cliff_runs) -> None:
    sarsa = cliff_runs["sarsa"].records.returns[:, -100:].mean()
    q_learning = cliff_runs["q_learning"].records.returns[:, -100:].mean()
    assert sarsa > q_learning + 10  # about -25 against -50 in Figure 6.4


def test_q_learning_learns_the_optimal_edge_path(cliff_runs) -> None:
    greedy = cliff_runs["q_learning"].records.eval_returns[:, -1, 0]
    assert np.all(greedy == -13)
    path = greedy_path(cliff_runs["q_learning"].records.snapshots[0, -1])
    assert path[:2] == [36, 24]  # up from the start, then along the row next to the cliff
    assert set(path[1:-1]) <= set(range(24, 36))
    assert path[-1] == 47
