"""Sweeps: the file and its validation, the store, the local backend, resuming, and a kill in the middle."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import tomli_w
from helpers import assert_each_once, assert_sweep_refused, invoke
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rlcompare import run
from rlcompare.experiment import rundir, store
from rlcompare.experiment.backends import LocalBackend
from rlcompare.experiment.sweep import SweepError, derive_seeds, load_sweep, parse_sweep
from rlcompare.experiment.sweep_store import (
    MANIFEST_FILE,
    SweepStore,
    load_configurations,
    read_manifest,
    read_table,
    run_sweep,
    trial_path,
)
from rlcompare.tabular.front import SWEEP_KEYS as CONFIG_KEYS
from rlcompare.tabular.state import Records

EXAMPLE = Path(__file__).parents[2] / "examples" / "sweep.toml"
SMALL = """
[sweep]
name = "small"
root_seed = 7
seeds = 3

[fixed]
episodes = 30
eval_every = 15
eval_episodes = 2

[grid]
algorithm = ["q_learning", "sarsa"]
alpha = [0.05, 0.2]

[[include]]
env = "CliffWalking-v1"
algorithm = "sarsa"
alpha = 0.5
"""


def _assert_same_records(a: Records, b: Records) -> None:
    for name in Records._fields:
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


# --- the sweep file -------------------------------------------------------------------------------------


def test_example_sweep_is_a_grid_plus_its_includes() -> None:
    sweep = load_sweep(EXAMPLE)
    assert (sweep.name, len(sweep.configs), len(sweep.seeds)) == ("alpha", 2 * 2 * 2 * 3 + 1, 10)
    assert sweep.swept == ("algorithm", "schedule", "env", "alpha")
    assert {c.env for c in sweep.configs} == {"MountainCar-v0", "CartPole-v1", "Acrobot-v1"}
    assert all(c.episodes == 1000 and c.gamma == 0.9 for c in sweep.configs)
    assert (sweep.configs[-1].env, sweep.configs[-1].alpha) == ("Acrobot-v1", 0.1)


def test_every_configuration_gets_the_same_seeds_derived_from_the_root_seed() -> None:
    """Seeds come from ``SeedSequence(root_seed).spawn(n)``: the order trials run in cannot change them, and
    configurations are paired on them."""
    sweep = parse_sweep(SMALL)
    children = np.random.SeedSequence(7).spawn(3)
    assert sweep.seeds == tuple(int(c.generate_state(1, np.uint64)[0] >> np.uint64(1)) for c in children)
    assert sweep.seeds == derive_seeds(7, 3) != derive_seeds(8, 3)
    trials = sweep.trials()
    assert len(trials) == 5 * 3
    assert [t.seed for t in trials[:5]] == [sweep.seeds[0]] * 5  # seed by seed, every configuration first
    assert len({t.trial_id for t in trials}) == 15
    assert len({t.config_hash for t in trials}) == 5


def test_a_sweep_file_with_many_mistakes_reports_each_one_with_its_path() -> None:
    text = """
