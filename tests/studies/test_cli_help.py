"""The command line's help: a fast --help and --version, help in plain words, report on a single run directory,
tables that fit 80 columns, and what a run says of the steps it was given."""

from __future__ import annotations

import json
import re
from importlib import metadata
from pathlib import Path
from types import SimpleNamespace

import pytest
import typer.main
from helpers import command_line, invoke
from typer.testing import CliRunner

from rlcompare import ExperimentConfig, cli, run
from rlcompare.cli import console as console_module
from rlcompare.cli.app_help import summary_app
from rlcompare.cli.config_options import PLAIN_WORDS
from rlcompare.studies.registry import MEASURED_DEFAULTS, STUDIES
from rlcompare.tabular.config import field_docs

HEAVY = ("numpy", "pandas", "numba", "jax", "matplotlib", "scipy", "pyarrow")
BENCH_COMMANDS = ("kernels", "envs", "study", "sweeps", "deep")
TINY = ExperimentConfig(algorithm="sarsa", seeds=(0, 1, 2), episodes=20, eval_every=10, eval_episodes=2)


def squeezed(text: str) -> str:
    """``text`` without its spaces and line breaks: what it says whatever the width it was wrapped to."""
    return "".join(text.split())


def every_help() -> dict[str, str]:
    """The help of the app, of every command and of every study, by command line."""
    lines = [[], *([name] for name in ("run", "sweep", "report", "bench", "reproduce")),
             *(["bench", name] for name in BENCH_COMMANDS), *(["reproduce", name] for name in STUDIES)]
    return {" ".join(args) or "rlcompare": invoke(*args, "--help").output for args in lines}


@pytest.mark.parametrize("args", [["--version"], ["--help"]])
def test_help_and_version_import_nothing_heavy(args: list[str]) -> None:
    done = command_line(*args, python=("-X", "importtime"))
    assert done.returncode == 0, done.stderr
    imported = {line.split("|")[-1].strip().split(".")[0] for line in done.stderr.splitlines()
                if line.startswith("import time:")}
    assert "typer" in imported  # the measurement sees imports at all
    assert not imported & set(HEAVY), imported & set(HEAVY)


@pytest.mark.parametrize("args", [["compare", "--help"], ["reproduce", "--help"], ["reproduce", "minatar", "--help"],
                                  ["sweep", "--help"], ["uci", "--help"]])
def test_a_commands_help_imports_no_statistics_and_no_compiler(args: list[str]) -> None:
    """A command's help builds the app from the configuration classes, without scipy's statistics (the plans'
    design imports them), numba, JAX or torch: it answered in 1.4-1.5 s here before, 0.45-0.49 s after."""
    done = command_line(*args, python=("-X", "importtime"))
    assert done.returncode == 0, done.stderr
    imported = {line.split("|")[-1].strip().split(".")[0] for line in done.stderr.splitlines()
                if line.startswith("import time:")}
    assert "typer" in imported
    assert not imported & {"scipy", "numba", "jax", "torch"}, imported & {"scipy", "numba", "jax", "torch"}


@pytest.mark.slow("starts rlcompare in processes of its own")
@pytest.mark.parametrize(("study", "kept_out"), [
    ("paper", {"pandas", "matplotlib", "scipy.stats", "jax"}),
    ("chess", {"pgx", "scipy.stats", "pandas", "matplotlib"}),
    ("chess-endgames", {"pandas", "matplotlib", "scipy.stats", "jax"}),
    ("deep", {"pandas", "matplotlib", "scipy.stats"}),
    ("minatar", {"pandas", "matplotlib", "scipy.stats", "gymnax", "seaborn"}),
    ("atari", {"pandas", "matplotlib", "scipy.stats"}),
])
def test_a_plan_imports_nothing_it_does_not_read(study: str, kept_out: set[str], tmp_path: Path) -> None:
    """A study's --plan names its games and counts its tests without the libraries that train or report them: the
    chess plan without pgx (seconds of tables built as it loads), the MinAtar plan without gymnax (whose package loads
    seaborn and scipy's statistics), the deep studies without their reports' pandas and matplotlib (a planner of
    their own: :attr:`rlcompare.studies.registry.Study.planner`), none without scipy's statistics; it answered in
    5.4-6.8 s before, 2-3 s after (chess), 1.4-2.2 s before, 0.6-0.8 s after (the paper); CPU seconds under load,
    before and after planners of their own: deep 2.35 and 1.36, MinAtar 3.29 and 1.39, Atari 2.35 and 1.53, chess
    2.17 and 1.40, the endgames (sizes from their facts, no tables) 2.28 and 0.95."""
    if study in ("chess", "deep", "minatar", "atari"):
        pytest.importorskip("jax")  # the deep extra: its configurations check a plan's settings
    if study == "atari":
        pytest.importorskip("ale_py")  # the atari extra: the plan checks each game's ROM
    done = command_line("reproduce", study, "--plan", "--out", str(tmp_path / study), python=("-X", "importtime"))
    assert done.returncode == 0, done.stderr
    imported = {line.split("|")[-1].strip() for line in done.stderr.splitlines() if line.startswith("import time:")}
    assert "rlcompare.studies.plans" in imported  # the measurement sees the plan's imports
    assert not imported & kept_out, imported & kept_out


