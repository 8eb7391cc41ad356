"""ExperimentConfig: the paper's defaults, and one clear error per bad value."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rlcompare import ConfigError, ExperimentConfig, machine
from rlcompare.envs.features import make_features
from rlcompare.formatting import quote
from rlcompare.tabular.memory import check_memory, records_bytes
from rlcompare.tabular.state import allocate_records
from rlcompare.tabular.train import epsilon_schedule


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
        ("episodes", 0, "[1, 2147483647]"),
        ("episodes", -5, "[1, 2147483647]"),
        ("episodes", 2.5, "[1, 2147483647]"),
        ("bins", 0, ">= 1"),
        ("max_steps", 0, "[1, 2147483647]"),
        ("eval_every", -1, "[0, 2147483647]"),
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
    ("CliffWalking-v1", 1, 1000), ("FrozenLake8x8-v1", 1, 200), ("CliffWalkingSlippery-v1", 10, 1000),
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


# --- counts a run can hold, and records that fit in memory ---------------------------------------------


@pytest.mark.parametrize(("field", "value"), [
    ("episodes", 1_000_000_000_000), ("episodes", 2**31), ("eval_episodes", 100_000_000_000),
    ("max_steps", 99999999999999999999), ("max_steps", 2**31), ("eval_every", 2**31), ("n", 2**31),
    ("tilings", 2**31), ("tiles", 2**31), ("hash_size", 2**31),
])
def test_a_count_beyond_32_bits_is_refused_naming_the_field(field: str, value: int) -> None:
    with pytest.raises(ConfigError) as caught:
        ExperimentConfig(**{field: value})
    assert caught.value.field_name == field
    assert "2147483647]" in caught.value.allowed


def test_counts_up_to_32_bits_pass_the_count_check() -> None:
    """The bound itself is a count; what stops a run that large is its memory, not the count check."""
    assert ExperimentConfig(max_steps=2**31 - 1, n=2**31 - 1, eval_every=2**31 - 1).max_steps == 2**31 - 1


def test_records_bytes_is_every_array_a_run_allocates() -> None:
    """CliffWalking (48 states, 4 actions), 2 seeds, 100 episodes, 4 evaluations of 3 episodes, 3 stages:
    returns, lengths and terminated 2 x 100 x (8 + 8 + 1) and ε 100 x 8; evaluations 2 x 4 x 3 x 17; snapshots
    2 x 3 x 48 x 4 x 8, visits 2 x 48 x 8 and the snapshots' episodes 3 x 8."""
    config = ExperimentConfig(env="CliffWalking-v1", seeds=(0, 1), episodes=100, eval_every=25, eval_episodes=3)
    assert records_bytes(config) == 3400 + 800 + 408 + 9216 + 768 + 24 == 14616


@settings(max_examples=40, deadline=None)
@given(env=st.sampled_from(["MountainCar-v0", "CartPole-v1", "CliffWalking-v1", "Taxi-v4"]),
       features=st.sampled_from(["grid", "tiles"]), hash_size=st.sampled_from([0, 64]),
       seeds=st.integers(1, 3), episodes=st.integers(1, 300), eval_every=st.integers(0, 60),
       eval_episodes=st.integers(1, 4), stages=st.integers(1, 4))
def test_records_bytes_equals_what_the_kernel_allocates(env: str, features: str, hash_size: int, seeds: int,
                                                        episodes: int, eval_every: int, eval_episodes: int,
                                                        stages: int) -> None:
    config = ExperimentConfig(env=env, features=features, hash_size=hash_size, seeds=tuple(range(seeds)),
                              episodes=episodes, eval_every=eval_every, eval_episodes=eval_episodes,
                              stages=tuple((f"s{k}", (k + 1) / stages) for k in range(stages)))
    coded = make_features(config.environment, config.features, config.bins, config.tilings, config.tiles,
                          config.hash_size, config.bounds)
    stage_episodes = np.array(list(config.stage_episodes().values()), dtype=np.int64)
    records = allocate_records(seeds, episodes, config.evaluation_rounds, eval_episodes, stage_episodes,
                               (coded.n_features, config.environment.n_actions))
    allocated = sum(array.nbytes for array in records) + epsilon_schedule(config).nbytes
    assert records_bytes(config) == allocated


def test_records_larger_than_memory_are_refused_with_the_figures(monkeypatch: pytest.MonkeyPatch) -> None:
    """3 seeds x 20,000,000 episodes: 1,180,096,024 bytes, 1.1 GiB, on a machine said to have 1 GiB."""
    monkeypatch.setattr(machine, "physical_memory", lambda: 2**30)
    config = ExperimentConfig(seeds=(0, 1, 2), episodes=20_000_000, eval_every=0)  # validation reads no machine
    with pytest.raises(ConfigError) as caught:
        check_memory(config)
    assert caught.value.field_name == "episodes"
    assert caught.value.allowed == ("a run whose records fit in memory: 3 seeds x 20,000,000 episodes need 1.1 GiB; "
                                    "this machine has 1.0 GiB")
    check_memory(ExperimentConfig(seeds=(0,), episodes=20_000_000, eval_every=0))


