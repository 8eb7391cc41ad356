"""A sweep file's values checked before anything runs: its name a directory name, no configuration twice, at
least one configuration, counts within what a run can hold, and errors that quote a bounded part of a value."""

from __future__ import annotations

from pathlib import Path

import pytest
import tomli_w
from helpers import invoke
from hypothesis import given, settings
from hypothesis import strategies as st

from rlcompare.experiment.sweep import SweepError, config_hash, is_sweep_name, parse_sweep
from rlcompare.formatting import quote
from rlcompare.tabular.config import ExperimentConfig

NAME_ALLOWED = ("allowed: a single directory name of letters, digits, '.', '_' and '-' (at most 100 characters, "
                "not starting with '.')")
EMPTY = "grid: empty; allowed: at least one [grid] list or one [[include]] table"


def _problems(text: str) -> list[str]:
    with pytest.raises(SweepError) as caught:
        parse_sweep(text)
    return caught.value.problems


def _named(name: object) -> str:
    return tomli_w.dumps({"sweep": {"name": name}, "grid": {"alpha": [0.1]}})


# --- the name: one directory, never a path -------------------------------------------------------------


@pytest.mark.parametrize("name", ["/tmp/x", "../x", "a/b", "a\\b", ".", "..", ".hidden", "", "x" * 101, "x" * 300,
                                  "a b", "né", "x\n", "C:x"])
def test_a_name_that_is_not_one_directory_name_is_refused(name: str) -> None:
    assert _problems(_named(name)) == [f"sweep.name: got {quote(name)}; {NAME_ALLOWED}"]


@pytest.mark.parametrize("name", [5, True, ["a"]])
def test_a_name_that_is_not_a_string_is_refused(name: object) -> None:
    assert _problems(_named(name)) == [f"sweep.name: got {name!r}; {NAME_ALLOWED}"]


@pytest.mark.parametrize("name", ["alpha", "a.b-c_d", "x" * 100, "2024-01-01", "-x", "_", "Sweep.v2"])
def test_a_directory_name_is_accepted(name: str) -> None:
    assert parse_sweep(_named(name)).name == name


@settings(max_examples=300, deadline=None)
@given(st.text(max_size=120))
def test_an_accepted_name_is_one_directory_inside_the_default_store(name: str) -> None:
    """Whatever the text, an accepted name stays one directory below runs/sweeps: never absolute, never up."""
    root = Path("/srv/runs/sweeps")
    if is_sweep_name(name):
        assert (root / name).parent == root
        assert (root / name).resolve().parent == root.resolve()
        assert name not in (".", "..")
        assert "/" not in name
        assert "\\" not in name
        assert len(name) <= 100
    else:
        assert _problems(_named(name))[0].startswith("sweep.name: got ")


