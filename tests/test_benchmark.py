"""The benchmark measures what it says: training steps of the right kernel (no timing is asserted)."""

from __future__ import annotations

from rlcompare import ExperimentConfig, run
from rlcompare.experiment.benchmark import kernel_steps_per_second


def test_kernel_measurement_counts_the_training_steps_of_the_right_kernel() -> None:
    fast = kernel_steps_per_second("sarsa", 1, runs=2, episodes=30, repeats=1)
    same = run(ExperimentConfig(algorithm="sarsa", schedule="constant", epsilon=0.5, seeds=(0, 1), episodes=30,
                                eval_every=0, stages=(("final", 1.0),)))
    assert fast.steps == same.records.lengths.sum()
    assert "fast kernel" in fast.label
    assert fast.seconds > 0
    general = kernel_steps_per_second("n_step_sarsa", 1, runs=2, episodes=10, repeats=1)
    assert "general kernel" in general.label
    assert general.steps_per_second == general.steps / general.seconds
