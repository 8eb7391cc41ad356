"""What many tests share: the command line, in this process or in a process of its own; a process killed once it has
written what a test waits for, and runs compared bit for bit; a small study of the paper; and the digests of a
directory's files (to show that nothing changed)."""

from __future__ import annotations

import hashlib
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from click.testing import Result
from typer.testing import CliRunner

from rlcompare.experiment import rundir
from rlcompare.experiment.engines import load_run
from rlcompare.rng import stream_state
from rlcompare.tabular.results import Results
from rlcompare.tabular.state import (
    AGENT_STREAM,
    ENV_STREAM,
    EVAL_AGENT_STREAM,
    EVAL_ENV_STREAM,
    EVAL_TRANSITION_STREAM,
    STREAMS,
    TRANSITION_STREAM,
    Records,
    RunState,
    allocate_records,
)


def invoke(*args: str, columns: int | None = 200, **options: Any) -> Result:
    """``rlcompare ARGS`` in this process (typer's runner), the console ``columns`` wide (None: rich's width for a
    log, 120)."""
    from rlcompare import cli

    env = {} if columns is None else {"COLUMNS": str(columns)}
    return CliRunner(env=env).invoke(cli.app, list(args), prog_name="rlcompare", **options)


def study_run(directory: Path, *args: str, columns: int | None = None) -> tuple[Path, str]:
    """``rlcompare ARGS --out DIRECTORY/study``, which must succeed: the study's directory and its output."""
    out = directory / "study"
    result = invoke(*args, "--out", str(out), columns=columns)
    assert result.exit_code == 0, result.output
    return out, result.output


def study_fixture(name: str, *args: str) -> Any:
    """A module's fixture: ``(out, output)`` of :func:`study_run` with ``args``, run once for the module."""

    @pytest.fixture(scope="module")
    def study(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
        return study_run(tmp_path_factory.mktemp(name), *args)

    return study


def assert_loaded_not_trained(out: Path, *args: str, runs: int, kept: str = "*/episodes.parquet") -> None:
    """``rlcompare ARGS --out OUT`` again over a finished study: each of its ``runs`` loaded, and no file matching
    ``kept`` written again."""
    before = {p: p.stat().st_mtime_ns for p in out.glob(kept)}
    assert before
    result = invoke(*args, "--out", str(out), columns=300)
    assert result.exit_code == 0, result.output
    assert result.output.count("loaded") == runs
    assert before == {p: p.stat().st_mtime_ns for p in out.glob(kept)}


def command_line(*args: str, columns: int = 200, python: tuple[str, ...] = (), **options: Any
                 ) -> subprocess.CompletedProcess[str]:
    """``rlcompare ARGS`` as a user runs it, in a process of its own (``python``: options of the interpreter)."""
    environment = {**os.environ, "COLUMNS": str(columns), **options.pop("env", {})}
    return subprocess.run([sys.executable, *python, "-m", "rlcompare.cli", *args], capture_output=True, text=True,
                          env=environment, check=False, **options)


def assert_each_once(problems: list[str], starts: list[str]) -> None:
    """Each of ``starts`` begins exactly one of ``problems``, and no problem is left over (a file's problems, all
    reported at once)."""
    for begins in starts:
        assert sum(p.startswith(begins) for p in problems) == 1, (begins, problems)
    assert len(problems) == len(starts), problems


def assert_sweep_refused(directory: Path, text: str, *said: str) -> None:
    """``rlcompare sweep`` of a file holding ``text`` exits 2 before running anything: its output says each of
    ``said``, without a traceback, and no study directory is written."""
    sweep_file = directory / "bad.toml"
    sweep_file.write_text(text)
    result = invoke("sweep", str(sweep_file), "--out", str(directory / "out"))
    assert result.exit_code == 2
    for words in said:
        assert words in result.output
    assert "Traceback" not in result.output
    assert not (directory / "out").exists()


def one_episode(rule: Any, settings: Any, table_env: Any, features: Any, w: np.ndarray, w2: np.ndarray,
                epsilon: float, agent_rng: np.ndarray, env_rng: np.ndarray | None = None,
                transitions: np.ndarray | None = None) -> tuple[RunState, Records]:
    """One training episode of one run through the engine's ``train_block`` (its choice of the loop by the rule's
    type, and its snapshot, included): the weights ``w`` and ``w2`` and the streams given (the environment's and
    the transitions' by default from seeds 1000 and 2000, the evaluation's from 1001 to 1003, unused: no
    evaluation round). The state and the records it left."""
    from rlcompare.tabular.runs import train_block  # compiled code: only where a test trains

    rng = np.empty((1, STREAMS, 4), np.uint64)
    for stream, given, seed in ((ENV_STREAM, env_rng, 1000), (AGENT_STREAM, agent_rng, 0),
                                (TRANSITION_STREAM, transitions, 2000), (EVAL_ENV_STREAM, None, 1001),
                                (EVAL_AGENT_STREAM, None, 1002), (EVAL_TRANSITION_STREAM, None, 1003)):
        rng[0, stream] = stream_state(seed) if given is None else given
    state = RunState(w=w[None].copy(), w2=w2[None].copy(), rng=rng)
    records = allocate_records(1, 1, 0, 1, np.array([1], np.int64), w.shape)
    train_block(0, 1, rule, settings, table_env, features, state, np.array([epsilon]), 0, 1, records)
    return state, records


def digests(directory: Path) -> dict[str, str]:
    """Every file under ``directory`` and its SHA-256, by its path relative to ``directory``."""
    return {str(path.relative_to(directory)): hashlib.sha256(path.read_bytes()).hexdigest()
            for path in sorted(Path(directory).rglob("*")) if path.is_file()}


def paper_study(path: Path, seeds: int, episodes: int, **settings: Any) -> Path:
    """The paper's configurations on ``seeds`` seeds trained into the study directory ``path``."""
    from rlcompare.studies.paper.study import paper_configs, reproduce

    list(reproduce(path, paper_configs(tuple(range(seeds)), episodes, **settings)))
    return path


ENV = {**os.environ, "COLUMNS": "300"}


def start(command: list[str], log: Path, env: dict[str, str] = ENV) -> subprocess.Popen[bytes]:
    """``command`` in a process group of its own (killed whole), its output to ``log``, with SIGINT and SIGTERM as a
    terminal's process has them (:func:`default_signals`)."""
    with log.open("wb") as output:
        return subprocess.Popen(command, stdout=output, stderr=output, start_new_session=True, env=env,
                                preexec_fn=default_signals)


def default_signals() -> None:
    """In a child before it runs its command: SIGINT and SIGTERM at their default actions and not blocked. A child
    inherits an ignored or blocked signal from the process that starts it, and a test worker that has run the rest
    of the suite may hold them so: the signal tests then saw their Ctrl-C go unheard."""
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT, signal.SIGTERM})


