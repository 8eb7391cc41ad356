"""Studies killed with SIGKILL, then run again: the same command resumes, trains only what was missing, and gives
results equal bit for bit to an uninterrupted run (the tabular engine); a report killed half-way is rebuilt equal
to one never interrupted; no half-written file is ever read as complete."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from rlcompare.experiment import rundir
from rlcompare.experiment.results import Results

pytestmark = pytest.mark.slow

ENV = {**os.environ, "COLUMNS": "300"}


def _start(command: list[str], log: Path) -> subprocess.Popen:
    with log.open("wb") as output:
        return subprocess.Popen(command, stdout=output, stderr=output, start_new_session=True, env=ENV)


def _kill_when(process: subprocess.Popen, ready, log: Path, timeout: float = 240) -> None:
    deadline = time.monotonic() + timeout
    while not ready() and time.monotonic() < deadline and process.poll() is None:
        time.sleep(0.02)
    assert process.poll() is None, log.read_text()
    os.killpg(process.pid, signal.SIGKILL)
    process.wait()


def _why(out: Path, *extra: str) -> list[str]:
    return [sys.executable, "-m", "rlcompare.cli", "reproduce", "why", "--seeds", "6", "--episodes", "5000",
            "--out", str(out), *extra]


def test_the_why_study_killed_mid_training_resumes_to_the_uninterrupted_result(tmp_path: Path) -> None:
    killed = tmp_path / "killed"
    log = tmp_path / "killed.log"
    process = _start(_why(killed), log)
    _kill_when(process, lambda: len(list(killed.glob(f"*/{rundir.META_FILE}"))) >= 3, log)
    finished = sorted(p.parent.name for p in killed.glob(f"*/{rundir.META_FILE}"))
    assert 3 <= len(finished) < 12
    for run in killed.iterdir():  # a run without meta.json is never read as finished
        if run.is_dir() and run.name not in finished and (run / rundir.CONFIG_FILE).exists():
            assert not (run / rundir.META_FILE).exists()
    again = subprocess.run(_why(killed), capture_output=True, text=True, check=False, env=ENV, timeout=600)
    assert again.returncode == 0, again.stderr
    assert again.stdout.count("loaded (already complete)") == len(finished)
    reference = tmp_path / "reference"
    assert subprocess.run(_why(reference), capture_output=True, check=False, env=ENV, timeout=600).returncode == 0
    runs = sorted(p.parent.name for p in reference.glob(f"*/{rundir.META_FILE}"))
    assert sorted(p.parent.name for p in killed.glob(f"*/{rundir.META_FILE}")) == runs
    for name in runs:
        resumed, uninterrupted = Results.load(killed / name), Results.load(reference / name)
        for field in ("returns", "lengths", "eval_returns", "eval_lengths"):
            assert (getattr(resumed.records, field) == getattr(uninterrupted.records, field)).all(), (name, field)
    assert (killed / "tables" / "decomposition.csv").read_bytes() == (reference / "tables" / "decomposition.csv"
                                                                       ).read_bytes()


def test_a_report_killed_half_way_is_rebuilt_equal_to_one_never_interrupted(tmp_path: Path) -> None:
    study = tmp_path / "why"
    made = subprocess.run(_why(study), capture_output=True, check=False, env=ENV, timeout=600)
    assert made.returncode == 0
    tables = {p.name: p.read_bytes() for p in (study / "tables").iterdir()}
    page = (study / "report.html").read_bytes()
    log = tmp_path / "report.log"
    process = _start([sys.executable, "-m", "rlcompare.cli", "report", str(study)], log)
    started = time.monotonic()
    _kill_when(process, lambda: time.monotonic() - started > 3.0, log)  # in its tables or figures
    again = subprocess.run([sys.executable, "-m", "rlcompare.cli", "report", str(study)], capture_output=True,
                           text=True, check=False, env=ENV, timeout=600)
    assert again.returncode == 0, again.stderr
    assert {p.name: p.read_bytes() for p in (study / "tables").iterdir()} == tables
    assert (study / "report.html").read_bytes() == page
    assert not list(study.rglob(".*.tmp"))  # what the killed report left half-written is gone


def _book(out: Path) -> list[str]:
    return [sys.executable, "-m", "rlcompare.cli", "reproduce", "book-6.3", "--runs", "200", "--out", str(out)]


def test_the_book_figure_study_killed_mid_training_resumes_to_the_uninterrupted_tables(tmp_path: Path) -> None:
    killed, reference = tmp_path / "killed", tmp_path / "reference"
    log = tmp_path / "killed.log"
    process = _start(_book(killed), log)
    _kill_when(process, lambda: len(list(killed.glob(f"*/{rundir.META_FILE}"))) >= 10, log)
    finished = len(list(killed.glob(f"*/{rundir.META_FILE}")))
    assert 10 <= finished < 60
    again = subprocess.run(_book(killed), capture_output=True, text=True, check=False, env=ENV, timeout=600)
    assert again.returncode == 0, again.stderr
    assert again.stdout.count("loaded (already complete)") == finished  # only the missing runs trained
    assert subprocess.run(_book(reference), capture_output=True, check=False, env=ENV, timeout=600).returncode == 0
    tables = sorted(p.name for p in (reference / "tables").iterdir())
    assert tables == sorted(p.name for p in (killed / "tables").iterdir())
    for name in tables:  # every number of the study, from the resumed runs and the uninterrupted ones alike
        assert (killed / "tables" / name).read_bytes() == (reference / "tables" / name).read_bytes(), name
