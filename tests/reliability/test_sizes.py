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

STUDIES = [("deep", ["--envs", "CartPole-v1", "--methods", "pqn_q_lambda"]),
           ("minatar", ["--games", "breakout", "--methods", "dqn"])]


@pytest.mark.slow("starts rlcompare in processes of their own")
@pytest.mark.parametrize(("study", "where"), STUDIES)
def test_steps_past_memory_name_the_option_given_and_abort_nothing(study: str, where: list[str],
                                                                   tmp_path: Path) -> None:
    """Steps that fit in 64 bits but in no array: what XLA would abort on, so in a process of its own."""
    out = tmp_path / "study"
    result = command_line("reproduce", study, "--steps", "10000000000000", "--seeds", "1", *where, "--out", str(out))
    assert result.returncode == 2, result.stdout + result.stderr
    assert "'--steps'" in result.stderr
    assert "Traceback" not in result.stderr
    assert "terminate called" not in result.stderr
    assert not out.exists()


@pytest.mark.slow("imports the deep studies, JAX with them")
@pytest.mark.parametrize(("study", "where"), STUDIES)
def test_steps_past_64_bits_name_the_option_given(study: str, where: list[str], tmp_path: Path) -> None:
    """Steps no 64-bit integer holds, refused as they are read (before, an OverflowError): in this process, no
    exception escaping (an abort, were one possible before XLA sees a number, is the test above's)."""
    out = tmp_path / "study"
    result = invoke("reproduce", study, "--steps", "99999999999999999999", "--seeds", "1", *where, "--out", str(out),
                    columns=300)
    assert result.exit_code == 2, result.output
    assert isinstance(result.exception, SystemExit)
    assert "'--steps'" in result.output
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


def test_seeds_past_memory_are_refused_by_the_plan_naming_seeds_before_anything_trains(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """chess-endgames with 2,000 seeds was killed by the kernel at 18 GB, its weights never counted; each seed's
    training is small, so the seeds are named, with how many fit (on a machine said to have 4 GiB)."""
    from rlcompare.studies.plans import tabular_training
    from rlcompare.tabular.config import ExperimentConfig
    from rlcompare.tabular.memory import records_bytes, run_bytes, training_bytes

    monkeypatch.setattr(machine, "physical_memory", lambda: 4 * 2**30)
    out = tmp_path / "study"
    result = invoke("reproduce", "chess-endgames", "--allow-undecidable", "--seeds", "2000", "--episodes", "10",
                    "--out", str(out), columns=400)
    assert result.exit_code == 2, result.output
    assert "'--seeds': got 2000; allowed: at most " in result.output
    assert "seeds, whose training fits in memory" in result.output
    assert "Traceback" not in result.output
    assert not out.exists()
    # one seed's weights and second estimates count beside its records: 2 x 48 states x 4 actions x 8 bytes, and
    # its 6 random streams of 4 words
    config = ExperimentConfig(env="CliffWalking-v1", seeds=(0, 1), episodes=10, eval_every=0)
    one = ExperimentConfig(env="CliffWalking-v1", seeds=(0,), episodes=10, eval_every=0)
    assert run_bytes(config) == training_bytes(one) == records_bytes(one) + 2 * 48 * 4 * 8 + 6 * 4 * 8
    monkeypatch.setattr(machine, "physical_memory", lambda: 2**10)
    with pytest.raises(ConfigError, match=r"^bins: got 1; allowed: a run whose records fit"):  # its own count
        tabular_training("x", one)


def test_a_paper_study_of_too_many_seeds_names_seeds_not_bins(tmp_path: Path) -> None:
    result = invoke("reproduce", "--allow-undecidable", "--seeds", "200000", "--plan", "--out",
                    str(tmp_path / "study"), columns=400)
    assert result.exit_code == 2
    assert "'--seeds': got 200000; allowed: at most 89,478 seeds of 400 features x 3 actions" in result.output
    assert "--bins" not in result.output


@pytest.mark.parametrize("algorithm", ["pqn_q_lambda", "ppo", "dqn"])
def test_too_few_steps_name_the_same_least_whatever_was_given(algorithm: str) -> None:
    """``--steps 1`` said the least was one rollout (4,096), and ``--steps 4096`` then asked for ten (one per
    evaluation round): each now names the fewest steps that train in every round, the bound the method's own checks
    imply, found by halving and checked here on both sides."""
    from rlcompare.deep.methods import hyperparameters

    config = DeepConfig(algorithm=algorithm, env="CartPole-v1", seeds=(0,))
    least = config.least_total_steps()
    assert least is not None
    resolved = hyperparameters(algorithm, "CartPole-v1", "default", {"total_steps": least})
    assert resolved.steps_trained(config.eval_rounds) > 0
    if algorithm == "pqn_q_lambda":
        assert least == config.eval_rounds * resolved.n_envs * resolved.n_steps
    messages = set()
    for steps in (1, least - 1):
        with pytest.raises(ConfigError) as caught:
            DeepConfig(algorithm=algorithm, env="CartPole-v1", seeds=(0,), hyperparameters={"total_steps": steps})
        assert caught.value.field_name == "total_steps"
        messages.add(caught.value.allowed.split(" (")[0])
    assert messages == {f"at least {least:,}, the fewest that train in each of the {config.eval_rounds} evaluation "
                        "rounds"}
    DeepConfig(algorithm=algorithm, env="CartPole-v1", seeds=(0,), hyperparameters={"total_steps": least})