def kill_when(process: subprocess.Popen[bytes], ready: Callable[[], bool], log: Path, timeout: float = 240) -> None:
    """Wait until ``ready()`` (the process still running), then kill its whole process group."""
    deadline = time.monotonic() + timeout
    while not ready() and time.monotonic() < deadline and process.poll() is None:
        time.sleep(0.02)
    assert process.poll() is None, log.read_text()
    os.killpg(process.pid, signal.SIGKILL)
    process.wait()


def finished_runs(study: Path) -> list[str]:
    """The runs of ``study`` that finished: those with ``meta.json``, written last."""
    return sorted(p.parent.name for p in study.glob(f"*/{rundir.META_FILE}"))


def assert_same_runs(resumed: Path, uninterrupted: Path, names: list[str]) -> None:
    """Each run ``names`` of one study directory equals the other's: every record of a tabular run, every episode,
    evaluation and parameter (final and at each stage) of a deep one."""
    for name in names:
        ours, theirs = load_run(resumed / name), load_run(uninterrupted / name)
        if isinstance(theirs, Results):
            for field in Records._fields:
                np.testing.assert_array_equal(getattr(ours.records, field), getattr(theirs.records, field),
                                              err_msg=f"{name}: {field}")
            continue
        pd.testing.assert_frame_equal(ours.episodes, theirs.episodes)
        pd.testing.assert_frame_equal(ours.evaluations, theirs.evaluations)
        assert ours.params.keys() == theirs.params.keys()
        assert ours.snapshots.keys() == theirs.snapshots.keys()
        for stage, arrays in [("final", theirs.params), *theirs.snapshots.items()]:
            mine = ours.params if stage == "final" else ours.snapshots[stage]
            for key, array in arrays.items():
                np.testing.assert_array_equal(mine[key], array, err_msg=f"{name}: {stage} {key}")
