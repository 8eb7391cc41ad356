"""One registry of methods: the configuration, the engine's rules, the benchmark and the command line all
read it."""

from __future__ import annotations

from pathlib import Path

import pytest
from helpers import invoke

from rlcompare import ConfigError, ExperimentConfig
from rlcompare.algorithms.registry import BEFORE_UPDATE, FAMILIES, METHODS, label
from rlcompare.algorithms.registry import rule_for as method_rule
from rlcompare.bench.kernels import MULTI_STEP, ONE_STEP
from rlcompare.cli import app
from rlcompare.tabular.config import ALGORITHMS, NEXT_ACTION_DEFAULTS
from rlcompare.tabular.loops import LOOPS


def test_the_configuration_accepts_exactly_the_registered_methods():
    assert tuple(METHODS) == ALGORITHMS
    with pytest.raises(ConfigError) as error:
        ExperimentConfig(algorithm="td_zero")
    assert all(name in error.value.allowed for name in METHODS)


@pytest.mark.parametrize("name", list(METHODS))
def test_each_method_gets_the_rule_its_entry_says(name):
    m = METHODS[name]
    rule = method_rule(ExperimentConfig(algorithm=name))
    assert type(rule) is m.rule
    assert m.family in FAMILIES
    assert m.rule in LOOPS
    if m.family == "policy gradient":
        assert rule.discount_gradient == m.discount_gradient
        assert (rule.baseline_alpha > 0) == m.baseline
    if m.one_step:
        assert rule.draw_before == (m.next_action == BEFORE_UPDATE)
        assert m.update is not None
    assert NEXT_ACTION_DEFAULTS.get(name) == m.next_action
    assert label(name) == m.label


def test_a_configured_order_overrides_the_box():
    moved = method_rule(ExperimentConfig(algorithm="q_learning", next_action="before_update"))
    assert moved.draw_before
    assert not method_rule(ExperimentConfig(algorithm="q_learning")).draw_before


def test_the_benchmark_measures_every_learner_once():
    assert sorted((*ONE_STEP, *MULTI_STEP)) == sorted(n for n, m in METHODS.items()
                                                                     if m.family != "baseline")


def test_the_command_line_lists_every_method_with_its_source():
    result = invoke("run", "--help", columns=400)
    assert result.exit_code == 0
    text = " ".join(result.output.split())
    for name, m in METHODS.items():
        assert name in text
        assert m.book.split(",")[0] in text


def test_every_study_listed_is_one_the_command_can_run():
    import typer.main

    from rlcompare.studies.registry import STUDIES

    listed = invoke("reproduce", "--list", columns=400).output.splitlines()
    assert [line.split()[0] for line in listed] == list(STUDIES)
    commands = typer.main.get_command(app).commands["reproduce"].commands
    assert list(commands) == list(STUDIES)
    for name, study in STUDIES.items():
        runner = study.load_runner()
        assert callable(runner.run), name
        assert callable(runner.report), name


def test_what_figures_videos_and_the_benchmark_say_of_an_environment_is_its_entrys():
    from rlcompare.bench.ports import PORT_EPISODES
    from rlcompare.envs.registry import PORTS, TABLE_ENVIRONMENTS, environment

    assert set(PORT_EPISODES) == {*PORTS, *TABLE_ENVIRONMENTS} - {"MountainCar-book"}
    assert all(PORT_EPISODES[name] == environment(name).bench_episodes for name in PORT_EPISODES)
    assert environment("CartPole-v1").endings == ("the pole fell", "balanced to the end")
    assert environment("MountainCar-book").action_names == environment("MountainCar-v0").action_names
    assert environment("MountainCar-book").gymnasium_id == "MountainCar-v0"  # the book's trajectories are the same
    assert environment("MountainCar-v0").gymnasium_id == "MountainCar-v0"
    assert environment("MountainCar-v0").start_box == ((-0.6, -0.4), (0.0, 0.0))  # Gymnasium's reset range
    assert environment("CartPole-v1").start_box is None  # no maps, so no start region to draw

    assert environment("Taxi-v4").map_axes is None


def test_the_help_names_the_options_each_method_reads():
    output = invoke("run", "--help", columns=400).output
    text = " ".join(output.replace("│", " ").split())  # the help's lines joined, without the panel's borders
    assert "n_step_sarsa (Sutton and Barto 7.2; reads --n)" in text
    assert "reinforce_baseline (Sutton and Barto 13.4; reads --baseline-alpha)" in text


def test_the_readme_lists_every_study_in_the_registrys_order():
    from rlcompare.studies.registry import STUDIES

    readme = (Path(__file__).parents[2] / "README.md").read_text()
    line = next(line for line in readme.splitlines() if line.startswith("rlcompare reproduce --list"))
    assert line.split("#")[1].split() == list(STUDIES)


@pytest.mark.parametrize("package", ["stats", "report"])
def test_statistics_and_pictures_name_no_environment(package):
    """What figures, tables and videos say of an environment comes from its registry entry."""
    for path in (Path(__file__).parents[2] / "src" / "rlcompare" / package).glob("*.py"):
        code = "\n".join(line for line in path.read_text().splitlines() if not line.lstrip().startswith("#"))
        for name in ("MountainCar", "CartPole", "Acrobot", "CliffWalking", "mountain_car", "cartpole"):
            assert f'"{name}' not in code, (path.name, name)
            assert f"envs import {name}" not in code, (path.name, name)
