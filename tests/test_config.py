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
