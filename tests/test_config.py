"""ExperimentConfig: the paper's defaults, and one clear error per bad value."""

from __future__ import annotations

import dataclasses

import pytest

from rlcompare import ConfigError, ExperimentConfig


def test_defaults_are_the_papers_setting() -> None:
    config = ExperimentConfig()
    assert (config.env, config.bins, config.alpha, config.gamma, config.max_steps) == (
        "MountainCar-v0", 20, 0.05, 0.9, 1000)
    assert config.epsilon == 0.5
    assert config.epsilon_start == 1.0
    assert len(config.seeds) == 30
    assert not config.truncation_as_terminal


def test_config_is_frozen() -> None:
    with pytest.raises(dataclasses.FrozenInstanceError):
        ExperimentConfig().alpha = 0.1  # type: ignore[misc]


@pytest.mark.parametrize(
    ("field", "value", "allowed"),
    [
        ("algorithm", "dqn", "q_learning"),
        ("schedule", "cosine", "constant, decay"),
        ("env", "Pong-v5", "MountainCar-v0"),
        ("env", "", "MountainCar-v0"),
        ("adapter", "yes", "true or false"),
        ("bins", (20, 20, 20), "2 of them"),
        ("bins", (20, 0), ">= 1"),
        ("bounds", ((0.0, 1.0),), "2 pairs of finite numbers"),
        ("bounds", ((1.0, 0.0), (0.0, 1.0)), "low < high"),
        ("bounds", "wide", "pairs of numbers"),
        ("alpha", 0.0, "(0, 1]"),
        ("alpha", 1.5, "(0, 1]"),
        ("alpha", float("nan"), "(0, 1]"),
        ("gamma", -0.1, "[0, 1]"),
        ("gamma", 1.01, "[0, 1]"),
        ("epsilon", 2.0, "[0, 1]"),
        ("decay_fraction", 0.0, "(0, 1]"),
        ("episodes", 0, ">= 1"),
        ("episodes", -5, ">= 1"),
        ("episodes", 2.5, ">= 1"),
        ("bins", 0, ">= 1"),
        ("max_steps", 0, ">= 1"),
        ("eval_every", -1, ">= 0"),
        ("seeds", (), "at least one seed"),
        ("seeds", (1, 1), "distinct"),
        ("seeds", (-1,), "[0, 2**63)"),
        ("seeds", (2**63,), "[0, 2**63)"),
        ("seeds", ("a",), "integers"),
        ("stages", (("early", 1.5),), "(0, 1]"),
    ],
)
def test_bad_value_names_the_field_and_what_is_allowed(field: str, value: object, allowed: str) -> None:
    with pytest.raises(ConfigError) as caught:
        ExperimentConfig(**{field: value})
    assert caught.value.field_name == field
    assert allowed in caught.value.allowed
    assert str(caught.value).startswith(f"{field}:")


def test_round_trip_through_dict() -> None:
    config = ExperimentConfig(algorithm="sarsa", schedule="constant", seeds=(3, 4), episodes=10)
    assert ExperimentConfig.from_dict(config.to_dict() | {"seeds": (3, 4), "stages": config.stages}) == config


def test_unknown_key_is_rejected_by_name() -> None:
    with pytest.raises(ConfigError) as caught:
        ExperimentConfig.from_dict({"algorithm": "sarsa", "lerning_rate": 0.1})
    assert caught.value.field_name == "lerning_rate"
    assert "alpha" in caught.value.allowed


def test_stage_episodes_are_shares_of_training() -> None:
    config = ExperimentConfig(episodes=5000)
    assert config.stage_episodes() == {"early": 500, "middle": 2500, "final": 5000}
    assert ExperimentConfig(episodes=3, stages=(("first", 0.01),)).stage_episodes() == {"first": 1}


def test_names_of_configurations() -> None:
    assert ExperimentConfig(algorithm="q_learning", schedule="constant").name == "q_learning-constant"
    assert ExperimentConfig(algorithm="random", schedule="decay").name == "random"


@pytest.mark.parametrize(("env", "bins", "max_steps"), [
    ("MountainCar-v0", 20, 1000), ("MountainCar-book", 20, 1000), ("CartPole-v1", (1, 1, 6, 12), 500),
    ("Acrobot-v1", (4, 4, 4, 4, 8, 8), 500), ("FrozenLake-v1", 1, 100), ("Taxi-v4", 1, 200),
    ("CliffWalking-v1", 1, 1000), ("FrozenLake8x8-v1", 10, 200),
])
def test_each_environment_fills_in_its_own_grid_and_limit(env: str, bins, max_steps: int) -> None:
    """None means the environment's default, written into the configuration so that config.json says what ran;
    a value given wins."""
    config = ExperimentConfig(env=env)
    assert (config.bins, config.max_steps) == (bins, max_steps)
    assert ExperimentConfig.from_dict(config.to_dict()) == config
    assert ExperimentConfig(env=env, max_steps=77).max_steps == 77


def test_grid_too_large_for_memory_is_refused_with_its_size() -> None:
    with pytest.raises(ConfigError, match="64,000,000 features") as caught:
        ExperimentConfig(env="Acrobot-v1", bins=20)
    assert caught.value.field_name == "bins"
    assert ExperimentConfig(env="Acrobot-v1", bins=20, seeds=(0,), stages=(("final", 1.0),), features="tiles")


def test_bins_and_bounds_round_trip_as_tuples() -> None:
    config = ExperimentConfig(env="CartPole-v1", bins=[1, 1, 6, 12],
                              bounds=[[-2.4, 2.4], [-3, 3], [-0.2, 0.2], [-3, 3]])
    assert config.bins == (1, 1, 6, 12)
    assert config.bounds == ((-2.4, 2.4), (-3.0, 3.0), (-0.2, 0.2), (-3.0, 3.0))
    assert ExperimentConfig.from_dict(config.to_dict()) == config
