"""``rlcompare export``: a run's training episodes as a tidy CSV and as TensorBoard files written by TensorBoard's
own writer; both read back by ``rlcompare compare`` to the run's own numbers, and the verdicts on the exported
files equal those on the run directories themselves."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from helpers import digests, invoke

from rlcompare.experiment.engines import load_run
from rlcompare.experiment.outside import grouping, read_runs, run_files

pytestmark = pytest.mark.slow("trains two small tabular runs and exports them")


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    root = tmp_path_factory.mktemp("export")
    for algorithm in ("q_learning", "sarsa"):
        result = invoke("run", "--algorithm", algorithm, "--seeds", "5", "--episodes", "40", "--out",
                        str(root / algorithm), columns=300)
        assert result.exit_code == 0, result.output
    return root


def test_the_csv_holds_each_episodes_return_at_the_steps_up_to_its_end(runs, tmp_path):
    for algorithm in ("sarsa", "q_learning"):
        result = invoke("export", str(runs / algorithm), "--out", str(tmp_path / "csv"), columns=300)
        assert result.exit_code == 0, result.output
    assert sorted(p.name for p in (tmp_path / "csv").glob("*.csv")) == ["q_learning-decay.csv",
                                                                         "sarsa-decay.csv"]
    table = pd.read_csv(tmp_path / "csv" / "sarsa-decay.csv")
    episodes = load_run(runs / "sarsa").episodes()
    assert list(table.columns) == ["method", "env", "seed", "step", "value"]
    assert set(table["method"]) == {"sarsa-decay"}
    np.testing.assert_array_equal(table["value"], episodes["return"])
    np.testing.assert_array_equal(table["step"], episodes.groupby("seed")["length"].cumsum())


def test_tensorboard_files_read_back_to_the_runs_numbers_and_verdicts(runs, tmp_path):
    pytest.importorskip("tensorboard")
    for algorithm in ("q_learning", "sarsa"):
        result = invoke("export", str(runs / algorithm), "--to", "tensorboard", "--out", str(tmp_path / "tb"),
                        columns=300)
        assert result.exit_code == 0, result.output
    again = invoke("export", str(runs / "sarsa"), "--to", "tensorboard", "--out", str(tmp_path / "tb"), columns=300)
    assert again.exit_code == 0, again.output
    assert len(list((tmp_path / "tb").rglob("events.out.tfevents.*"))) == 10  # the second export replaced its own
    root, files = run_files([tmp_path / "tb"])
    from_events = read_runs(files, root, grouping("{method}/{env}/{seed}/*")).drop(columns=["source", "kind"])
    root, dirs = run_files([runs / "q_learning", runs / "sarsa"])
    from_runs = read_runs(dirs, root, grouping("{method}/{env}/{seed}/*")).drop(columns=["source", "kind"])
    pd.testing.assert_frame_equal(from_events.reset_index(drop=True), from_runs.reset_index(drop=True),
                                  check_dtype=False)
    verdicts = []
    for name, paths in (("events", [str(tmp_path / "tb")]), ("runs", [str(runs / "q_learning"), str(runs / "sarsa")])):
        result = invoke("compare", *paths, "--paired", "--cut-to-shortest", "--out", str(tmp_path / name),
                        columns=300)
        assert result.exit_code == 0, result.output
        verdicts.append(pd.read_csv(tmp_path / name / "tables" / "verdicts.csv"))
    pd.testing.assert_frame_equal(*verdicts)


def test_bad_input_is_one_line(runs, tmp_path):
    unknown = invoke("export", str(runs / "sarsa"), "--to", "wandb", "--out", str(tmp_path / "x"), columns=300)
    assert unknown.exit_code == 2
    assert "--to" in unknown.output
    not_a_run = invoke("export", str(tmp_path), "--out", str(tmp_path / "y"), columns=300)
    assert not_a_run.exit_code == 2
    assert "not a run directory" in not_a_run.output
    assert not (tmp_path / "x").exists()
    assert not (tmp_path / "y").exists()


@pytest.mark.parametrize("to", ["csv", "tensorboard"])
def test_a_second_run_of_the_same_name_is_refused_and_the_first_runs_files_stay(runs, tmp_path, to):
    """SARSA at α 0.05 exported, then SARSA at α 0.5 (the same configuration name) into the same directory: refused
    in one line naming the first run, whose files are left byte for byte."""
    if to == "tensorboard":
        pytest.importorskip("tensorboard")
    other = tmp_path / "sarsa-0.5"
    assert invoke("run", "--algorithm", "sarsa", "--alpha", "0.5", "--seeds", "5", "--episodes", "40", "--out",
                  str(other), columns=300).exit_code == 0
    out = tmp_path / "export"
    assert invoke("export", str(runs / "sarsa"), "--to", to, "--out", str(out)).exit_code == 0
    before = digests(out)
    refused = invoke("export", str(other), "--to", to, "--out", str(out), columns=300)
    assert refused.exit_code == 2
    assert str((runs / "sarsa").resolve()) in refused.output
    assert "Traceback" not in refused.output
    assert digests(out) == before


def test_an_interrupted_exports_scratch_is_not_read_and_the_next_export_removes_it(runs, tmp_path):
    pytest.importorskip("tensorboard")
    out = tmp_path / "tb"
    for algorithm in ("q_learning", "sarsa"):
        assert invoke("export", str(runs / algorithm), "--to", "tensorboard", "--out", str(out)).exit_code == 0
    scratch = out / ".export-killed"  # as a process killed while writing leaves it: marked, then half a file
    scratch.mkdir()
    (scratch / ".rlcompare-scratch").write_text("an export's scratch")
    (scratch / "events.out.tfevents.1.killed").write_bytes(b"half a file")
    empty = out / ".export-killed-early"  # killed before its mark
    empty.mkdir()
    users = out / ".export-notes"  # a user's, of the same prefix: not proved an export's, so it stays
    users.mkdir()
    (users / "notes.txt").write_text("mine")
    result = invoke("compare", str(out), "--cut-to-shortest", "--out", str(tmp_path / "compared"), columns=300)
    assert result.exit_code == 0, result.output
    assert invoke("export", str(runs / "sarsa"), "--to", "tensorboard", "--out", str(out)).exit_code == 0
    assert not scratch.exists()
    assert not empty.exists()
    assert (users / "notes.txt").read_text() == "mine"
    assert sorted(p.name for p in out.glob(".export-*")) == [".export-notes"]
