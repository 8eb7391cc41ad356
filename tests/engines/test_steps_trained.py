"""What a deep training runs, known before it runs: each method's ``steps_trained`` against the steps its traced
program records (whole batches in every evaluation round), and Atari 100k's budget as it trains."""

from __future__ import annotations

import dataclasses
import math

import pytest

jax = pytest.importorskip("jax")

from rlcompare.deep import float64, pqn  # noqa: E402
from rlcompare.deep.config import DeepConfig  # noqa: E402
from rlcompare.deep.methods import deep_method  # noqa: E402


@pytest.mark.parametrize(("method", "settings", "rounds"), [
    ("pqn_q_lambda", {"total_steps": 10_000, "n_envs": 4, "n_steps": 16, "n_minibatches": 4}, 3),
    ("dqn", {"total_steps": 1_001, "learning_starts": 10, "train_freq": 4}, 4),
    ("munchausen_dqn", {"total_steps": 999, "n_envs": 2, "learning_starts": 10, "train_freq": 3}, 2),
    ("ppo", {"total_steps": 5_000, "n_envs": 2, "n_steps": 64, "batch_size": 32}, 7),
])
def test_steps_trained_are_the_steps_the_traced_program_records(method: str, settings: dict, rounds: int) -> None:
    config = DeepConfig(algorithm=method, env="CartPole-v1", seeds=(0,), eval_rounds=rounds, eval_episodes=1,
                        hyperparameters=settings)
    train = deep_method(method).module.make_train(config.method_config(), config.environment, rounds, 1)
    done = float64(jax.eval_shape)(train, jax.random.key(0)).finished.done  # (rounds, updates, steps a round, envs)
    assert math.prod(done.shape) == config.steps_trained
    assert config.steps_trained != settings["total_steps"]


def test_atari_100k_trains_81920_steps_in_ten_rounds() -> None:
    """PQN's Atari preset: 128 environments x 32 steps a rollout; 100,000 steps hold 24 rollouts, 2 in each of 10
    rounds run: 20 x 4,096."""
    preset = dataclasses.replace(pqn.PRESETS["default"]["Breakout-Atari"], total_steps=100_000)
    assert preset.steps_trained(10) == 81_920


def test_a_studys_start_names_the_steps_that_train_and_the_number_given_where_they_differ() -> None:
    """``reproduce atari --steps 40960`` said "40,960 steps" at its start and trained 32,768."""
    from rlcompare.studies.paired_plan import Plan

    plan = Plan(seeds=(0,), methods=("pqn_q_lambda", "ppo"), envs={"CartPole-v1": "CartPole-v1"}, steps=45_000,
                workers=1)
    trained = sorted({c.steps_trained for c in plan.configs().values()})
    assert trained == [40_960]  # PQN's 4,096-step rollouts and PPO's 2,048, ten rounds each: whole batches
    assert plan.steps_text() == "40,960 steps (45,000 given; whole batches)"
    exact = dataclasses.replace(plan, steps=40_960, methods=("pqn_q_lambda",))
    assert exact.steps_text() == "40,960 steps"
