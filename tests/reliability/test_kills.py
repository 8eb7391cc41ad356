"""Studies killed with SIGKILL, then run again: the same command resumes, trains only what was missing, and gives
results equal bit for bit to an uninterrupted run (the tabular engine); a report killed half-way is rebuilt equal
to one never interrupted; no half-written file is ever read as complete."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from helpers import ENV, assert_same_runs, finished_runs, invoke, kill_when, start

from rlcompare.experiment import store

pytestmark = pytest.mark.slow("kills a study in a process of its own and runs it again")

WHY = ("reproduce", "why", "--allow-undecidable", "--seeds", "6", "--episodes", "1500")
"""The why study's 12 runs, each long enough (a tenth of a second or more) for a kill to land between two of them."""


def _why(out: Path) -> list[str]:
    return [sys.executable, "-m", "rlcompare.cli", *WHY, "--out", str(out)]


@pytest.fixture(scope="module")
def why_reference(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The why study made uninterrupted (in this process): what a killed one must resume to, and a study to
    report."""
    out = tmp_path_factory.mktemp("why") / "reference"
    made = invoke(*WHY, "--out", str(out), columns=300)
    assert made.exit_code == 0, made.output
    return out


def test_the_why_study_killed_mid_training_resumes_to_the_uninterrupted_result(why_reference: Path,
                                                                              tmp_path: Path) -> None:
    killed = tmp_path / "killed"
    log = tmp_path / "killed.log"
    process = start(_why(killed), log)
    kill_when(process, lambda: len(finished_runs(killed)) >= 3, log)
    finished = finished_runs(killed)
    assert 3 <= len(finished) < 12
    again = invoke(*WHY, "--out", str(killed), columns=300)  # the same command, in this process
    assert again.exit_code == 0, again.output
    assert again.output.count("loaded (already complete)") == len(finished)
    runs = finished_runs(why_reference)
    assert finished_runs(killed) == runs
    assert_same_runs(killed, why_reference, runs)
    assert (killed / "tables" / "decomposition.csv").read_bytes() == (why_reference / "tables" / "decomposition.csv"
                                                                       ).read_bytes()


def test_a_report_killed_half_way_is_rebuilt_equal_to_one_never_interrupted(why_reference: Path,
                                                                           tmp_path: Path) -> None:
    study = Path(shutil.copytree(why_reference, tmp_path / "why", ignore=shutil.ignore_patterns(store.LOCK_FILE)))
    report = [sys.executable, "-m", "rlcompare.cli", "report", str(study)]
    assert subprocess.run(report, capture_output=True, check=False, env=ENV, timeout=600).returncode == 0
    tables = {p.name: p.read_bytes() for p in (study / "tables").iterdir()}
    page = (study / "report.html").read_bytes()
    written = {path: _modified(path) for path in [*(study / "tables").iterdir(), *(study / "figures").iterdir(),
                                                  study / "report.html"]}
    log = tmp_path / "report.log"
    process = start(report, log)
    # half-way through: once it has written one of its files again, the others (a figure among them, drawn for a
    # second or more) still to write
    kill_when(process, lambda: any(_modified(path) != when for path, when in written.items()), log)
    # what a kill in the middle of writing a figure leaves (whether or not this one did), and a user's file
    (study / "figures" / ".decomposition.png.k1ll3d.tmp").write_bytes(b"half a picture")
    (study / "figures" / ".mine.tmp").write_bytes(b"a user's")
    again = invoke("report", str(study), columns=300)  # the same command, in this process
    assert again.exit_code == 0, again.output
    assert {p.name: p.read_bytes() for p in (study / "tables").iterdir()} == tables
    assert (study / "report.html").read_bytes() == page
    assert list(study.rglob(".*.tmp")) == [study / "figures" / ".mine.tmp"]  # what rlcompare left half-written is gone


def _modified(path: Path) -> int | None:
    """When ``path`` was last written (None while it is being replaced)."""
    try:
        return path.stat().st_mtime_ns
    except FileNotFoundError:
        return None


BOOK = ("reproduce", "book-6.3", "--allow-undecidable", "--runs", "200", "--episodes", "2000")
"""Figure 6.3's 60 runs: 30 of 200 seeds x 100 episodes (a twentieth of a second or more each), then 30 of 2 seeds x
2,000 episodes."""


def _book(out: Path) -> list[str]:
    return [sys.executable, "-m", "rlcompare.cli", *BOOK, "--out", str(out)]


def test_the_book_figure_study_killed_mid_training_resumes_to_the_uninterrupted_tables(tmp_path: Path) -> None:
    killed, reference = tmp_path / "killed", tmp_path / "reference"
    log = tmp_path / "killed.log"
    process = start(_book(killed), log)
    kill_when(process, lambda: len(finished_runs(killed)) >= 10, log)
    finished = len(finished_runs(killed))
    assert 10 <= finished < 60
    again = invoke(*BOOK, "--out", str(killed), columns=300)  # the same command, in this process
    assert again.exit_code == 0, again.output
    assert again.output.count("loaded (already complete)") == finished  # only the missing runs trained
    uninterrupted = invoke(*BOOK, "--out", str(reference), columns=300)
    assert uninterrupted.exit_code == 0, uninterrupted.output
    tables = sorted(p.name for p in (reference / "tables").iterdir())
    assert tables == sorted(p.name for p in (killed / "tables").iterdir())
    for name in tables:  # every number of the study, from the resumed runs and the uninterrupted ones alike
        assert (killed / "tables" / name).read_bytes() == (reference / "tables" / name).read_bytes(), name
