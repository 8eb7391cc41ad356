"""Sizes XLA cannot represent end in a refusal naming the option, never in an abort (issue 39): the records'
arithmetic is checked when a configuration is made, every array of the traced program before it compiles."""

from __future__ import annotations

from pathlib import Path

import pytest
from helpers import command_line, invoke

from rlcompare import machine
from rlcompare.deep import train
from rlcompare.deep.config import DeepConfig
from rlcompare.experiment.sweep import SweepError, parse_sweep
from rlcompare.validation import ConfigError


@pytest.mark.slow("starts rlcompare in processes of their own")
@pytest.mark.parametrize(("study", "where"), [("deep", ["--envs", "CartPole-v1", "--methods", "pqn_q_lambda"]),
                                               ("minatar", ["--games", "breakout", "--methods", "dqn"])])
@pytest.mark.parametrize("steps", ["99999999999999999999", "10000000000000"])
def test_steps_past_memory_name_the_option_given_and_abort_nothing(study: str, where: list[str], steps: str,
                                                                   tmp_path: Path) -> None:
    out = tmp_path / "study"
    result = command_line("reproduce", study, "--steps", steps, "--seeds", "1", *where, "--out", str(out))
    assert result.returncode == 2, result.stdout + result.stderr
    assert "'--steps'" in result.stderr
    assert "Traceback" not in result.stderr
    assert "terminate called" not in result.stderr
    assert not out.exists()


def test_a_sweep_file_with_steps_past_memory_names_the_key() -> None:
    text = """
[sweep]
name = "huge"
engine = "deep"
seeds = 1
[fixed]
env = "CartPole-v1"
hyperparameters.total_steps = 9223372036854775807
[grid]
algorithm = ["pqn_q_lambda"]
"""
    with pytest.raises(SweepError) as refused:
        parse_sweep(text)
    assert [p.split(";")[0] for p in refused.value.problems] == [
        "fixed.hyperparameters.total_steps: got 9223372036854775807"]


@pytest.mark.slow("traces a training")
def test_an_array_past_memory_is_refused_after_tracing_and_before_compiling(monkeypatch: pytest.MonkeyPatch
                                                                           ) -> None:
    config = DeepConfig(algorithm="dqn", env="CartPole-v1", seeds=(0,), vmap_width=1,
                        hyperparameters={"total_steps": 2048, "buffer_size": 2**30, "learning_starts": 64})
    monkeypatch.setattr(machine, "physical_memory", lambda: 2**30)  # the replay buffer alone is 16 GiB
    compiled_before = train.compiled_program.cache_info().misses
    with pytest.raises(ConfigError, match=r"^vmap_width: got 1; allowed: a training that fits in memory"):
        train.check_sizes(config)
    assert train.compiled_program.cache_info().misses == compiled_before


@pytest.mark.parametrize("command", [["run"], ["reproduce"], ["reproduce", "chess-endgames"], ["reproduce", "chess"],
                                     ["reproduce", "atari"], ["reproduce", "minatar"], ["reproduce", "sensitivity"]])
@pytest.mark.parametrize("seeds", ["99999999999999999999", "20000000"])
def test_a_count_of_seeds_past_any_design_is_refused_as_it_is_read(command: list[str], seeds: str,
                                                                   tmp_path: Path) -> None:
    """Once an OverflowError traceback (20 digits), or minutes of checking seeds one at a time (20 million)."""
    out = tmp_path / "out"
    result = invoke(*command, "--seeds", seeds, "--out", str(out), columns=300)
    assert result.exit_code == 2, result.output
    assert "'--seeds'" in result.output
    assert "[1, 1000000]" in result.output
    assert not out.exists()


def test_seeds_that_would_pass_two_to_the_63_name_the_first_seed(tmp_path: Path) -> None:
    result = invoke("run", "--seeds", "3", "--first-seed", str(2**63 - 1), "--out", str(tmp_path / "out"),
                    columns=300)
    assert result.exit_code == 2
    assert "'--first-seed'" in result.output