def test_a_name_that_escapes_never_reaches_the_file_system(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """With no --out the store would be runs/sweeps/NAME: a name with '..' is refused before anything is made."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "bad.toml").write_text(_named("../../escaped"))
    result = invoke("sweep", "bad.toml")
    assert result.exit_code == 2
    assert "sweep.name: got '../../escaped'" in result.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.toml"]


# --- each configuration once ---------------------------------------------------------------------------


@pytest.mark.parametrize(("text", "problem"), [
    ("[grid]\nalpha = [0.1, 0.1]\n", "grid.alpha[1]: the same configuration as grid.alpha[0]"),
    ("[grid]\nalpha = [1, 1.0]\n", "grid.alpha[1]: the same configuration as grid.alpha[0]"),
    ("[grid]\ngamma = [0.9, 0.5, 0.9]\n", "grid.gamma[2]: the same configuration as grid.gamma[0]"),
    ("[grid]\nalgorithm = ['q_learning', 'sarsa']\nalpha = [0.1, 0.2]\n[[include]]\nalgorithm = 'sarsa'\n"
     "alpha = 0.1\n", "include[0]: the same configuration as grid (algorithm = 'sarsa', alpha = 0.1)"),
    ("[fixed]\nepisodes = 10\n[[include]]\nalgorithm = 'sarsa'\n[[include]]\nalgorithm = 'sarsa'\nepisodes = 10\n",
     "include[1]: the same configuration as include[0]"),
    ("[grid]\nmax_steps = [1000]\n[[include]]\n", "include[0]: the same configuration as grid (max_steps = 1000)"),
])
def test_a_configuration_given_twice_is_refused_naming_both(text: str, problem: str) -> None:
    assert _problems(text) == [f"{problem}; allowed: each configuration once"]


def test_a_duplicate_value_beside_other_grid_keys_is_named_once() -> None:
    """alpha[1] repeats alpha[0] under each algorithm: one problem, naming the paths that differ."""
    assert _problems("[grid]\nalgorithm = ['q_learning', 'sarsa']\nalpha = [0.1, 0.1]\n") == [
        "grid.alpha[1]: the same configuration as grid.alpha[0]; allowed: each configuration once"]


def test_a_value_set_back_to_its_default_is_not_taken_for_a_duplicate() -> None:
    """α = 1.5 is checked again with the default α, 0.05, the same as alpha[0]: only the bad value is reported."""
    assert _problems("[grid]\nalpha = [0.05, 1.5]\n") == ["grid.alpha[1]: got 1.5; allowed: a number in (0, 1]"]


@pytest.mark.parametrize("field", ["alpha", "gamma", "epsilon", "epsilon_start", "epsilon_end", "decay_fraction",
                                   "lam", "baseline_alpha", "target_epsilon"])
def test_an_integer_and_its_float_are_one_configuration(field: str) -> None:
    as_int, as_float = ExperimentConfig(**{field: 1}), ExperimentConfig(**{field: 1.0})
    assert as_int == as_float
    assert as_int.to_dict() == as_float.to_dict()
    assert config_hash(as_int) == config_hash(as_float)
    assert type(getattr(as_int, field)) is float


@settings(max_examples=60, deadline=None)
@given(st.lists(st.sampled_from([0, 1, 0.0, 1.0, 0.5, 0.25]), min_size=1, max_size=4))
def test_a_grid_is_refused_exactly_when_two_of_its_values_are_equal_numbers(values: list[float]) -> None:
    text = tomli_w.dumps({"grid": {"gamma": values}})
    distinct = len({float(v) for v in values}) == len(values)
    if distinct:
        sweep = parse_sweep(text)
        assert len({config_hash(c) for c in sweep.configs}) == len(values)
    else:
        assert all(p.endswith("; allowed: each configuration once") for p in _problems(text))


# --- at least one configuration ------------------------------------------------------------------------


@pytest.mark.parametrize("text", ["", "# nothing\n", "[sweep]\nname = 'x'\nseeds = 2\n", "[fixed]\nalpha = 0.1\n",
                                  "[sweep]\n[fixed]\nepisodes = 10\n", "[grid]\n"])
def test_a_sweep_with_no_configuration_is_refused(text: str) -> None:
    assert _problems(text) == [EMPTY]


def test_an_empty_sweep_still_reports_its_fixed_values() -> None:
    assert _problems("[fixed]\nalpha = 2\n") == [EMPTY, "fixed.alpha: got 2; allowed: a number in (0, 1]"]


def test_an_include_with_no_keys_is_the_fixed_values_alone() -> None:
    sweep = parse_sweep("[fixed]\nepisodes = 10\n[[include]]\n")
    assert [(c.episodes, c.alpha) for c in sweep.configs] == [(10, 0.05)]


# --- counts a run can hold ------------------------------------------------------------------------------


@pytest.mark.parametrize(("key", "value", "allowed"), [
    ("episodes", 1_000_000_000_000, "[1, 2147483647]"),
    ("eval_episodes", 100_000_000_000, "[1, 2147483647]"),
    ("max_steps", 2**63 - 1, "[1, 2147483647]"),
    ("eval_every", 2**31, "[0, 2147483647]"),
    ("n", 2**40, "[1, 2147483647]"),
    ("tilings", 2**31, "[1, 2147483647]"),
    ("tiles", 2**31, "[1, 2147483647]"),
    ("hash_size", 2**62, "[0, 2147483647]"),
])
def test_a_huge_count_in_a_sweep_file_is_a_problem_at_its_path(key: str, value: int, allowed: str) -> None:
    problems = _problems(tomli_w.dumps({"grid": {key: [value]}}))
    assert problems == [f"grid.{key}[0]: got {value}; allowed: an integer in {allowed}"
                        + (" (0: no hashing)" if key == "hash_size" else "")
                        + (" (0: no evaluation)" if key == "eval_every" else "")]


def test_records_larger_than_memory_in_a_sweep_file_are_a_problem_with_the_figure() -> None:
    text = "[sweep]\nseeds = 30\n[fixed]\neval_every = 1\n[grid]\neval_episodes = [2147483647]\n"
    (problem,) = _problems(text)
    assert problem.startswith("grid.eval_episodes[0]: got 2147483647; allowed: a run whose records fit in memory: "
                              "30 seeds x 5,000 evaluations x 2,147,483,647 episodes need ")
    assert problem.endswith(" GiB")


@pytest.mark.parametrize(("option", "value"), [("--episodes", "1000000000000"), ("--eval-episodes", "100000000000"),
                                               ("--max-steps", "99999999999999999999")])
def test_a_huge_count_on_the_command_line_is_one_line_and_exit_2(option: str, value: str, tmp_path: Path) -> None:
    result = invoke("run", option, value, "--out", str(tmp_path / "out"))
    assert result.exit_code == 2, result.output
    assert "[1, 2147483647]" in result.output
    assert "Traceback" not in result.output
    assert not (tmp_path / "out").exists()


# --- what an error quotes -------------------------------------------------------------------------------


@pytest.mark.slow("compiles or trains for a second or more")
def test_a_huge_value_in_a_sweep_file_is_quoted_in_part() -> None:
    big = "x" * 1_000_000
    text = tomli_w.dumps({"sweep": {"name": big, "root_seed": big, "seeds": big}, "fixed": {"gamma": big},
                          "grid": {"alpha": big, "algorithm": ["q_learning", big]}})
    problems = _problems(text)
    assert len(problems) == 6
    quoted = [p.split("; allowed:")[0] for p in problems]  # the allowed values grow with the registries
    assert all(len(q) < 200 for q in quoted), [len(q) for q in quoted]
    assert all("… (1,000,002 characters)" in p for p in problems)


def test_a_huge_key_is_quoted_in_part() -> None:
    key = "k" * 1_000_000
    problems = _problems(tomli_w.dumps({key: {}, "sweep": {key: 1}, "fixed": {key: 1}, "grid": {"alpha": [0.1]}}))
    assert len(problems) == 3
    assert all(len(p) < 600 for p in problems), [len(p) for p in problems]
    assert all("… (1,000,000 characters)" in p for p in problems)


def test_a_huge_value_beside_a_bad_combination_is_quoted_in_part() -> None:
    """The combination a problem names quotes its values capped too."""
    text = tomli_w.dumps({"grid": {"env": ["CartPole-v1", "Acrobot-v1"], "bins": [[1, 1, 6, 12]],
                                   "stages": [[["x" * 1_000_000, 1.0]]]}})
    problems = _problems(text)
    assert problems
    assert all(len(p) < 600 for p in problems), [len(p) for p in problems]
