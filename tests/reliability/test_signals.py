"""Signals a terminal or a scheduler sends, to real processes (issue 39): Ctrl-C once finishes the trainings in
flight and keeps them, twice abandons them at once (exit 130, never an abort); SIGTERM to ``report`` ends its video
workers with it, so nothing writes into the directory after its lock is gone."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest
from helpers import ENV, finished_runs, paper_study, start

pytestmark = pytest.mark.slow("sends signals to rlcompare processes that train or render")

DEEP = ["reproduce", "deep", "--allow-undecidable", "--steps", "41000", "--episodes", "50", "--seeds", "2", "--envs",
        "CartPole-v1", "--methods", "pqn_q_lambda,pqn_sarsa_lambda", "--workers", "1"]
"""Two deep trainings of about the fewest steps they take (a training is in flight while its program compiles,
seconds, whatever its steps), after the tabular pair's, at 50 episodes."""


SAYS_SO = 30
"""Seconds a process may take to say what a Ctrl-C does: on 2 cores shared with the rest of the suite (pgx's and the
chess study's compiles beside it), 5 s was sometimes too few for its main thread to get its turn."""


def rlcompare(*args: str) -> list[str]:
    return [sys.executable, "-m", "rlcompare.cli", *args]


def cold_compiles(cache: Path) -> dict[str, str]:
    """The environment of a study whose networks compile afresh, in the empty JAX cache ``cache``: a compile takes
    seconds, time to send the signals while a training is in flight (with the user's warm cache a training of
    CartPole can end within the test's reaction)."""
    assert not cache.exists() or not any(cache.iterdir()), cache
    return {**ENV, "JAX_COMPILATION_CACHE_DIR": str(cache)}


@pytest.fixture(scope="module")
def compiled(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A JAX cache that the first test's training, kept after its Ctrl-C, compiles into from nothing, and the second
    test's resumed command (sent no signal) reads: one compile fewer."""
    return tmp_path_factory.mktemp("jax-cache")


def wait_for(ready: Callable[[], bool], process: subprocess.Popen[bytes], log: Path, timeout: float = 240) -> None:
    deadline = time.monotonic() + timeout
    while not ready():
        assert process.poll() is None, log.read_text()
        assert time.monotonic() < deadline, log.read_text()
        time.sleep(0.05)


def in_flight(study: Path) -> bool:
    """Whether a network's training has begun: its run directory, made when its thread starts it, beside the
    tabular pair's two."""
    return len(list(study.glob("*/.rlcompare.json"))) > 2


FIRST, SECOND = "pqn_q_lambda-CartPole-v1", "pqn_sarsa_lambda-CartPole-v1"
"""The two deep trainings of :data:`DEEP`, one after the other (``--workers 1``)."""


def in_flight_when_handled(text: str) -> list[str]:
    """The trainings the first Ctrl-C found in flight, as the process said; one of :data:`FIRST` and
    :data:`SECOND`."""
    flying = text.split("Ctrl-C: finishing the trainings in flight (")[1].split(")")[0].split(", ")
    assert flying in ([FIRST], [SECOND]), text
    return flying


def deep_runs(study: Path) -> set[str]:
    """The deep trainings of ``study`` that finished (the tabular pair trains first and always does)."""
    return set(finished_runs(study)) - {"tabular-sarsa-CartPole-v1", "tabular-q_learning-CartPole-v1"}


def test_ctrl_c_once_finishes_the_training_in_flight_and_keeps_it(compiled: Path, tmp_path: Path) -> None:
    out, log = tmp_path / "study", tmp_path / "log"
    cache = tmp_path / "jax-cache" if any(compiled.iterdir()) else compiled  # filled already where run after the next
    process = start(rlcompare(*DEEP, "--out", str(out)), log, cold_compiles(cache))
    wait_for(lambda: in_flight(out), process, log)
    process.send_signal(signal.SIGINT)
    wait_for(lambda: "Ctrl-C: finishing the trainings in flight (" in log.read_text(), process, log,
             timeout=SAYS_SO)
    assert process.wait(timeout=240) == 130, log.read_text()
    text = log.read_text()
    assert "Ctrl-C again abandons them" in text
    assert "Traceback" not in text
    # the one in flight kept and nothing started after it; on a loaded machine the Ctrl-C is sometimes handled only
    # once the first training is done and the second under way, and then both are kept, rightly
    flying = in_flight_when_handled(text)
    assert deep_runs(out) == ({FIRST} if flying == [FIRST] else {FIRST, SECOND}), text


def test_ctrl_c_twice_abandons_at_once_and_the_same_command_resumes(compiled: Path, tmp_path: Path) -> None:
    out, log = tmp_path / "study", tmp_path / "log"
    process = start(rlcompare(*DEEP, "--out", str(out)), log, cold_compiles(tmp_path / "jax-cache"))
    wait_for(lambda: in_flight(out), process, log)
    process.send_signal(signal.SIGINT)
    wait_for(lambda: "Ctrl-C again abandons them" in log.read_text(), process, log, timeout=SAYS_SO)
    process.send_signal(signal.SIGINT)
    assert process.wait(timeout=10) == 130, log.read_text()
    text = log.read_text()
    assert "abandoned; the finished runs are kept" in text
    assert "FATAL" not in text
    assert "terminate called" not in text
    # the one in flight abandoned; the first kept where it had finished before the Ctrl-C was handled
    assert deep_runs(out) == (set() if in_flight_when_handled(text) == [FIRST] else {FIRST}), text
    # no signal is sent to the resumed command: it may find its programs compiled
    resumed = subprocess.run(rlcompare(*DEEP, "--out", str(out)), capture_output=True, text=True,
                             env={**ENV, "JAX_COMPILATION_CACHE_DIR": str(compiled)}, check=False)
    assert resumed.returncode == 0, resumed.stderr
    assert len(finished_runs(out)) == 4


def test_sigterm_to_report_ends_its_video_workers_before_its_lock_is_released(tmp_path: Path) -> None:
    study = paper_study(tmp_path / "study", seeds=2, episodes=300)
    log = tmp_path / "log"
    process = start(rlcompare("report", str(study)), log)
    wait_for(lambda: any((study / "videos").glob(".*.tmp*")), process, log)  # a worker is writing a video
    workers = children(process.pid)
    assert workers
    process.send_signal(signal.SIGTERM)
    assert process.wait(timeout=30) == 143, log.read_text()
    assert "Traceback" not in log.read_text()
    deadline = time.monotonic() + 10  # multiprocessing's resource tracker ends once its pipe closes
    while [pid for pid in workers if alive(pid)] and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not [(pid, Path(f"/proc/{pid}/cmdline").read_text()) for pid in workers if alive(pid)]
    written = {path: path.stat().st_mtime_ns for path in (study / "videos").iterdir()}
    time.sleep(2)
    assert {path: path.stat().st_mtime_ns for path in (study / "videos").iterdir()} == written


def children(pid: int) -> list[int]:
    """The processes ``pid`` started (its video workers and multiprocessing's resource tracker), read from
    ``/proc``: the fourth field of a process's ``stat``, after its parenthesised name, is its parent."""
    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:  # the process ended meanwhile
            continue
        if int(fields[1]) == pid:
            found.append(int(stat.parent.name))
    return found


def alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return Path(f"/proc/{pid}/stat").read_text().split()[2] != "Z"
