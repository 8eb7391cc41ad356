"""Shared fixtures: small configurations that train in well under a second once compiled."""

from __future__ import annotations

import pytest

from rlcompare import ExperimentConfig

LONGEST_FIRST = ("test_algorithms_beyond_paper.py", "test_adapter.py", "test_sweep_deep.py", "test_deep_study.py",
                 "test_ownership.py", "test_deep_pqn.py", "test_ray.py", "test_cli.py", "test_agent_input.py",
                 "test_deep_dqn.py", "test_deep_ppo.py", "test_classic_control.py", "test_video.py",
                 "test_browser.py", "test_env_studies.py")
"""The files that take longest (``--durations``, cold caches), slowest first. ``scripts/test`` hands whole
files to its workers in collection order, so starting these first lets the workers end together; the order
changes no result."""


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """The files of :data:`LONGEST_FIRST` first, each file's tests in their own order."""
    rank = {name: i for i, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))


@pytest.fixture
def small_config() -> ExperimentConfig:
    """Three seeds, 200 episodes, evaluation every 50 episodes."""
    return ExperimentConfig(algorithm="sarsa", schedule="decay", seeds=(0, 1, 2), episodes=200,
                            eval_every=50, eval_episodes=4)