def test_version_is_the_installed_packages() -> None:
    expected = f"rlcompare {metadata.version('rlcompare')}"
    assert command_line("--version").stdout.strip() == expected
    result = invoke("--version")
    assert (result.exit_code, result.output.strip()) == (0, expected)


def test_the_fast_help_is_the_whole_apps_help() -> None:
    summary = CliRunner(env={"COLUMNS": "100"}).invoke(summary_app(), ["--help"], prog_name="rlcompare")
    whole = invoke("--help", columns=100)
    assert summary.exit_code == whole.exit_code == 0
    assert summary.output == whole.output
    for name in ("run", "sweep", "report", "bench", "reproduce", "--version"):
        assert name in summary.output
    as_run = command_line("--help", columns=100).stdout  # by main(), which answers from the summary app alone
    assert [line.rstrip() for line in as_run.replace("python -m rlcompare.cli", "rlcompare").splitlines()] == [
        line.rstrip() for line in whole.output.splitlines()]


@pytest.mark.slow("starts rlcompare in processes of its own")
def test_no_help_names_a_python_type() -> None:
    helps = every_help()
    assert len(helps) == 6 + len(BENCH_COMMANDS) + len(STUDIES)
    for line, text in helps.items():
        assert "Usage:" in text, line
        for noise in ("<str>", "<int>", "<bool>", "<float>", "<path>", "<list", "{"):
            assert noise not in text, (line, noise)
    assert re.search(r"--seeds\s+INTEGER", helps["run"])  # an option that takes a value still says what kind
    assert re.search(r"--alpha\s+NUMBER", helps["run"])
    assert re.search(r"--force\s+Write", helps["run"])  # a flag takes none
    assert "Usage: rlcompare report [OPTIONS] STUDY_DIR" in helps["report"]


@pytest.mark.slow("starts rlcompare in processes of its own")
def test_the_help_speaks_plainly() -> None:
    """No None (nobody types it), no Gymnasium space types, no attribute names of the code."""
    for line, text in every_help().items():
        words = " ".join(text.replace("│", " ").split())
        for jargon in (r"\bNone\b", r"\b[Bb]ox\b", "drawn_next", r"rlcompare\.\w", "SeedSequence", "Discrete"):
            assert not re.search(jargon, words), (line, jargon)


def test_each_plain_phrase_still_replaces_words_of_a_docstring() -> None:
    docs = " ".join(field_docs().values())
    stale = [phrase for phrase in PLAIN_WORDS if phrase not in docs]
    assert not stale


def test_run_options_are_the_docstrings_in_plain_words() -> None:
    options = {param.opts[0]: param for param in typer.main.get_command(cli.app).commands["run"].params}
    assert "box" in field_docs()["next_action"]
    assert options["--next-action"].help.count("Default: each method's own order.") == 1


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("face") / "run"
    run(TINY, out=path)
    return path


def test_report_on_a_single_run_directory_shows_its_results(run_dir: Path) -> None:
    result = invoke("report", str(run_dir))
    assert result.exit_code == 0, result.output
    said = squeezed(result.output)  # whatever the console's width
    assert squeezed(f"{TINY.name} -") in said  # its row, with a negative return
    assert squeezed("behaviour mean") in said
    assert squeezed(f"Run directory: {run_dir} ({TINY.name}, 3 seeds)") in said
    assert "one configuration of" not in result.output
    assert not (run_dir / "report.html").exists()  # a single run has no page: nothing is written into it


def test_report_on_a_run_of_a_study_names_the_study(run_dir: Path, tmp_path: Path) -> None:
    from rlcompare.experiment import store

    study = tmp_path / "study"
    store.claim(study, store.Owner("study", "paper"))
    run(TINY, out=study / TINY.name)
    result = invoke("report", str(study / TINY.name))
    assert result.exit_code == 0, result.output
    assert squeezed(f"one configuration of the paper study: 'rlcompare report {study.resolve()}'") in squeezed(
        result.output)


def test_report_refuses_a_directory_rlcompare_did_not_write(tmp_path: Path) -> None:
    (tmp_path / "mine.txt").write_text("a user's file")
    result = invoke("report", str(tmp_path))
    assert result.exit_code == 2
    assert isinstance(result.exception, SystemExit)
    assert "Traceback" not in result.output
    assert "was not written by rlcompare" in result.output
    assert "a run directory" in result.output  # the error lists what is allowed
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "meta.json").write_text(json.dumps({}))
    (tmp_path / "run" / "config.json").write_text(json.dumps({}))
    result = invoke("report", str(tmp_path / "run"))  # looks like a run, but no marker says rlcompare wrote it
    assert result.exit_code == 2
    assert "was not written by rlcompare" in result.output


@pytest.mark.slow("starts rlcompare in processes of its own")
def test_a_table_fits_an_80_column_terminal(run_dir: Path) -> None:
    done = command_line("report", str(run_dir), columns=80)
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert max(map(len, lines)) <= 80
    assert any(line.lstrip().startswith(TINY.name) for line in lines)  # its name whole, not cut
    assert any(re.search(r"\[-?\d+\.\d, -?\d+\.\d\]", line) for line in lines)  # an interval whole on its line