[sweep]
seeds = 0
colour = "red"
[fixed]
alpha = 2
gamma = "high"
seeds = 4
[grid]
algorithm = ["q_learning", "dqn"]
bins = [20, [1, 2, 3]]
gama = [0.9]
episodes = 5
[extra]
"""
    with pytest.raises(SweepError) as caught:
        parse_sweep(text, "bad.toml")
    problems = caught.value.problems
    assert_each_once(problems, [
        "extra: unknown section",
        "sweep.colour: unknown key; allowed: name, root_seed, seeds",
        "sweep.seeds: got 0",
        "fixed.seeds: the seeds are set once",
        "grid.gama: unknown key; allowed: algorithm",
        "grid.episodes: got 5; allowed: a non-empty list of values",
        "fixed.alpha: got 2; allowed: a number in (0, 1]",
        "fixed.gamma: got 'high'; allowed: a number in [0, 1]",
        "grid.algorithm[1]: got 'dqn'; allowed: random, q_learning",
        "grid.bins[1]: got (1, 2, 3); allowed: an integer >= 1, or 2 of them",
    ])
    assert str(caught.value).startswith("bad.toml: 10 problems")


def test_a_value_wrong_only_in_combination_names_the_combination() -> None:
    """CartPole's 4 bins are right for CartPole and wrong for Acrobot; α = 1.5 is wrong everywhere. A
    problem is reported once, with the combination only where the value is fine elsewhere."""
    text = '[grid]\nenv = ["CartPole-v1", "Acrobot-v1"]\nbins = [[1, 1, 6, 12], 5]\nalpha = [0.1, 1.5]\n'
    with pytest.raises(SweepError) as caught:
        parse_sweep(text)
    assert caught.value.problems == [
        "grid.alpha[1]: got 1.5; allowed: a number in (0, 1]",
        "grid.bins[0]: got (1, 1, 6, 12); allowed: an integer >= 1, or 6 of them (one per observation dimension of "
        "Acrobot-v1) (with env = 'Acrobot-v1', alpha = 0.1)",
    ]
    assert len(parse_sweep('[grid]\nenv = ["CartPole-v1"]\nbins = [[1, 1, 6, 12]]\n').configs) == 1


@pytest.mark.parametrize("text", ["[grid\n", "alpha = ", "[sweep]\nseeds = 1e400\n", "x = 1\n[x]\n"])
def test_text_that_is_not_toml_or_not_a_sweep_is_one_clear_error(text: str) -> None:
    with pytest.raises(SweepError):
        parse_sweep(text)


KEYS = st.sampled_from([*CONFIG_KEYS, "seeds", "name", "root_seed", "colour"])
SCALARS = st.one_of(st.integers(-2**70, 2**70), st.floats(allow_nan=True), st.booleans(), st.text(max_size=12),
                    st.sampled_from(["q_learning", "sarsa", "CartPole-v1", "Taxi-v4", "tiles", "decay", "Nope-v0"]))
VALUES = st.recursive(SCALARS, lambda inner: st.lists(inner, max_size=3) | st.dictionaries(KEYS, inner, max_size=3),
                      max_leaves=8)
TABLE = st.dictionaries(KEYS, VALUES, max_size=4)
DOCUMENTS = st.fixed_dictionaries({}, optional={
    "sweep": TABLE, "fixed": TABLE, "grid": st.dictionaries(KEYS, st.lists(VALUES, max_size=3) | VALUES, max_size=3),
    "include": st.lists(TABLE, max_size=2), "other": TABLE,
})


def _toml(document: dict) -> str | None:
    try:
        return tomli_w.dumps(document)
    except (TypeError, ValueError):  # values TOML cannot hold (mixed arrays are fine; None is not)
        return None


@pytest.mark.slow("runs sweeps")
@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(DOCUMENTS)
def test_no_sweep_document_makes_the_loader_raise_anything_but_its_own_error(document: dict) -> None:
    text = _toml(document)
    if text is None:
        return
    outcome = _parse_or_error(text)
    if isinstance(outcome, SweepError):
        assert all(isinstance(p, str) for p in outcome.problems)
        assert outcome.problems
    else:
        assert outcome.configs
        assert all(c.seeds == outcome.seeds for c in outcome.configs)


@settings(max_examples=200, deadline=None)
@given(st.text(max_size=200))
def test_no_text_makes_the_loader_raise_anything_but_its_own_error(text: str) -> None:
    outcome = _parse_or_error(text)
    assert not isinstance(outcome, SweepError) or outcome.problems


def _parse_or_error(text: str):
    """The sweep, or the loader's own error; anything else it raises fails the test."""
    try:
        return parse_sweep(text)
    except SweepError as error:
        return error


# --- the store and the local backend ------------------------------------------------------------------


