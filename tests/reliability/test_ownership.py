"""Nothing a user owns is lost or overwritten, and no inconsistent result is trusted (issue 11).

Every case is tried as a clumsy or hostile user would: files outside rlcompare's own outputs must be
byte-identical afterwards, bad input ends with one line and exit code 2, and a run whose files do not belong
together is refused on load and trained again on resume.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from helpers import invoke
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rlcompare import ExperimentConfig, Results, load_agent, run
from rlcompare.experiment import rundir, store
from rlcompare.experiment.backends import LocalBackend
from rlcompare.experiment.engines import load_if_complete, load_run
from rlcompare.experiment.sweep import parse_sweep
from rlcompare.experiment.sweep_store import MANIFEST_FILE, load_configurations, run_sweep, trial_path
from rlcompare.studies.paper.study import paper_configs, reproduce

TINY = ExperimentConfig(algorithm="sarsa", seeds=(0, 1), episodes=30, eval_every=10, eval_episodes=2)
SWEEP = """
[sweep]
name = "own"
seeds = 2
[fixed]
episodes = 20
eval_every = 10
eval_episodes = 1
[grid]
algorithm = ["q_learning", "sarsa"]
"""


def snapshot(directory: Path) -> dict[str, str]:
    """Every file under ``directory`` (rlcompare's own markers aside) and its checksum."""
    return {str(p.relative_to(directory)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(directory.rglob("*")) if p.is_file()}


def user_files(directory: Path) -> dict[str, bytes]:
    """A user's own files, some with the names rlcompare writes."""
    files = {"config.json": b'{"mine": true}\n', "meta.json": b"{}\n", "report.html": b"<p>my report</p>",
             "notes.txt": b"do not lose", "figures/mine.png": b"\x89PNG mine", "manifest.json": b"{}"}
    for name, data in files.items():
        (directory / name).parent.mkdir(parents=True, exist_ok=True)
        (directory / name).write_bytes(data)
    return files


def assert_untouched(directory: Path, files: dict[str, bytes]) -> None:
    for name, data in files.items():
        assert (directory / name).read_bytes() == data, name


def one_clear_line(result) -> None:
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    assert isinstance(result.exception, SystemExit)


@pytest.fixture(scope="module")
def study(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("own") / "study"
    list(reproduce(path, paper_configs((0, 1), episodes=60, eval_every=30, eval_episodes=2)))
    return path


@pytest.fixture
def study_copy(study: Path, tmp_path: Path) -> Path:
    return Path(shutil.copytree(study, tmp_path / "study"))


# --- 1. names, and directories that hold something else ------------------------------------------------

@pytest.mark.slow("trains studies into directories it damages, fills or shares")
def test_sweep_into_a_study_directory_is_refused_and_report_builds_the_study(study_copy: Path, tmp_path: Path
                                                                           ) -> None:
    sweep_file = tmp_path / "s.toml"
    sweep_file.write_text(SWEEP)
    before = snapshot(study_copy)
    result = invoke("sweep", str(sweep_file), "--out", str(study_copy))
    one_clear_line(result)
    assert "the paper study" in result.output
    assert snapshot(study_copy) == before
    result = invoke("report", str(study_copy), "--no-videos")
    assert result.exit_code == 0, result.output
    assert "Paper" in (study_copy / "report.html").read_text() or "Table I" in (study_copy / "report.html").read_text()
    assert not (study_copy / MANIFEST_FILE).exists()


@pytest.mark.parametrize("command", ["run", "reproduce", "sweep"])
def test_a_directory_with_a_users_files_is_refused_and_left_as_it_was(command: str, tmp_path: Path) -> None:
    target = tmp_path / "mine"
    target.mkdir()
    files = user_files(target)
    sweep_file = tmp_path / "s.toml"
    sweep_file.write_text(SWEEP)
    args = {"run": ["run", "--episodes", "5", "--seeds", "1"],
            "reproduce": ["reproduce", "--allow-undecidable", "--episodes", "5", "--seeds", "1", "--no-videos"],
            "sweep": ["sweep", str(sweep_file)]}[command]
    result = invoke(*args, "--out", str(target))
    one_clear_line(result)
    assert "files rlcompare did not write" in result.output
    assert "--force" in result.output
    assert sorted(p.name for p in target.iterdir()) == sorted({n.split("/")[0] for n in files})
    assert_untouched(target, files)


def test_a_marker_whose_first_write_was_killed_is_written_again(tmp_path: Path) -> None:
    """A process killed while it wrote a directory's first marker leaves the marker's temporary file; the next
    claim removes it and writes the marker, and a user's file beside it is still refused and left alone."""
    owner = store.Owner("run", "x")
    interrupted = tmp_path / "interrupted"
    interrupted.mkdir()
    (interrupted / f".{store.MARKER_FILE}.k1ll3d.tmp").write_text('{"written_by": "rl')
    assert not store.claim(interrupted, owner)
    assert sorted(p.name for p in interrupted.iterdir()) == [store.MARKER_FILE]
    assert store.owner_of(interrupted) == owner

    beside = tmp_path / "beside"
    beside.mkdir()
    (beside / f".{store.MARKER_FILE}.k1ll3d.tmp").write_text("")
    (beside / "notes.txt").write_text("keep")
    with pytest.raises(store.StoreError, match=r"notes\.txt"):
        store.claim(beside, owner)
    assert sorted(p.name for p in beside.iterdir()) == [f".{store.MARKER_FILE}.k1ll3d.tmp", "notes.txt"]


@pytest.mark.slow("trains studies into directories it damages, fills or shares")
def test_force_writes_beside_a_users_files_but_never_over_them(tmp_path: Path) -> None:
    target = tmp_path / "mine"
    target.mkdir()
    (target / "notes.txt").write_text("keep")
    (target / "figures").mkdir()
    (target / "figures" / "mine.png").write_bytes(b"mine")
    args = ["reproduce", "--allow-undecidable", "--episodes", "20", "--seeds", "1", "--no-videos", "--out",
            str(target), "--force"]
    refused = invoke(*args)  # a figure's name is known only after training: refused before it (issue 39)
    one_clear_line(refused)
    assert "where it writes its own (figures/mine.png)" in refused.output
    (target / "figures" / "mine.png").rename(target / "mine.png")
    result = invoke(*args)
    assert result.exit_code == 0, result.output
    assert (target / "notes.txt").read_text() == "keep"
    assert (target / "mine.png").read_bytes() == b"mine"
    assert (target / "report.html").is_file()
    (target / "figures" / "mine.png").write_bytes(b"mine")
    again = invoke("report", str(target), "--no-videos")
    assert again.exit_code == 0, again.output
    assert (target / "figures" / "mine.png").read_bytes() == b"mine"  # the report's stale-figure sweep spares it

    run_dir = tmp_path / "run"
    run_dir.mkdir()
    files = user_files(run_dir)
    result = invoke("run", "--episodes", "5", "--seeds", "1", "--out", str(run_dir), "--force")
    one_clear_line(result)
    assert "config.json: a file rlcompare did not write" in result.output
    assert_untouched(run_dir, files)


@pytest.mark.slow("trains studies into directories it damages, fills or shares")
def test_a_report_deletes_only_the_figures_it_wrote(study_copy: Path) -> None:
    assert invoke("report", str(study_copy), "--no-videos").exit_code == 0
    (study_copy / "figures" / "mine.png").write_bytes(b"my figure")
    shutil.rmtree(study_copy / "random")  # its figure is now stale, and rlcompare's to delete
    result = invoke("report", str(study_copy), "--no-videos")
    assert result.exit_code == 2, result.output  # the missing run is named
    assert (study_copy / "figures" / "mine.png").read_bytes() == b"my figure"
    assert not (study_copy / "figures" / "fig3-random.png").exists()
    assert (study_copy / "figures" / "fig4-q_learning-constant.png").is_file()


@pytest.mark.parametrize("out", ["", " ", "x" * 300, "runs/" + "y" * 256 + "/run"])
def test_an_empty_or_overlong_out_is_one_clear_error(out: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
                                                     ) -> None:
    monkeypatch.chdir(tmp_path)
    result = invoke("run", "--episodes", "5", "--seeds", "1", "--out", out)
    one_clear_line(result)
    assert "--out" in result.output
    assert list(tmp_path.iterdir()) == []


def test_report_on_a_run_directory_writes_nothing_and_on_a_plain_directory_is_refused(study: Path,
                                                                                     tmp_path: Path) -> None:
    before = snapshot(study / "sarsa-decay")
    result = invoke("report", str(study / "sarsa-decay"))
    assert result.exit_code == 0, result.output  # a run's results are shown, its directory left as it is
    assert snapshot(study / "sarsa-decay") == before
    (tmp_path / "plain").mkdir()
    result = invoke("report", str(tmp_path / "plain"))
    one_clear_line(result)
    assert "not written by rlcompare" in result.output


def test_another_study_into_a_study_directory_is_refused(study_copy: Path) -> None:
    before = snapshot(study_copy)
    result = invoke("reproduce", "cliff", "--allow-undecidable", "--seeds", "1", "--out", str(study_copy))
    one_clear_line(result)
    assert snapshot(study_copy) == before


# --- 3. two processes, one store ------------------------------------------------------------------------

@pytest.mark.slow("trains studies into directories it damages, fills or shares")
def test_a_second_sweep_into_a_store_in_use_stops_and_the_first_runs_each_trial_once(tmp_path: Path) -> None:
    sweep_file = tmp_path / "s.toml"
    sweep_file.write_text(SWEEP.replace("seeds = 2", "seeds = 6").replace("episodes = 20", "episodes = 2000"))
    out = tmp_path / "store"
    command = [sys.executable, "-m", "rlcompare.cli", "sweep", str(sweep_file), "--out", str(out), "--workers", "1",
               "--no-report"]
    first = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120
        while not (out / MANIFEST_FILE).is_file() and time.monotonic() < deadline and first.poll() is None:
            time.sleep(0.05)
        os.kill(first.pid, signal.SIGSTOP)  # mid-sweep, its lock held, however long the second takes to start
        try:
            second = subprocess.run(command, capture_output=True, text=True, check=False, timeout=120)
        finally:
            os.kill(first.pid, signal.SIGCONT)
        first_out, first_err = first.communicate(timeout=300)
    finally:
        first.kill()
    assert first.returncode == 0, first_err
    assert second.returncode == 2, second.stdout + second.stderr
    assert "another rlcompare process" in second.stderr
    assert "Traceback" not in second.stderr
    assert "12 trials run, 0 already finished" in first_out
    configs, problems = load_configurations(out)
    assert not problems
    assert sorted(len(r.seeds) for r in configs.values()) == [6, 6]


def test_the_lock_is_released_when_its_holder_dies(tmp_path: Path) -> None:
    store.claim(tmp_path / "d", store.SWEEP)
    holder = subprocess.Popen([sys.executable, "-c", "import sys, time\nfrom rlcompare.experiment import store\n"
                               f"with store.locked({str(tmp_path / 'd')!r}):\n print('held', flush=True)\n"
                               " time.sleep(60)"], stdout=subprocess.PIPE, text=True)
    assert holder.stdout.readline().strip() == "held"
    with pytest.raises(store.StoreError, match=f"pid {holder.pid}"), store.locked(tmp_path / "d"):
        pass
    holder.kill()
    holder.wait()
    holder.stdout.close()
    with store.locked(tmp_path / "d"):
        pass


# --- 4, 5. files that do not belong together -------------------------------------------------------------

@pytest.mark.slow("trains studies into directories it damages, fills or shares")
def test_another_configurations_files_in_a_run_directory_are_refused_and_retrained(study_copy: Path) -> None:
    original = load_run(study_copy / "sarsa-decay")
    for name in (rundir.EPISODES_FILE, rundir.QTABLES_FILE):
        shutil.copyfile(study_copy / "q_learning-decay" / name, study_copy / "sarsa-decay" / name)
    with pytest.raises(store.StoreError, match=r"sarsa-decay/episodes\.parquet: does not belong to this run"):
        load_run(study_copy / "sarsa-decay")
    result = invoke("report", str(study_copy), "--no-videos")
    output = " ".join(result.output.split())  # the console wraps long paths where it likes
    assert "sarsa-decay" in output
    assert "does not belong to this run" in output
    assert result.exit_code == 2  # the rest is reported; what is missing is named
    again = {r.config.name: reused for r, reused in reproduce(study_copy, paper_configs(
        (0, 1), episodes=60, eval_every=30, eval_episodes=2))}
    assert [name for name, reused in again.items() if not reused] == ["sarsa-decay"]
    np.testing.assert_array_equal(load_run(study_copy / "sarsa-decay").records.returns, original.records.returns)


@pytest.mark.parametrize(("field", "value"), [("bins", 10), ("seeds", [5, 1]), ("alpha", 0.5)])
def test_an_edited_config_is_refused_by_load_and_load_agent(field: str, value, tmp_path: Path) -> None:
    run(TINY, out=tmp_path / "run")
    path = tmp_path / "run" / rundir.CONFIG_FILE
    data = store.read_json(path)
    data[field] = value
    path.write_text(json.dumps(data))
    for load in (lambda: load_run(tmp_path / "run"), lambda: load_agent(tmp_path / "run", seed=0)):
        with pytest.raises(store.StoreError, match=r"config\.json: does not belong to this run"):
            load()
    assert load_if_complete(tmp_path / "run", TINY) is None


def test_a_run_written_without_a_record_of_its_contents_is_not_trusted(tmp_path: Path) -> None:
    run(TINY, out=tmp_path / "run")
    meta = store.read_json(tmp_path / "run" / rundir.META_FILE)
    del meta["contents"]
    (tmp_path / "run" / rundir.META_FILE).write_text(json.dumps(meta))
    with pytest.raises(store.StoreError, match="no record of the run's contents"):
        load_run(tmp_path / "run")


@pytest.fixture(scope="module")
def small_sweep(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("sweep") / "store"
    run_sweep(parse_sweep(SWEEP), SWEEP, out, LocalBackend(2))
    return out


@pytest.mark.slow("trains a sweep's trials")
def test_a_copied_or_corrupt_trial_is_redone_on_resume(small_sweep: Path, tmp_path: Path) -> None:
    out = Path(shutil.copytree(small_sweep, tmp_path / "store"))
    trials = parse_sweep(SWEEP).trials()
    dirs = [trial_path(out, t.config_hash, t.seed) for t in trials]
    for name in rundir.RUN_FILES:  # trial 0's files into trial 1's directory
        shutil.copyfile(dirs[0] / name, dirs[1] / name)
    data = bytearray((dirs[2] / rundir.EPISODES_FILE).read_bytes())
    data[len(data) // 2] ^= 0xFF
    (dirs[2] / rundir.EPISODES_FILE).write_bytes(bytes(data))
    _, problems = load_configurations(out)
    assert sum("left out" in p for p in problems) == 2
    result = invoke("report", str(out))
    assert result.exit_code == 0, result.output
    assert result.output.count("left out") == 2
    assert run_sweep(parse_sweep(SWEEP), SWEEP, out, LocalBackend(1)) == (2, 2)
    for trial_dir in dirs:
        assert snapshot(trial_dir)[rundir.EPISODES_FILE] == snapshot(small_sweep / trial_dir.relative_to(out))[
            rundir.EPISODES_FILE]
    assert load_configurations(out)[1] == []


@pytest.fixture(scope="module")
def two_runs(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, Results]:
    root = tmp_path_factory.mktemp("fuzz")
    first = run(TINY, out=root / "a")
    run(ExperimentConfig(algorithm="q_learning", seeds=(0, 1), episodes=30, eval_every=10, eval_episodes=2),
        out=root / "b")
    return root / "a", root / "b", first


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(damage=st.one_of(
    st.tuples(st.just("flip"), st.sampled_from(rundir.RUN_FILES), st.floats(0, 1, exclude_max=True),
              st.integers(1, 255)),
    st.tuples(st.just("truncate"), st.sampled_from(rundir.RUN_FILES), st.floats(0, 1, exclude_max=True),
              st.just(0)),
    st.tuples(st.just("swap"), st.sampled_from(rundir.RUN_FILES), st.just(0.0), st.just(0)),
))
def test_a_damaged_run_directory_is_refused_or_reads_exactly_as_written(damage, two_runs) -> None:
    """Random byte flips, truncations and files swapped in from another run: ``load`` raises a StoreError
    naming the problem, or returns exactly the records that were written (a flip in a timestamp, say)."""
    source, other, written = two_runs
    kind, name, where, mask = damage
    with tempfile.TemporaryDirectory() as scratch:
        run_dir = Path(shutil.copytree(source, Path(scratch) / "run"))
        path = run_dir / name
        data = bytearray(path.read_bytes())
        if kind == "flip":
            data[int(where * len(data))] ^= mask
            path.write_bytes(bytes(data))
        elif kind == "truncate":
            path.write_bytes(bytes(data[: int(where * len(data))]))
        else:
            shutil.copyfile(other / name, path)
        try:
            loaded = load_run(run_dir)
        except store.StoreError:
            return
        for field, array in written.records._asdict().items():
            np.testing.assert_array_equal(getattr(loaded.records, field), array, err_msg=field)
        assert loaded.config == written.config


# --- 8, 9, 10. sizes, full disks, read-only directories, failed runs -------------------------------------

@pytest.mark.parametrize(("name", "message"), [(rundir.CONFIG_FILE, "not a file of this run"),
                                                (rundir.META_FILE, "more than rlcompare writes")])
def test_an_oversized_metadata_file_is_refused_unread(name: str, message: str, tmp_path: Path) -> None:
    run(TINY, out=tmp_path / "run")
    (tmp_path / "run" / name).write_text('{"algorithm": "' + "x" * (store.MAX_JSON_BYTES + 10) + '"}')
    started = time.perf_counter()
    with pytest.raises(store.StoreError, match=message) as error:
        load_run(tmp_path / "run")
    assert time.perf_counter() - started < 5
    assert len(str(error.value)) < 300
    result = invoke("report", str(tmp_path / "run"))
    assert len(result.output) < 1000


def test_a_run_that_fails_leaves_no_directory_behind(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from rlcompare.tabular import front

    def interrupted(*args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(front, "train", interrupted)
    result = invoke("run", "--episodes", "5", "--seeds", "1", "--out", str(tmp_path / "new"))
    one_clear_line(result)
    assert "No space left on device" in result.output
    assert not (tmp_path / "new").exists()


@contextlib.contextmanager
def small_filesystem(path: Path, size: str = "256k") -> Iterator[Path]:
    """A tmpfs of ``size`` at ``path`` (needs root: skipped elsewhere)."""
    path.mkdir()
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(path)],
                             capture_output=True, check=False)
    if mounted.returncode:
        pytest.skip("cannot mount a small file system here (needs root)")
    try:
        yield path
    finally:
        subprocess.run(["umount", "-l", str(path)], check=False)


def fill(filesystem: Path) -> None:
    fd = os.open(filesystem / "filler", os.O_WRONLY | os.O_CREAT)
    with contextlib.suppress(OSError):
        while True:
            os.write(fd, b"\0" * 4096)
    os.close(fd)


FULL_DISK_COMMANDS = {
    "run": ["run", "--episodes", "50", "--seeds", "2"],
    "report": ["report"],
    "sweep": ["sweep"],
    "why": ["reproduce", "why", "--allow-undecidable", "--seeds", "2", "--episodes", "50"],
    "book-6.3": ["reproduce", "book-6.3", "--allow-undecidable", "--runs", "2"],
    "cliff": ["reproduce", "cliff", "--allow-undecidable", "--seeds", "2"],
    "sensitivity": ["reproduce", "sensitivity", "--allow-undecidable", "--seeds", "2", "--episodes", "50"],
    "deep": ["reproduce", "deep", "--allow-undecidable", "--seeds", "2", "--steps", "41000", "--methods",
             "pqn_q_lambda,pqn_sarsa_lambda",
             "--envs", "CartPole-v1"],
    "minatar": ["reproduce", "minatar", "--allow-undecidable", "--seeds", "2", "--games", "breakout", "--steps",
                "40960"],
}


@pytest.mark.parametrize("command", FULL_DISK_COMMANDS)
def test_a_full_disk_is_one_clear_error(command: str, study: Path, tmp_path: Path) -> None:
    sweep_file = tmp_path / "s.toml"
    sweep_file.write_text(SWEEP)
    with small_filesystem(tmp_path / "fs", "2m") as fs:
        if command == "report":
            shutil.copytree(study, fs / "study", ignore=shutil.ignore_patterns("figures", "tables", "report.html"))
        fill(fs)
        where = {"report": [str(fs / "study"), "--no-videos"],
                 "sweep": [str(sweep_file), "--out", str(fs / "store")]}.get(command, ["--out", str(fs / "out")])
        result = invoke(*FULL_DISK_COMMANDS[command], *where)
        one_clear_line(result)
        assert "no space left" in result.output.lower()
        assert not (fs / "out").exists()


@pytest.mark.slow("trains studies into directories it damages, fills or shares")
def test_a_disk_that_fills_mid_study_keeps_the_finished_runs_and_resumes_once_there_is_room(tmp_path: Path) -> None:
    """``reproduce why`` on a file system with room for a few of its 12 runs (each about 180 kB): one clear line
    when a run cannot be written, every run written before it kept and whole; with room again, the same command
    loads those, trains the rest, and writes the tables of an uninterrupted study byte for byte."""
    from helpers import assert_same_runs, finished_runs

    why = ["reproduce", "why", "--allow-undecidable", "--seeds", "6", "--episodes", "1000"]
    reference = tmp_path / "reference"
    assert invoke(*why, "--out", str(reference)).exit_code == 0
    with small_filesystem(tmp_path / "fs", "900k") as fs:
        full = invoke(*why, "--out", str(fs / "why"))
        one_clear_line(full)
        assert "no space left" in full.output.lower()
        kept = finished_runs(fs / "why")
        assert 1 <= len(kept) < 12
        assert_same_runs(fs / "why", reference, kept)
        subprocess.run(["mount", "-o", "remount,size=8m", str(fs)], check=True)
        again = invoke(*why, "--out", str(fs / "why"))
        assert again.exit_code == 0, again.output
        assert again.output.count("loaded (already complete)") == len(kept)
        assert finished_runs(fs / "why") == finished_runs(reference)
        assert_same_runs(fs / "why", reference, finished_runs(reference))
        for table in (reference / "tables").iterdir():
            assert (fs / "why" / "tables" / table.name).read_bytes() == table.read_bytes(), table.name


def test_report_in_a_read_only_directory_is_one_clear_error(study: Path, tmp_path: Path) -> None:
    with small_filesystem(tmp_path / "fs", "8m") as fs:
        shutil.copytree(study, fs / "study")
        before = snapshot(fs / "study")
        subprocess.run(["mount", "-o", "remount,ro", str(fs)], check=True)
        result = invoke("report", str(fs / "study"), "--no-videos")
        one_clear_line(result)
        assert "Read-only file system" in result.output
        assert snapshot(fs / "study") == before


def test_the_lock_file_of_a_directory_in_use_names_its_process(tmp_path: Path) -> None:
    with store.output_directory(tmp_path / "d", store.RUN):
        assert (tmp_path / "d" / store.LOCK_FILE).read_text().strip() == str(os.getpid())
