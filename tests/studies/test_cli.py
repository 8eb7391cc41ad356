"""The command line: what reproduce writes, what run resolves, and one clear message for bad input."""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
from pathlib import Path

import pytest
import typer.main
from helpers import invoke

from rlcompare import ExperimentConfig, cli
from rlcompare.cli.config_options import plain
from rlcompare.experiment import rundir, store
from rlcompare.experiment.engines import load_run
from rlcompare.report import drawn
from rlcompare.tabular.config import field_docs


@pytest.fixture(scope="module")
def reproduced(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """The paper's study of 2 seeds x 100 episodes, made by ``reproduce``: its directory and what it said."""
    out = tmp_path_factory.mktemp("reproduce") / "paper"
    result = invoke("reproduce", "--allow-undecidable", "--seeds", "2", "--episodes", "100", "--no-videos", "--out",
                    str(out))
    assert result.exit_code == 0, result.output
    return out, result.output


@pytest.mark.slow("trains studies through the command line")
def test_reproduce_writes_every_promised_file(reproduced: tuple[Path, str]) -> None:
    out, output = reproduced
    names = ["random", "q_learning-decay", "q_learning-constant", "sarsa-decay", "sarsa-constant",
             "q_learning-decay-before_update", "q_learning-constant-before_update", "sarsa-decay-after_update",
             "sarsa-constant-after_update"]  # the paper's five, then the order ablation
    assert sorted(p.name for p in out.iterdir()) == sorted([*names, "figures", "tables", "report.html",
                                                            drawn.LEDGER, rundir.MEMBERS_FILE, *store.OWN_FILES])
    for name in names:
        assert sorted(p.name for p in (out / name).iterdir()) == sorted(rundir.RUN_FILES + store.OWN_FILES)
        assert name in output
    loaded = load_run(out / "sarsa-constant")
    assert (loaded.config.seeds, loaded.config.episodes, loaded.config.epsilon) == ((0, 1), 100, 0.5)
    assert loaded.meta["study"] == "paper"
    assert "-262" in output  # the paper's Table II beside ours


@pytest.mark.slow("trains studies through the command line")
def test_reproduce_again_loads_instead_of_training(reproduced: tuple[Path, str]) -> None:
    out, _ = reproduced
    result = invoke("reproduce", "--allow-undecidable", "--seeds", "2", "--episodes", "100", "--no-videos", "--out",
                    str(out))
    assert result.exit_code == 0
    assert result.output.count("loaded (already complete)") == 9


def test_run_resolves_every_option(tmp_path: Path) -> None:
    result = invoke("run", "--algorithm", "sarsa", "--schedule", "constant", "--alpha", "0.1", "--gamma", "0.95",
                    "--epsilon", "0.2", "--bins", "12", "--episodes", "30", "--max-steps", "300",
                    "--truncation-as-terminal", "--seeds", "2", "--first-seed", "5", "--eval-every", "10",
                    "--eval-episodes", "3", "--out", str(tmp_path / "run"))
    assert result.exit_code == 0, result.output
    config = load_run(tmp_path / "run").config
    assert (config.algorithm, config.schedule, config.alpha, config.gamma, config.epsilon, config.bins) == (
        "sarsa", "constant", 0.1, 0.95, 0.2, 12)
    assert (config.episodes, config.max_steps, config.truncation_as_terminal) == (30, 300, True)
    assert (config.seeds, config.eval_every, config.eval_episodes) == ((5, 6), 10, 3)


def test_run_help_explains_options() -> None:
    result = invoke("run", "--help")
    assert result.exit_code == 0
    for option in ("--algorithm", "--schedule", "--alpha", "--gamma", "--bins", "--episodes", "--max-steps",
                   "--truncation-as-terminal", "--seeds", "--eval-every", "--out"):
        assert option in result.output
    assert "Algorithm 1" in result.output
    assert "Exploration: constant (ε fixed)" in result.output  # the field's docstring


def test_every_configuration_field_is_an_option_whose_help_is_its_docstring() -> None:
    """One place per fact: ``run`` takes each field as an option named after it, with the field's default and its
    docstring as help, in plain words (then how the command line gives it, where that differs from what the field
    holds)."""
    options = {param.opts[0]: param for param in typer.main.get_command(cli.app).commands["run"].params}
    docs = field_docs()
    assert docs["alpha"] == "Step size α, in (0, 1]."
    assert docs["schedule"] == "Exploration: constant (ε fixed) or decay (linear from epsilon_start to epsilon_end)."
    forms = {"seeds": 30, "bins": None, "bounds": None, "stages": None}
    for field in dataclasses.fields(ExperimentConfig):
        option = options.pop("--stage" if field.name == "stages" else "--" + field.name.replace("_", "-"))
        if field.name == "algorithm":  # the registry's methods, and the options each reads
            assert option.help == cli.ALGORITHM_HELP
        elif field.name in forms:
            assert option.help.startswith(plain(docs[field.name]) + " Given as ")
            assert option.default == forms[field.name]
        else:
            assert (option.help, option.default) == (plain(docs[field.name]), field.default), field.name
    assert sorted(options) == ["--first-seed", "--force", "--out"]


@pytest.mark.parametrize(
    ("args", "option", "allowed"),
    [
        (["run", "--algorithm", "dqn"], "--algorithm", "q_learning"),
        (["run", "--schedule", "cosine"], "--schedule", "constant, decay"),
        (["run", "--alpha", "0"], "--alpha", "(0, 1]"),
        (["run", "--alpha", "1.5"], "--alpha", "(0, 1]"),
        (["run", "--gamma", "2"], "--gamma", "[0, 1]"),
        (["run", "--episodes", "0"], "--episodes", "[1, 2147483647]"),
        (["run", "--episodes", "-3"], "--episodes", "[1, 2147483647]"),
        (["run", "--episodes", "1000000000000"], "--episodes", "[1, 2147483647]"),
        (["run", "--eval-episodes", "100000000000"], "--eval-episodes", "[1, 2147483647]"),
        (["run", "--max-steps", "99999999999999999999"], "--max-steps", "[1, 2147483647]"),
        (["run", "--episodes", "2000000000"], "--episodes", "fit in memory"),
        (["run", "--seeds", "0"], "--seeds", "[1, 1000000]"),
        (["reproduce", "--seeds", "-1"], "--seeds", ">= 1"),
        (["reproduce", "--episodes", "0"], "--episodes", ">= 1"),
        (["reproduce", "--algorithms", "dqn"], "--algorithms", "expected_sarsa"),
        (["reproduce", "mars"], "STUDY", "book-10.2"),
        (["run", "--algorithm", "sarsa_lambda", "--lam", "1.5"], "--lam", "[0, 1]"),
        (["run", "--algorithm", "n_step_sarsa", "--n", "0"], "--n", "[1, 2147483647]"),
        (["run", "--features", "tiles", "--tiles", "0"], "--tiles", "[1, 2147483647]"),
        (["run", "--features", "tiles", "--hash-size", "-1"], "--hash-size", "[0, 2147483647]"),
        (["run", "--features", "coarse"], "--features", "grid, tiles"),
        (["run", "--trace", "dutch"], "--trace", "replacing, accumulating"),
        (["run", "--env", "Pendulum-v1"], "--env", "Discrete actions"),
        (["run", "--env", "CartPole-v1", "--bins", "6,6"], "--bins", "4 of them"),
        (["run", "--bins", "many"], "--bins", "one per observation dimension"),
        (["run", "--bounds", "0:1"], "--bounds", "2 pairs of finite numbers"),
        (["run", "--bounds", "0-1,2-3"], "--bounds", "LOW:HIGH per observation dimension"),
        (["run", "--env", "MountainCar-book", "--adapter"], "--env", "not a registered Gymnasium environment"),
        (["run", "--bins", "10000000"], "--bins", "fit in 4 GiB"),
        (["run", "--alpha", "nan"], "--alpha", "(0, 1]"),
        (["run", "--gamma", "inf"], "--gamma", "[0, 1]"),
        (["run", "--epsilon", "-0.1"], "--epsilon", "[0, 1]"),
        (["run", "--epsilon", "nan"], "--epsilon", "[0, 1]"),
        (["run", "--algorithm", "sarsa_lambda", "--lam", "nan"], "--lam", "[0, 1]"),
        (["run", "--first-seed", "-1"], "--first-seed", "[0, "),
        (["run", "--first-seed", str(2**63 - 1), "--seeds", "2"], "--first-seed", f"[0, {2**63 - 2}]"),
    ],
)
def test_bad_input_gets_one_clear_message_and_exit_code_2(
    args: list[str], option: str, allowed: str, tmp_path: Path
) -> None:
    result = invoke(*args, "--out", str(tmp_path / "out"))
    assert result.exit_code == 2
    assert option in result.output
    assert allowed in result.output
    assert isinstance(result.exception, SystemExit)  # a usage error, not an exception escaping
    assert not (tmp_path / "out").exists()


@pytest.mark.slow("trains studies through the command line")
def test_console_script_reports_bad_input_without_a_traceback(tmp_path: Path) -> None:
    """The installed ``rlcompare`` command, as a user runs it."""
    blocker = tmp_path / "file"
    blocker.write_text("")
    for args, option in ((["run", "--alpha", "2"], "--alpha"), (["run", "--out", str(blocker / "sub")], "--out")):
        completed = subprocess.run([sys.executable, "-m", "rlcompare.cli", *args, "--episodes", "2", "--seeds", "1"],
                                   capture_output=True, text=True, env={**os.environ, "COLUMNS": "200"}, check=False)
        assert completed.returncode == 2
        assert option in completed.stderr
        assert "Traceback" not in completed.stderr + completed.stdout


@pytest.mark.parametrize("command", ["run", "reproduce"])
def test_output_path_that_is_a_file_is_refused(command: str, tmp_path: Path) -> None:
    target = tmp_path / "file"
    target.write_text("keep me")
    result = invoke(command, "--episodes", "5", "--seeds", "1", "--out", str(target))
    assert result.exit_code == 2
    assert "--out" in result.output
    assert "is a file" in result.output
    assert target.read_text() == "keep me"


def test_run_on_an_environment_without_a_port_says_it_runs_at_python_speed(tmp_path: Path) -> None:
    result = invoke("run", "--env", "CliffWalkingSlippery-v1", "--algorithm", "q_learning", "--episodes", "5",
                    "--seeds", "1", "--out", str(tmp_path / "cliff"))
    assert result.exit_code == 0, result.output
    assert "CliffWalkingSlippery-v1 through Gymnasium's API: Python speed" in result.output
    loaded = load_run(tmp_path / "cliff")
    assert loaded.meta["stepped_by"] == "Gymnasium adapter (Python speed)"
    assert (loaded.config.env, loaded.config.max_steps) == ("CliffWalkingSlippery-v1", 1000)


def test_run_resolves_grid_bounds_and_the_adapter(tmp_path: Path) -> None:
    result = invoke("run", "--env", "CartPole-v1", "--adapter", "--bins", "1,1,3,4",
                    "--bounds=-2.4:2.4,-2:2,-0.2:0.2,-3:3", "--episodes", "4", "--seeds", "1",
                    "--out", str(tmp_path / "cartpole"))
    assert result.exit_code == 0, result.output
    config = load_run(tmp_path / "cartpole").config
    assert (config.env, config.adapter, config.bins, config.max_steps) == ("CartPole-v1", True, (1, 1, 3, 4), 500)
    assert config.bounds == ((-2.4, 2.4), (-2.0, 2.0), (-0.2, 0.2), (-3.0, 3.0))
    assert "Python speed" in result.output


def test_reproduce_lists_every_study() -> None:
    result = invoke("reproduce", "--list")
    assert result.exit_code == 0
    for name in ("paper", "cartpole", "acrobot", "book-10.2", "book-12.10", "cliff"):
        assert f"\n{name} " in "\n" + result.output
    assert "CartPole-v1" in result.output
