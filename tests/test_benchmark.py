"""The benchmark measures what it says: the training steps of the configuration it names, and reference kernels
that train as rlcompare does (no timing is asserted)."""

from __future__ import annotations

import numpy as np
import pytest

from rlcompare import ExperimentConfig, run
from rlcompare.bench.tabular import REFERENCES, kernel_and_reference, kernel_steps_per_second
from rlcompare.envs.features import make_features
from rlcompare.tabular.state import initial_state
from rlcompare.tabular.train import epsilon_schedule


def test_kernel_measurement_counts_the_training_steps_of_the_configuration_it_names() -> None:
    measured = kernel_steps_per_second("sarsa", 1, runs=2, episodes=30, repeats=1)
    same = run(ExperimentConfig(algorithm="sarsa", schedule="constant", epsilon=0.5, seeds=(0, 1), episodes=30,
                                eval_every=0, stages=(("final", 1.0),)))
    assert measured.steps == same.records.lengths.sum()
    assert measured.label == "sarsa (grid)"
    assert measured.seconds > 0


def test_port_benchmark_measures_the_gymnasium_loop_the_port_and_the_adapter_on_one_environment() -> None:
    from rlcompare.bench.tabular import gymnasium_steps_per_second

    loop = gymnasium_steps_per_second("CartPole-v1", steps=300)
    assert (loop.label, loop.steps) == ("CartPole-v1, Gymnasium loop", 300)
    port = kernel_steps_per_second("q_learning", 1, env="Taxi-v4", runs=2, episodes=5, repeats=1)
    adapter = kernel_steps_per_second("q_learning", 1, env="Taxi-v4", runs=2, episodes=5, repeats=1, adapter=True)
    assert (port.label, adapter.label) == ("Taxi-v4, compiled port", "Taxi-v4, Gymnasium adapter")
    assert port.steps == adapter.steps  # the same episodes, stepped two ways


@pytest.mark.parametrize("algorithm", sorted(REFERENCES))
def test_each_reference_kernel_trains_as_rlcompare_does_from_the_same_random_streams(algorithm: str) -> None:
    """The plain kernels the benchmark divides by do the same training: drawing from the same streams in the same
    order, they give every episode's return and length and the final table equal to rlcompare's, bit for bit, as
    ε decays from 1 to 0 (any other update, order of draws or time-limit rule would part them within episodes)."""
    config = ExperimentConfig(algorithm=algorithm, seeds=(0, 5), episodes=30, eval_every=0, stages=(("final", 1.0),))
    ours = run(config)
    kernel, extra = REFERENCES[algorithm]
    grid = make_features(config.environment, "grid", config.bins, config.tilings, config.tiles, config.hash_size)
    state = initial_state(list(config.seeds), grid.n_features, config.environment.n_actions)
    returns, lengths = np.zeros((2, config.episodes)), np.zeros((2, config.episodes), np.int64)
    kernel(state.rng, epsilon_schedule(config), grid, state.w, state.w2, config.alpha, config.gamma, config.max_steps,
           returns, lengths, *(getattr(config, name) for name in extra))
    table = (state.w + state.w2) / 2 if algorithm == "double_q_learning" else state.w
    assert np.array_equal(returns, ours.records.returns)
    assert np.array_equal(lengths, ours.records.lengths)
    assert np.array_equal(table, ours.records.snapshots[:, 0])
    assert lengths.sum() > 10_000  # long enough for ties, exploration and the time limit to have happened


def test_kernel_and_reference_are_measured_on_the_same_steps() -> None:
    ours, plain = kernel_and_reference("q_learning", 1, runs=2, episodes=5, repeats=1)
    assert ours.steps == plain.steps > 0
    assert (ours.label, plain.label) == ("q_learning (grid)", "q_learning, reference kernel")