@pytest.mark.parametrize("width", [60, 80, 120])
def test_a_wide_table_wraps_instead_of_being_cut(width: int, monkeypatch: pytest.MonkeyPatch,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    import pandas as pd

    from rlcompare.bench.harness import Measurement
    from rlcompare.bench.kernels import kernel_table

    monkeypatch.setenv("COLUMNS", str(width))  # the console reads it at each print
    names = ["q_learning-constant-before_update", "double_expected_sarsa-constant", "random"]
    frame = pd.DataFrame([(name, "-176.3 [-180.1, -172.5]", "-1000.0 [-1000.0, -1000.0]", "93%", "-262")
                          for name in names],
                         columns=["configuration", "behaviour mean", "greedy mean", "greedy success",
                                  "paper (Table II)"])
    console_module.print_frame(frame, "Mean cumulative reward over seeds [95% bootstrap interval]", "a caption")
    measured = [Measurement("MountainCar-v0, Gymnasium loop", 1, 30_000, 1.0),
                *(Measurement("double_expected_sarsa (grid)", n, 16_000_000, 1.3) for n in (1, 2))]
    console_module.print_bench(kernel_table(measured))
    shown = capsys.readouterr().out
    assert max(map(len, shown.splitlines())) <= width
    if width >= 80:  # the numbers keep their columns; names fold where they must
        assert shown.count("12,307,692") == 2
        assert shown.count("[-180.1, -172.5]") == 3
    if width >= 120:
        assert "q_learning-constant-before_update" in shown


def test_the_compile_notice_promises_no_time_it_cannot_keep(monkeypatch: pytest.MonkeyPatch,
                                                            capsys: pytest.CaptureFixture[str]) -> None:
    from rlcompare import compiled

    monkeypatch.setattr(compiled, "holds_nothing_yet", lambda: True)
    monkeypatch.setenv("COLUMNS", "200")
    console_module.announce_compiling()
    said = capsys.readouterr().out
    assert "Compiling" in said
    assert not re.search(r"\d+-\d+ s", said)
    assert "each configuration's line below says how long" in said


def deep_results(given: int | None, trained: int) -> SimpleNamespace:
    config = SimpleNamespace(hyperparameters={} if given is None else {"total_steps": given}, name="pqn")
    return SimpleNamespace(config=config, seeds=(0, 1), meta={"timings": {"training_steps": trained,
                                                                         "wall_seconds": 3.0}})


def test_steps_a_training_rounded_are_said_with_the_number_trained(capsys: pytest.CaptureFixture[str]) -> None:
    line = console_module.rounded_steps_line("pqn_q_lambda-CartPole-v1", deep_results(50_000, 40_960))
    assert line is not None
    assert "40,960 steps per seed, not the 50,000 given" in line
    assert console_module.rounded_steps_line("x", deep_results(40_960, 40_960)) is None
    assert console_module.rounded_steps_line("x", deep_results(None, 40_960)) is None  # the preset's: not given
    assert console_module.rounded_steps_line("x", SimpleNamespace(config=TINY, meta={"timings": {}})) is None
    console_module.ConsoleUI().done("pqn_q_lambda-CartPole-v1", deep_results(50_000, 40_960), reused=False)
    said = " ".join(capsys.readouterr().out.split())
    assert "2 seeds: 3.0 s" in said
    assert "not the 50,000 given" in said


def test_a_count_of_one_is_singular() -> None:
    line = console_module.done_line("x", SimpleNamespace(config=SimpleNamespace(episodes=1), seeds=(0,),
                                                         meta={"timings": {"wall_seconds": 1.0}}), reused=False)
    assert "1 seed x 1 episode:" in line


@pytest.mark.slow("makes every study's plan at its defaults")
@pytest.mark.parametrize("name", list(STUDIES))
def test_every_studys_help_states_what_its_default_can_decide_and_what_its_plan_computes(name: str) -> None:
    """The help's line (``MEASURED_DEFAULTS``) gives a time and, where it names a smallest p and a level, the same
    numbers as the study's own plan at its defaults computes for its headline question."""
    study = STUDIES[name]
    stated = MEASURED_DEFAULTS[name]
    assert re.search(r"\d (s|min)\b", stated)
    shown = " ".join(invoke("reproduce", name, "--help", columns=300).output.split())
    assert f"Its default, measured: {stated} (docs/defaults.md)." in shown
    named = re.match(r"smallest p ([\d.e-]+) against (Holm's )?([\d.]+)", stated)
    if named is None:
        assert any(words in stated for words in ("plumbing check", "no test", "bootstrap interval", "t tests"))
        return
    headline = next(q for q in study.load_planner().study_plan(study.options()).questions if q.headline)
    assert float(named.group(1)) == pytest.approx(headline.reach.smallest_p, rel=0.05)  # two figures, as stated
    assert float(named.group(3)) == pytest.approx(headline.reach.level, rel=0.05)
