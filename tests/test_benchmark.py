"""The benchmark measures what it says: the training steps of the configuration it names (no timing is
asserted)."""

from __future__ import annotations

from rlcompare import ExperimentConfig, run
from rlcompare.experiment.benchmark import kernel_steps_per_second


def test_kernel_measurement_counts_the_training_steps_of_the_configuration_it_names() -> None:
    measured = kernel_steps_per_second("sarsa", 1, runs=2, episodes=30, repeats=1)
    same = run(ExperimentConfig(algorithm="sarsa", schedule="constant", epsilon=0.5, seeds=(0, 1), episodes=30,
                                eval_every=0, stages=(("final", 1.0),)))
    assert measured.steps == same.records.lengths.sum()
    assert measured.label == "sarsa (grid)"
    assert measured.seconds > 0


def test_port_benchmark_measures_the_gymnasium_loop_the_port_and_the_adapter_on_one_environment() -> None:
    from rlcompare.experiment.benchmark import gymnasium_steps_per_second

    loop = gymnasium_steps_per_second("CartPole-v1", steps=300)
    assert (loop.label, loop.steps) == ("CartPole-v1, Gymnasium loop", 300)
    port = kernel_steps_per_second("q_learning", 1, env="Taxi-v4", runs=2, episodes=5, repeats=1)
    adapter = kernel_steps_per_second("q_learning", 1, env="Taxi-v4", runs=2, episodes=5, repeats=1, adapter=True)
    assert (port.label, adapter.label) == ("Taxi-v4, compiled port", "Taxi-v4, Gymnasium adapter")
    assert port.steps == adapter.steps  # the same episodes, stepped two ways
