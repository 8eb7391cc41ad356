"""A deep training that does not fit in memory is refused after compiling, before its first step, naming what
to change; the compiled program's own accounting counts replay buffers and records."""

from __future__ import annotations

import pytest

pytest.importorskip("jax")

from rlcompare import machine
from rlcompare.deep import use_compilation_cache
from rlcompare.deep.config import DeepConfig
from rlcompare.deep.train import compiled_training, memory_needed
from rlcompare.experiment import rundir
from rlcompare.experiment.runner import run
from rlcompare.validation import ConfigError

pytestmark = pytest.mark.slow("compiles deep programs")

OBSERVATION_BYTES = 10 * 10 * 4  # Breakout's four boolean channels


def test_a_replay_buffer_counts_while_training_and_longer_training_in_the_records() -> None:
    """DQN on CartPole with its preset's buffer of 100,000 transitions (``tests/engines/test_golden_deep.py``'s
    configuration, so JAX's compilation cache holds its program where that file ran) against one of 1,000."""
    use_compilation_cache()
    large = DeepConfig(algorithm="dqn", env="CartPole-v1", seeds=(0, 3), vmap_width=2, eval_rounds=2,
                       eval_episodes=2, hyperparameters={"total_steps": 2048, "learning_starts": 512})
    small = DeepConfig(**{**large.__dict__, "hyperparameters": {**large.hyperparameters, "buffer_size": 1_000}})
    assert large.method_config().buffer_size == 100_000
    small_training, small_records = memory_needed(small, compiled_training(small))
    large_training, large_records = memory_needed(large, compiled_training(large))
    cartpole_observation = 4 * 4  # four float32
    assert large_training - small_training >= 2 * 99_000 * 2 * cartpole_observation  # two seeds' buffers, side by side
    assert large_records == small_records > 0  # the records grow with steps, not with the buffer


def test_a_training_too_large_for_the_machine_is_refused_before_it_runs(monkeypatch, tmp_path) -> None:
    config = DeepConfig(algorithm="pqn_q_lambda", env="CartPole-v1", seeds=(0,), vmap_width=1, eval_rounds=1,
                        eval_episodes=1, hyperparameters={"total_steps": 2_048, "n_envs": 8, "n_steps": 16})
    monkeypatch.setattr(machine, "physical_memory", lambda: 100_000)
    with pytest.raises(ConfigError, match=r"(vmap_width: got 1|total_steps: got 2048); allowed: a training that "
                                          r"fits in memory: "
                                          r"pqn_q_lambda-CartPole-v1 on 1 seeds.*this machine has 0.0 GiB"):
        run(config, out=tmp_path / "run")
    assert not (tmp_path / "run" / rundir.PARAMS_FILE).exists()


def test_the_plan_counts_records_and_replay_buffers_before_anything_compiles() -> None:
    """Records: 2 copies x 10 bytes a step x 3 seeds x the steps trained; a replay buffer (two seeds side by side):
    per transition two observations of Breakout's 400 boolean cells, an int32 action, a float32 reward and a bool
    ending, 809 bytes; PQN keeps none."""
    small = DeepConfig(algorithm="dqn", env="MinAtar/Breakout-v0", seeds=(0, 1, 2), vmap_width=2, eval_rounds=2,
                       eval_episodes=1, hyperparameters={"total_steps": 2_000, "buffer_size": 1_000,
                                                         "learning_starts": 100})
    large = DeepConfig(**{**small.__dict__, "hyperparameters": {**small.hyperparameters, "buffer_size": 50_000}})
    records = 2 * 10 * 3 * small.steps_trained
    assert small.memory_before_running() == records + 2 * 1_000 * (2 * OBSERVATION_BYTES + 9)
    assert large.memory_before_running() - small.memory_before_running() == 2 * 49_000 * 809
    pqn = DeepConfig(algorithm="pqn_q_lambda", env="MinAtar/Breakout-v0", seeds=(0, 1, 2), eval_rounds=2,
                     eval_episodes=1)
    assert pqn.memory_before_running() == 2 * 10 * 3 * pqn.steps_trained
