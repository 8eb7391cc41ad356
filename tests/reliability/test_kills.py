"""Studies killed with SIGKILL, then run again: the same command resumes, trains only what was missing, and gives
results equal bit for bit to an uninterrupted run (the tabular engine); a report killed half-way is rebuilt equal
to one never interrupted; no half-written file is ever read as complete."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest
from helpers import ENV, assert_same_runs, finished_runs, kill_when, start

pytestmark = pytest.mark.slow("kills a study in a process of its own and runs it again")

def _why(out: Path, *extra: str) -> list[str]:
    return [sys.executable, "-m", "rlcompare.cli", "reproduce", "why", "--allow-undecidable", "--seeds", "6",
            "--episodes", "5000",
            "--out", str(out), *extra]


def test_the_why_study_killed_mid_training_resumes_to_the_uninterrupted_result(tmp_path: Path) -> None:
    killed = tmp_path / "killed"
    log = tmp_path / "killed.log"
    process = start(_why(killed), log)
    kill_when(process, lambda: len(finished_runs(killed)) >= 3, log)
    finished = finished_runs(killed)
    assert 3 <= len(finished) < 12
    again = subprocess.run(_why(killed), capture_output=True, text=True, check=False, env=ENV, timeout=600)
    assert again.returncode == 0, again.stderr
    assert again.stdout.count("loaded (already complete)") == len(finished)
    reference = tmp_path / "reference"
    assert subprocess.run(_why(reference), capture_output=True, check=False, env=ENV, timeout=600).returncode == 0
    runs = finished_runs(reference)
    assert finished_runs(killed) == runs
    assert_same_runs(killed, reference, runs)
    assert (killed / "tables" / "decomposition.csv").read_bytes() == (reference / "tables" / "decomposition.csv"
                                                                       ).read_bytes()


def test_a_report_killed_half_way_is_rebuilt_equal_to_one_never_interrupted(tmp_path: Path) -> None:
    study = tmp_path / "why"
    made = subprocess.run(_why(study), capture_output=True, check=False, env=ENV, timeout=600)
    assert made.returncode == 0
    report = [sys.executable, "-m", "rlcompare.cli", "report", str(study)]
    started = time.monotonic()
    assert subprocess.run(report, capture_output=True, check=False, env=ENV, timeout=600).returncode == 0
    whole = time.monotonic() - started
    tables = {p.name: p.read_bytes() for p in (study / "tables").iterdir()}
    page = (study / "report.html").read_bytes()
    log = tmp_path / "report.log"
    process = start(report, log)
    started = time.monotonic()
    kill_when(process, lambda: time.monotonic() - started > whole / 2, log)  # half-way through, as timed whole
    # what a kill in the middle of writing a figure leaves (whether or not this one did), and a user's file
    (study / "figures" / ".decomposition.png.k1ll3d.tmp").write_bytes(b"half a picture")
    (study / "figures" / ".mine.tmp").write_bytes(b"a user's")
    again = subprocess.run(report, capture_output=True, text=True, check=False, env=ENV, timeout=600)
    assert again.returncode == 0, again.stderr
    assert {p.name: p.read_bytes() for p in (study / "tables").iterdir()} == tables
    assert (study / "report.html").read_bytes() == page
    assert list(study.rglob(".*.tmp")) == [study / "figures" / ".mine.tmp"]  # what rlcompare left half-written is gone


def _book(out: Path) -> list[str]:
    return [sys.executable, "-m", "rlcompare.cli", "reproduce", "book-6.3", "--allow-undecidable", "--runs", "200",
            "--out", str(out)]


def test_the_book_figure_study_killed_mid_training_resumes_to_the_uninterrupted_tables(tmp_path: Path) -> None:
    killed, reference = tmp_path / "killed", tmp_path / "reference"
    log = tmp_path / "killed.log"
    process = start(_book(killed), log)
    kill_when(process, lambda: len(finished_runs(killed)) >= 10, log)
    finished = len(finished_runs(killed))
    assert 10 <= finished < 60
    again = subprocess.run(_book(killed), capture_output=True, text=True, check=False, env=ENV, timeout=600)
    assert again.returncode == 0, again.stderr
    assert again.stdout.count("loaded (already complete)") == finished  # only the missing runs trained
    assert subprocess.run(_book(reference), capture_output=True, check=False, env=ENV, timeout=600).returncode == 0
    tables = sorted(p.name for p in (reference / "tables").iterdir())
    assert tables == sorted(p.name for p in (killed / "tables").iterdir())
    for name in tables:  # every number of the study, from the resumed runs and the uninterrupted ones alike
        assert (killed / "tables" / name).read_bytes() == (reference / "tables" / name).read_bytes(), name
