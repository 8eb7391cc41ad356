"""Shared fixtures: small configurations that train in well under a second once compiled."""

from __future__ import annotations

import pytest

from rlcompare import ExperimentConfig


@pytest.fixture
def small_config() -> ExperimentConfig:
    """Three seeds, 200 episodes, evaluation every 50 episodes."""
    return ExperimentConfig(algorithm="sarsa", schedule="decay", seeds=(0, 1, 2), episodes=200,
                            eval_every=50, eval_episodes=4)