def test_a_run_too_large_for_this_machine_still_loads_and_is_refused_only_when_it_starts(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A configuration made on a bigger machine round-trips here; training it is refused before anything is
    allocated or written."""
    from rlcompare.experiment.runner import run

    monkeypatch.setattr(machine, "physical_memory", lambda: 2**20)
    config = ExperimentConfig(seeds=tuple(range(8)), episodes=20_000, eval_every=0)
    assert ExperimentConfig.from_dict(config.to_dict()) == config
    with pytest.raises(ConfigError, match="fit in memory"):
        run(config, out=tmp_path / "run")
    assert not (tmp_path / "run").exists()


def test_evaluations_larger_than_this_machines_memory_are_refused() -> None:
    """2**31 - 1 evaluations of 2**31 - 1 episodes: no machine holds their records."""
    memory = machine.physical_memory()
    with pytest.raises(ConfigError) as caught:
        check_memory(ExperimentConfig(seeds=(0,), episodes=2**31 - 1, eval_every=1,
                                                    eval_episodes=2**31 - 1))
    assert caught.value.field_name == "eval_episodes"
    assert caught.value.allowed.startswith("a run whose records fit in memory: 1 seeds x 2,147,483,647 evaluations "
                                           "x 2,147,483,647 episodes need ")
    assert f"GiB; this machine has {memory / 2**30:,.{1 if memory < 10 * 2**30 else 0}f} GiB" in caught.value.allowed


def test_physical_memory_falls_back_where_the_machine_does_not_say(monkeypatch: pytest.MonkeyPatch) -> None:
    def unsupported(name: str) -> int:
        raise ValueError(name)

    monkeypatch.setattr(machine.os, "sysconf", unsupported)
    assert machine.physical_memory() == 16 * 2**30


# --- numbers: one value, one configuration ----------------------------------------------------------------


def test_an_integer_rate_is_stored_as_a_float() -> None:
    config = ExperimentConfig(alpha=1, gamma=0, epsilon_end=0, target_epsilon=1)
    assert (config.alpha, config.gamma, config.epsilon_end, config.target_epsilon) == (1.0, 0.0, 0.0, 1.0)
    assert all(type(v) is float for v in (config.alpha, config.gamma, config.epsilon_end, config.target_epsilon))
    assert config.to_dict() == ExperimentConfig(alpha=1.0, gamma=0.0, epsilon_end=0.0, target_epsilon=1.0).to_dict()
    assert ExperimentConfig().target_epsilon is None


@pytest.mark.parametrize("value", [True, False, "1", None, [1], 2, 10**400])
def test_a_rate_that_is_not_a_number_in_range_is_still_an_error_quoting_it(value: object) -> None:
    with pytest.raises(ConfigError) as caught:
        ExperimentConfig(alpha=value)
    assert caught.value.field_name == "alpha"
    assert caught.value.value is value
    assert str(caught.value).startswith(f"alpha: got {quote(value)}; allowed: a number in (0, 1]")


# --- what an error quotes -------------------------------------------------------------------------------------


@pytest.mark.slow("compiles or trains for a second or more")
def test_an_error_on_a_huge_value_is_one_short_line() -> None:
    huge = "x" * 10_000_000
    with pytest.raises(ConfigError) as caught:
        ExperimentConfig(env=huge)
    message = str(caught.value)
    assert len(message) < 700  # the environments allowed, and why this one is not: the start of it
    assert caught.value.value is huge
    assert "… (10,000,002 characters)" in message
    with pytest.raises(ConfigError) as caught:
        ExperimentConfig(alpha=huge)
    assert len(str(caught.value)) < 200


def test_quote_keeps_a_short_value_whole_and_cuts_a_long_one() -> None:
    assert quote("abc") == "'abc'"
    assert quote((1, 2)) == "(1, 2)"
    assert quote("x" * 78) == repr("x" * 78)
    assert quote("x" * 79) == repr("x" * 79)[:80] + "… (81 characters)"
    assert quote(10**5000) == "<an integer of 16,610 bits>"


@settings(max_examples=200, deadline=None)
@given(st.one_of(st.text(max_size=400), st.lists(st.integers(), max_size=60), st.floats()), st.integers(1, 200))
def test_quote_is_the_start_of_the_repr_and_at_most_the_limit(value: object, limit: int) -> None:
    quoted, whole = quote(value, limit), repr(value)
    if len(whole) <= limit:
        assert quoted == whole
    else:
        assert quoted == f"{whole[:limit]}… ({len(whole):,} characters)"