@pytest.fixture(scope="module")
def small_store(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("small") / "store"
    finished, ran = run_sweep(parse_sweep(SMALL), SMALL, out, LocalBackend(2))
    assert (finished, ran) == (0, 15)
    return out


def test_each_trial_is_stored_once_and_equals_a_run_of_its_configuration(small_store: Path) -> None:
    sweep = parse_sweep(SMALL)
    manifest = json.loads((small_store / MANIFEST_FILE).read_text())
    assert [t["status"] for t in manifest["trials"]] == ["done"] * 15
    assert sorted(p.relative_to(small_store).as_posix() for p in (small_store / "trials").glob("*/*")) == sorted(
        f"trials/config={t.config_hash}/trial={t.seed}" for t in sweep.trials())
    for trial in sweep.trials()[::4]:
        stored = store.read_json(trial_path(small_store, trial.config_hash, trial.seed) / rundir.CONFIG_FILE)
        assert stored == trial.config.to_dict()
    configs, missing = load_configurations(small_store)
    assert missing == []
    for config in sweep.configs:
        from rlcompare.experiment.sweep import config_hash

        _assert_same_records(configs[config_hash(config)].records, run(config).records)


def test_the_store_reads_as_one_partitioned_dataset_with_the_swept_values(small_store: Path) -> None:
    episodes = read_table(small_store)
    assert len(episodes) == 15 * 30
    assert episodes.groupby(["config", "seed"]).size().eq(30).all()  # every trial once
    assert set(episodes.columns) >= {"config", "seed", "episode", "return", "algorithm", "alpha", "env"}
    assert sorted(episodes["alpha"].unique()) == [0.05, 0.2, 0.5]
    evaluations = read_table(small_store, rundir.EVALUATIONS_FILE)
    assert len(evaluations) == 15 * 2 * 2


def test_results_do_not_depend_on_the_number_of_workers(small_store: Path, tmp_path: Path) -> None:
    run_sweep(parse_sweep(SMALL), SMALL, tmp_path / "one", LocalBackend(1))
    ours, theirs = load_configurations(small_store)[0], load_configurations(tmp_path / "one")[0]
    assert ours.keys() == theirs.keys()
    for key in ours:
        _assert_same_records(ours[key].records, theirs[key].records)


@pytest.mark.slow("runs sweeps")
def test_rerun_skips_finished_trials_and_runs_what_is_missing_or_partial(small_store: Path, tmp_path: Path) -> None:
    out = tmp_path / "copy"
    import shutil

    shutil.copytree(small_store, out)
    trials = parse_sweep(SMALL).trials()
    shutil.rmtree(trial_path(out, trials[0].config_hash, trials[0].seed))  # never ran
    (trial_path(out, trials[1].config_hash, trials[1].seed) / rundir.META_FILE).unlink()  # killed before meta.json
    (out / "trials" / f"config={trials[2].config_hash}" / f"trial={trials[2].seed}" / ".episodes.parquet.x.tmp"
     ).write_bytes(b"half")
    assert run_sweep(parse_sweep(SMALL), SMALL, out, LocalBackend(2)) == (13, 2)
    assert not list(out.glob("trials/*/*/.*.tmp"))
    assert run_sweep(parse_sweep(SMALL), SMALL, out, LocalBackend(2)) == (15, 0)
    for key, results in load_configurations(small_store)[0].items():
        _assert_same_records(results.records, load_configurations(out)[0][key].records)


def test_a_grown_sweep_runs_only_its_new_trials(small_store: Path, tmp_path: Path) -> None:
    import shutil

    shutil.copytree(small_store, tmp_path / "grown")
    grown = SMALL.replace("alpha = [0.05, 0.2]", "alpha = [0.05, 0.2, 0.1]")
    assert run_sweep(parse_sweep(grown), grown, tmp_path / "grown", LocalBackend(2)) == (15, 6)


@pytest.mark.slow("runs sweeps")
def test_sweep_killed_with_sigkill_resumes_to_the_uninterrupted_result(small_store: Path, tmp_path: Path) -> None:
    """The command line, killed with SIGKILL once some trials are saved, then run again: every trial once, each
    equal to the uninterrupted run's, and nothing left behind that looks finished."""
    sweep_file = tmp_path / "slow.toml"
    sweep_file.write_text(SMALL.replace("episodes = 30", "episodes = 400").replace("seeds = 3", "seeds = 4"))
    out = tmp_path / "killed"
    command = [sys.executable, "-m", "rlcompare.cli", "sweep", str(sweep_file), "--out", str(out), "--workers", "2",
               "--no-report"]
    log = tmp_path / "killed.log"
    with log.open("wb") as output:
        process = subprocess.Popen(command, stdout=output, stderr=output, start_new_session=True)
    deadline = time.monotonic() + 240
    done = 0
    while done < 4 and time.monotonic() < deadline and process.poll() is None:
        time.sleep(0.05)
        done = len(list(out.glob("trials/*/*/meta.json")))
    assert process.poll() is None, log.read_text()
    os.killpg(process.pid, signal.SIGKILL)
    process.wait()
    sweep = load_sweep(sweep_file)
    finished = [t for t in sweep.trials() if rundir.is_complete(trial_path(out, t.config_hash, t.seed))]
    assert 4 <= len(finished) < 20
    for trial in sweep.trials():  # a directory without meta.json is never read as a finished trial
        trial_dir = trial_path(out, trial.config_hash, trial.seed)
        if trial_dir.exists() and trial not in finished:
            assert not (trial_dir / rundir.META_FILE).exists()
    again = subprocess.run(command, capture_output=True, text=True, check=False)
    assert again.returncode == 0, again.stderr
    assert f"{20 - len(finished)} trials run, {len(finished)} already finished" in again.stdout
    resumed, _ = load_configurations(out)
    reference, _ = load_configurations(_uninterrupted(sweep_file, tmp_path / "reference"))
    assert resumed.keys() == reference.keys()
    for key in reference:
        assert resumed[key].seeds == reference[key].seeds
        _assert_same_records(resumed[key].records, reference[key].records)
    assert read_table(out).groupby(["config", "seed"]).size().eq(400).all()


def _uninterrupted(sweep_file: Path, out: Path) -> Path:
    run_sweep(load_sweep(sweep_file), sweep_file.read_text(), out, LocalBackend(2))
    return out


# --- the command line and the report ------------------------------------------------------------------


@pytest.mark.slow("runs sweeps")
def test_sweep_command_runs_reports_and_groups(tmp_path: Path) -> None:
    sweep_file = tmp_path / "small.toml"
    sweep_file.write_text(SMALL)
    result = invoke("sweep", str(sweep_file), "--out", str(tmp_path / "out"), "--workers", "2",
                                     "--group-by", "algorithm")
    assert result.exit_code == 0, result.output
    assert "small: 5 configurations x 3 seeds = 15 trials on the local backend" in result.output
    table = pd.read_csv(tmp_path / "out" / "tables" / "configurations.csv")
    assert len(table) == 5
    assert set(table.columns) >= {"algorithm", "alpha", "env", "behaviour mean", "greedy mean"}
    assert (tmp_path / "out" / "tables" / "by-algorithm-sarsa.csv").is_file()
    assert (tmp_path / "out" / "figures" / "across-alpha.png").is_file()
    html = (tmp_path / "out" / "report.html").read_text()
    assert "Sweep: small" in html
    assert "15 of 15 trials finished" in html
    from rlcompare.report.findings import BEHAVIOUR_AND_GREEDY

    assert BEHAVIOUR_AND_GREEDY in html  # a tabular sweep shows both returns, so it says why they differ
    again = invoke("report", str(tmp_path / "out"), "--group-by", "env")
    assert again.exit_code == 0, again.output
    assert (tmp_path / "out" / "tables" / "by-env-CliffWalking-v1.csv").is_file()


@pytest.mark.parametrize(("args", "message"), [
    (["--backend", "spark"], "allowed: local, ray"),
    (["--workers", "0"], "allowed: an integer >= 1"),
    (["--group-by", "gamma"], "allowed: a swept key (algorithm, env, alpha)"),
])
def test_sweep_command_rejects_bad_options_before_running(args: list[str], message: str, tmp_path: Path) -> None:
    sweep_file = tmp_path / "small.toml"
    sweep_file.write_text(SMALL)
    result = invoke("sweep", str(sweep_file), "--out", str(tmp_path / "out"), *args)
    assert result.exit_code == 2
    assert message in result.output
    assert not (tmp_path / "out").exists()


def test_sweep_command_prints_every_problem_of_a_bad_file(tmp_path: Path) -> None:
    assert_sweep_refused(tmp_path, '[fixed]\nalpha = 3\n[grid]\nalgorithm = ["dqn"]\n',
                         "fixed.alpha: got 3; allowed: a number in (0, 1]", "grid.algorithm[0]: got 'dqn'")
    missing = invoke("sweep", str(tmp_path / "none.toml"))
    assert missing.exit_code == 2
    assert "cannot read the file" in missing.output


def test_store_open_names_no_trial_twice(tmp_path: Path) -> None:
    sweep = parse_sweep(SMALL)
    todo = SweepStore(tmp_path).open(sweep, SMALL)
    assert len(todo) == len({t.trial_id for t in todo}) == 15
    assert todo[0].config == replace(sweep.configs[0], seeds=(sweep.seeds[0],))
    manifest = read_manifest(tmp_path)
    assert [t["id"] for t in manifest["trials"]] == [t.trial_id for t in todo]
    assert {t["status"] for t in manifest["trials"]} == {"pending"}


def test_ray_backend_without_a_cluster_is_one_clear_error(tmp_path: Path) -> None:
    pytest.importorskip("ray")
    sweep_file = tmp_path / "small.toml"
    sweep_file.write_text(SMALL)
    with socket.socket() as probe:  # a port where nothing listens
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    result = invoke("sweep", str(sweep_file), "--out", str(tmp_path / "out"), "--backend", "ray",
                                     "--address", f"127.0.0.1:{port}")
    assert result.exit_code == 2
    assert f"no Ray cluster at '127.0.0.1:{port}'" in result.output
    assert "Traceback" not in result.output
    assert not (tmp_path / "out").exists()  # nothing written for a sweep that could not start
