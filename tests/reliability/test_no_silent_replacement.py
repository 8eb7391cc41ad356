"""Results made with other settings are never replaced without a word: a study or a run asked into a directory
that holds finished runs made otherwise is refused in one line naming the differing settings and the choices,
with nothing written; the same settings resume; ``--force`` replaces."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from click.testing import Result
from helpers import digests, invoke

pytestmark = pytest.mark.slow("trains studies and runs into directories it then asks again")


def paper(out: Path, seeds: int, *options: str) -> Result:
    """The paper's study of ``seeds`` seeds x 20 episodes into ``out`` (a design too small to decide, asked for)."""
    return invoke("reproduce", "--allow-undecidable", "--seeds", str(seeds), "--episodes", "20", "--no-videos",
                  "--out", str(out), *options)


def test_a_study_with_other_seeds_is_refused_naming_them_and_nothing_changes(tmp_path: Path) -> None:
    out = tmp_path / "paper"
    first = paper(out, 3)
    assert first.exit_code == 0, first.output
    before = digests(out)
    refused = paper(out, 2)
    assert refused.exit_code == 2
    design, time, *lines = refused.output.strip().splitlines()
    assert design.startswith("This design cannot decide")
    assert time.startswith("Time: about ")  # the same settings as the first's, whose pace it kept
    assert len(lines) == 1
    assert "holds finished runs made with other settings" in lines[0]
    assert "seeds 0-2 there, 0, 1 asked" in lines[0]
    assert "--force" in lines[0]
    assert "another --out" in lines[0]
    assert "Traceback" not in refused.output
    assert digests(out) == before
    again = paper(out, 3)
    assert again.exit_code == 0, again.output  # the same settings resume: every run loaded
    assert again.output.count("loaded (already complete)") == 9
    replaced = paper(out, 2, "--force")
    assert replaced.exit_code == 0, replaced.output
    assert digests(out) != before


def test_a_run_with_other_settings_is_refused_in_its_directory(tmp_path: Path) -> None:
    out = tmp_path / "run"
    assert invoke("run", "--seeds", "2", "--episodes", "20", "--out", str(out)).exit_code == 0
    before = digests(out)
    refused = invoke("run", "--seeds", "2", "--episodes", "30", "--out", str(out))
    assert refused.exit_code == 2
    assert "episodes 20 there, 30 asked" in refused.output
    assert digests(out) == before
    assert invoke("run", "--seeds", "2", "--episodes", "20", "--out", str(out)).exit_code == 0


@contextlib.contextmanager
def paused(process: subprocess.Popen[str]) -> Iterator[None]:
    """``process`` stopped (SIGSTOP) for the block and continued after it: mid-way through its writing, its
    directory's lock held, however long the other processes take to start on a loaded machine."""
    os.kill(process.pid, signal.SIGSTOP)
    try:
        yield
    finally:
        os.kill(process.pid, signal.SIGCONT)


@pytest.mark.slow("runs two rlcompare processes on one directory")
def test_report_and_reproduce_while_a_study_is_written_wait_or_refuse_in_one_line(tmp_path: Path) -> None:
    """A real second process: ``report`` and a second ``reproduce`` on a directory a running ``reproduce`` is
    writing are refused in one line naming its process; the first finishes untouched."""
    out = tmp_path / "paper"
    command = [sys.executable, "-m", "rlcompare.cli", "reproduce", "--allow-undecidable", "--seeds", "4",
               "--episodes", "1000", "--no-videos", "--out", str(out)]
    env = {**os.environ, "COLUMNS": "300"}
    first = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        deadline = time.monotonic() + 120
        while not list(out.glob("*/config.json")) and time.monotonic() < deadline and first.poll() is None:
            time.sleep(0.05)  # training has begun: the directory is locked
        with paused(first):
            report = subprocess.run([sys.executable, "-m", "rlcompare.cli", "report", str(out)],
                                    capture_output=True, text=True, check=False, timeout=120, env=env)
            second = subprocess.run(command, capture_output=True, text=True, check=False, timeout=120, env=env)
        first_out, first_err = first.communicate(timeout=300)
    finally:
        first.kill()
    assert first.returncode == 0, first_err
    for refused in (report, second):
        assert refused.returncode == 2, refused.stdout + refused.stderr
        assert f"another rlcompare process (pid {first.pid}) is writing here" in refused.stderr
        assert "Traceback" not in refused.stderr
    assert "Report:" in first_out


def test_report_and_run_on_a_run_directory_being_written_are_refused_naming_its_writer(tmp_path: Path) -> None:
    """A real second process: ``report`` and ``uci`` of a run directory ``run`` is still writing, and a second
    ``run`` into it, are refused in one line naming the writer (before, ``report`` failed on the files not yet
    there, and ``uci`` said the directory held nothing it reads); the writer finishes untouched, and its directory
    then reads as any other."""
    from rlcompare.experiment import store

    out = tmp_path / "run"
    command = [sys.executable, "-m", "rlcompare.cli", "run", "--episodes", "1000", "--seeds", "40", "--out", str(out)]
    env = {**os.environ, "COLUMNS": "300"}
    first = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        deadline = time.monotonic() + 120
        lock = out / store.LOCK_FILE
        while time.monotonic() < deadline and first.poll() is None and not (
                lock.exists() and lock.read_text().strip() == str(first.pid)):
            time.sleep(0.05)  # the writer holds the lock
        with paused(first):
            others = [subprocess.Popen(args, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                       stderr=subprocess.PIPE, text=True, env=env)
                      for args in ([sys.executable, "-m", "rlcompare.cli", "report", str(out)],
                                   [sys.executable, "-m", "rlcompare.cli", "uci", str(out)], command)]
            answers = [other.communicate(timeout=120)[1] for other in others]
        first_out, first_err = first.communicate(timeout=300)
    finally:
        first.kill()
    assert first.returncode == 0, first_err
    for other, answer in zip(others, answers, strict=True):
        assert other.returncode == 2, answer
        assert answer.strip().splitlines() == [
            f"Error: {out}: another rlcompare process (pid {first.pid}) is writing here; wait for it to finish, or "
            "use another directory"]
    assert "Run directory:" in first_out
    report = invoke("report", str(out))
    assert report.exit_code == 0, report.output
    assert "(q_learning-decay, 40 seeds)" in report.output


def test_a_run_whose_configuration_was_edited_is_damaged_and_trained_again_not_another_runs(tmp_path: Path) -> None:
    """alpha 0.5 edited to 0.25 in config.json by hand: the run was made with 0.5 and is damaged (its checksum is not
    meta.json's); the same command says so and trains it again, never that it was made with 0.25."""
    out = tmp_path / "run"
    command = ("run", "--episodes", "5", "--seeds", "2", "--alpha", "0.5", "--out", str(out))
    assert invoke(*command).exit_code == 0
    config = out / "config.json"
    config.write_text(config.read_text().replace('"alpha": 0.5,', '"alpha": 0.25,'))
    again = invoke(*command, columns=300)
    assert again.exit_code == 0, again.output
    said = " ".join(again.output.split())
    assert "A damaged run, trained again:" in said
    assert "config.json: does not belong to this run" in said
    assert "other settings" not in said
    assert '"alpha": 0.5,' in config.read_text()
