"""Deep sweeps: ``engine = "deep"`` in a sweep file, its validation, trials of the deep engine on the local and Ray
backends, resuming, merging per configuration, and the report's table."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import tomli_w
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

pytest.importorskip("jax")

from helpers import assert_each_once, assert_sweep_refused, invoke

from rlcompare.deep import INSTALL_HINT
from rlcompare.deep.config import DeepConfig
from rlcompare.deep.front import SWEEP_KEYS as DEEP_KEYS
from rlcompare.deep.results import DeepResults
from rlcompare.experiment import rundir, store
from rlcompare.experiment.engines import load_run
from rlcompare.experiment.sweep import SweepError, config_dict, config_hash, parse_sweep
from rlcompare.experiment.sweep_store import MANIFEST_FILE, load_configurations, read_table, trial_path
from rlcompare.studies.sweep_report import PANELS, across_figure, deep_configuration_rows, deep_metrics

TINY = """
[sweep]
name = "deep-tiny"
engine = "deep"
root_seed = 1
seeds = 2

[fixed]
env = "CartPole-v1"
eval_rounds = 2
eval_episodes = 2
hyperparameters.total_steps = 4096      # 2 rounds x 16 environments x 128 steps

[grid]
algorithm = ["pqn_q_lambda", "pqn_sarsa_lambda"]
"""
EXAMPLE = Path(__file__).parents[2] / "examples" / "sweep-deep.toml"


def _problems(text: str) -> list[str]:
    with pytest.raises(SweepError) as caught:
        parse_sweep(text)
    return caught.value.problems


def _assert_same(a: DeepResults, b: DeepResults) -> None:
    assert a.seeds == b.seeds
    pd.testing.assert_frame_equal(a.episodes, b.episodes)
    pd.testing.assert_frame_equal(a.evaluations, b.evaluations)
    assert a.params.keys() == b.params.keys()
    for name in a.params:
        np.testing.assert_array_equal(a.params[name], b.params[name], err_msg=name)


# --- the sweep file -------------------------------------------------------------------------------------


def test_a_deep_sweep_is_deep_configurations_of_one_seed_each() -> None:
    sweep = parse_sweep(TINY)
    assert (sweep.engine, sweep.swept, len(sweep.configs), len(sweep.trials())) == ("deep", ("algorithm",), 2, 4)
    assert all(isinstance(c, DeepConfig) and c.vmap_width == 1 and c.eval_rounds == 2 for c in sweep.configs)
    assert sweep.configs[0].hyperparameters == {"total_steps": 4096}
    trial = sweep.trials()[0]
    assert trial.config.seeds == (sweep.seeds[0],)
    assert config_dict(trial.config)["engine"] == "deep"
    assert len({config_hash(c) for c in sweep.configs}) == 2


def test_the_example_deep_sweep_is_valid() -> None:
    sweep = parse_sweep(EXAMPLE.read_text())
    assert sweep.engine == "deep"
    assert "hyperparameters.lam" in sweep.swept


def test_hyperparameters_are_a_dotted_key_in_every_section_and_swept_by_name() -> None:
    text = """
[sweep]
engine = "deep"
[fixed]
hyperparameters.total_steps = 4096
eval_rounds = 2
[grid]
hyperparameters.lam = [0, 0.5]
[[include]]
hyperparameters = {lam = 0.9, gamma = 0.95}
"""
    sweep = parse_sweep(text)
    assert sweep.swept == ("hyperparameters.lam", "hyperparameters.gamma")
    assert [c.hyperparameters for c in sweep.configs] == [
        {"total_steps": 4096, "lam": 0.0}, {"total_steps": 4096, "lam": 0.5},
        {"total_steps": 4096, "lam": 0.9, "gamma": 0.95}]
    assert isinstance(sweep.configs[0].hyperparameters["lam"], float)  # 0 is 0.0, one configuration either way


def test_a_deep_sweep_file_reports_every_mistake_with_its_path() -> None:
    text = """
[sweep]
engine = "deep"
[fixed]
alpha = 0.1
vmap_width = 4
seeds = 3
hyperparameters.total_steps = 4096
eval_rounds = 2
[grid]
algorithm = ["pqn_q_lambda", "q_learning"]
hyperparameters.lam = [0.5, 2]
hyperparameters.colour = [1]
hyperparameters.gamma = 0.9
[[include]]
hyperparameters = 5
"""
    problems = _problems(text)
    assert_each_once(problems, [
        f"fixed.alpha: unknown key; allowed: {', '.join(DEEP_KEYS)}, hyperparameters.NAME",
        "fixed.vmap_width: fixed at 1 in a sweep (each trial trains one seed)",
        "fixed.seeds: the seeds are set once",
        "grid.hyperparameters.gamma: got 0.9; allowed: a non-empty list of values",
        "include[0].hyperparameters: got 5; allowed: a table of the method's hyperparameters",
        "grid.algorithm[1]: got 'q_learning'; allowed: pqn_q_lambda, pqn_sarsa_lambda,",
        "grid.hyperparameters.lam[1]: got 2; allowed: a number in [0, 1]",
        "grid.hyperparameters.colour: unknown key; allowed: the fields of PQNConfig:",
    ])


def test_a_hyperparameter_wrong_only_with_other_values_names_the_combination() -> None:
    """4096 steps are 2 rollouts: enough for 2 evaluation rounds, not for 3."""
    text = ('[sweep]\nengine = "deep"\n[fixed]\nhyperparameters.total_steps = 4096\n'
            '[grid]\neval_rounds = [2, 3]\n')
    assert _problems(text) == ["fixed.hyperparameters.total_steps: got 4096; allowed: at least 6,144, the fewest that "
                               "train in each of the 3 evaluation rounds (at least 3 rollouts of n_envs x n_steps = "
                               "2048 steps) (with eval_rounds = 3)"]


def test_a_hyperparameter_set_to_its_preset_value_is_the_same_configuration() -> None:
    text = '[sweep]\nengine = "deep"\n[grid]\nhyperparameters.lam = [0.95, 0.5]\n[[include]]\n'
    assert _problems(text) == ["include[0]: the same configuration as grid (hyperparameters.lam = 0.95); allowed: "
                               "each configuration once"]


def test_an_unknown_engine_is_one_problem() -> None:
    assert _problems('[sweep]\nengine = "torch"\n[grid]\nalgorithm = ["dqn"]\n') == [
        "sweep.engine: got 'torch'; allowed: tabular, deep"]


def test_without_the_deep_extra_a_deep_sweep_is_one_line_saying_how_to_install_it(
        monkeypatch: pytest.MonkeyPatch) -> None:
    for name in [name for name in sys.modules if name.startswith("rlcompare.deep")]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "jax", None)  # import jax fails, as where JAX is not installed
    problems = _problems(TINY)
    assert len(problems) == 1
    assert problems[0].startswith(f"sweep.engine: {INSTALL_HINT}")


def test_the_sweep_command_prints_every_problem_of_a_deep_file(tmp_path: Path) -> None:
    assert_sweep_refused(tmp_path, '[sweep]\nengine = "deep"\n[fixed]\nhyperparameters.lam = "high"\n'
                         '[grid]\nalgorithm = ["sarsa"]\nbatch = [1]\n',
                         "grid.algorithm[0]: got 'sarsa'; allowed: pqn_q_lambda", "grid.batch: unknown key")


KEYS = st.sampled_from([*DEEP_KEYS, "seeds", "vmap_width", "hyperparameters", "alpha"])
NAMES = st.sampled_from(["lam", "gamma", "total_steps", "hidden", "target", "double", "colour"])
SCALARS = st.one_of(st.integers(-2**70, 2**70), st.floats(allow_nan=True), st.booleans(), st.text(max_size=8),
                    st.sampled_from(["pqn_q_lambda", "dqn", "ppo", "CartPole-v1", "zoo", "default", "Nope-v0"]))
VALUES = st.recursive(SCALARS, lambda inner: st.lists(inner, max_size=3), max_leaves=6)
TABLE = st.dictionaries(KEYS, VALUES | st.dictionaries(NAMES, VALUES, max_size=3), max_size=4)


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.fixed_dictionaries({"sweep": st.just({"engine": "deep"})},
                             optional={"fixed": TABLE, "grid": TABLE, "include": st.lists(TABLE, max_size=2)}))
def test_no_deep_sweep_document_makes_the_loader_raise_anything_but_its_own_error(document: dict) -> None:
    try:
        text = tomli_w.dumps(document)
    except (TypeError, ValueError):
        return
    try:
        outcome = parse_sweep(text)
    except SweepError as error:
        outcome = error
    if isinstance(outcome, SweepError):
        assert outcome.problems
        assert all(isinstance(p, str) for p in outcome.problems)
    else:
        assert all(isinstance(c, DeepConfig) and c.vmap_width == 1 for c in outcome.configs)


# --- trials, the store, resuming and the report ------------------------------------------------------------


@pytest.fixture(scope="module")
def deep_store(tmp_path_factory) -> tuple[Path, Path, str]:
    """The tiny sweep through the command line, on two local workers, with its report."""
    root = tmp_path_factory.mktemp("deep-sweep")
    sweep_file, out = root / "tiny.toml", root / "store"
    sweep_file.write_text(TINY)
    result = invoke("sweep", str(sweep_file), "--out", str(out), "--workers", "2")
    assert result.exit_code == 0, result.output
    return sweep_file, out, result.output


@pytest.mark.slow("runs deep sweeps")
def test_each_trial_is_a_deep_run_directory_and_the_manifest_is_done(deep_store) -> None:
    _, out, output = deep_store
    assert "deep-tiny: 2 configurations x 2 seeds = 4 trials on the local backend" in output
    assert "4 trials run, 0 already finished" in output
    sweep = parse_sweep(TINY)
    manifest = json.loads((out / MANIFEST_FILE).read_text())
    assert manifest["engine"] == "deep"
    assert [t["status"] for t in manifest["trials"]] == ["done"] * 4
    assert [t["swept"]["algorithm"] for t in manifest["trials"]] == ["pqn_q_lambda", "pqn_sarsa_lambda"] * 2
    for trial in sweep.trials():
        trial_dir = trial_path(out, trial.config_hash, trial.seed)
        assert sorted(p.name for p in trial_dir.iterdir() if not p.name.startswith(".")) == sorted(
            rundir.DEEP_RUN_FILES)
        assert store.read_json(trial_dir / rundir.CONFIG_FILE) == config_dict(trial.config)


@pytest.mark.slow("runs deep sweeps")
def test_trials_merge_per_configuration_in_the_sweep_order_of_seeds(deep_store) -> None:
    _, out, _ = deep_store
    sweep = parse_sweep(TINY)
    runs, problems = load_configurations(out)
    assert problems == []
    assert list(runs) == [config_hash(c) for c in sweep.configs]
    for config, results in zip(sweep.configs, runs.values(), strict=True):
        assert isinstance(results, DeepResults)
        assert results.config == config
        assert results.seeds == sweep.seeds
        assert results.evaluations.groupby("seed")["round"].nunique().to_dict() == dict.fromkeys(sweep.seeds, 2)
        assert all(array.shape[0] == 2 for array in results.params.values())
        first = load_run(trial_path(out, config_hash(config), sweep.seeds[0]))
        pd.testing.assert_frame_equal(results.evaluations[results.evaluations["seed"] == sweep.seeds[0]],
                                      first.evaluations)
    episodes = read_table(out)
    assert set(episodes.groupby("config")["seed"].nunique()) == {2}
    assert set(episodes["algorithm"]) == {"pqn_q_lambda", "pqn_sarsa_lambda"}


@pytest.mark.slow("runs deep sweeps")
def test_the_report_tables_every_deep_configuration(deep_store) -> None:
    _, out, _ = deep_store
    table = pd.read_csv(out / "tables" / "configurations.csv")
    assert table["algorithm"].tolist() == ["pqn_q_lambda", "pqn_sarsa_lambda"]
    assert set(table.columns) >= {"config", "seeds", "steps", "final greedy, mean", "final greedy, IQM", "AUC, mean",
                                  "AUC, IQM"}
    assert table["seeds"].tolist() == [2, 2]
    assert (out / "figures" / "curves-CartPole-v1.png").is_file()
    assert "4 of 4 trials finished" in (out / "report.html").read_text()


@pytest.mark.slow("runs deep sweeps")
def test_a_finished_deep_sweep_resumes_without_training_and_redoes_a_broken_trial(deep_store, tmp_path: Path) -> None:
    import shutil

    sweep_file, out, _ = deep_store
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    before = {p: p.stat().st_mtime_ns for p in copy.glob("trials/*/*/*.npz")}
    again = invoke("sweep", str(sweep_file), "--out", str(copy), "--no-report")
    assert again.exit_code == 0, again.output
    assert "0 trials run, 4 already finished" in again.output
    assert before == {p: p.stat().st_mtime_ns for p in copy.glob("trials/*/*/*.npz")}
    trial = parse_sweep(TINY).trials()[3]
    (trial_path(copy, trial.config_hash, trial.seed) / rundir.PARAMS_FILE).write_bytes(b"damaged")
    redo = invoke("sweep", str(sweep_file), "--out", str(copy), "--workers", "1", "--no-report")
    assert redo.exit_code == 0, redo.output
    assert "1 trials run, 3 already finished" in redo.output
    ours, theirs = load_configurations(copy)[0], load_configurations(out)[0]
    for key in theirs:  # the trial run again equals the first run of it, bit for bit
        _assert_same(ours[key], theirs[key])


def test_the_report_draws_deep_metrics_across_a_swept_hyperparameter() -> None:
    """Without training: two configurations that differ in λ, with made-up greedy returns."""
    sweep = parse_sweep('[sweep]\nengine = "deep"\nseeds = 3\n[fixed]\neval_rounds = 2\n'
                        '[grid]\nhyperparameters.lam = [0.0, 0.9]\n')
    runs, metrics = {}, {}
    for k, config in enumerate(sweep.configs):
        evaluations = pd.DataFrame([{"seed": seed, "round": r, "after_step": 1000 * (r + 1),
                                     "return": 10.0 * (k + r + i), "length": 10, "terminated": True}
                                    for seed in sweep.seeds for r in range(2) for i in range(2)])
        results = DeepResults(config, pd.DataFrame(), evaluations, {}, {"timings": {"training_steps": 2000}})
        runs[config_hash(config)] = results
        metrics[config_hash(config)] = deep_metrics(results)
    assert metrics[config_hash(sweep.configs[1])]["final"].tolist() == [25.0] * 3  # round 1: 10 x (1 + 1 + 0.5)
    assert metrics[config_hash(sweep.configs[1])]["auc"].tolist() == [20.0] * 3
    table = deep_configuration_rows(runs, metrics, list(sweep.swept))
    assert table["hyperparameters.lam"].tolist() == ["0.0", "0.9"]
    assert table["final greedy, mean"].tolist() == ["15.0 [15.0, 15.0]", "25.0 [25.0, 25.0]"]
    figure = across_figure(runs, metrics, "hyperparameters.lam", list(sweep.swept), PANELS["deep"])
    assert [ax.get_title() for ax in figure.axes] == ["CartPole-v1: greedy return, final round",
                                                      "CartPole-v1: area under the greedy curve"]
    assert figure.axes[0].lines[0].get_ydata().tolist() == [15.0, 25.0]


# --- the Ray backend -----------------------------------------------------------------------------------------


@pytest.mark.slow("starting and stopping the cluster take about half a minute")
def test_a_deep_sweep_on_a_ray_cluster_equals_the_local_backend(deep_store, tmp_path: Path) -> None:
    """A head node on loopback (``tests/ray_cluster.py``), one CPU, the tiny sweep's first seed (the seeds depend
    on their index alone): every trial once, equal to the local backend's."""
    pytest.importorskip("ray")
    from ray_cluster import loopback_cluster

    _, reference, _ = deep_store
    sweep_file, out = tmp_path / "ray.toml", tmp_path / "ray"
    sweep_file.write_text(TINY.replace("seeds = 2", "seeds = 1"))
    with loopback_cluster() as (address, env, _, _):
        done = subprocess.run([sys.executable, "-m", "rlcompare.cli", "sweep", str(sweep_file), "--out", str(out),
                               "--backend", "ray", "--address", address, "--no-report"],
                              capture_output=True, text=True, env={**env, "COLUMNS": "200"}, timeout=400, check=False)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "2 trials run, 0 already finished" in done.stdout
    assert {t["status"] for t in json.loads((out / MANIFEST_FILE).read_text())["trials"]} == {"done"}
    ours = load_configurations(out)[0]
    assert list(ours) == [config_hash(c) for c in parse_sweep(TINY).configs]
    for key, results in ours.items():
        _assert_same(results, load_run(trial_path(reference, key, results.seeds[0])))


def test_a_huge_hyperparameter_name_is_quoted_in_part() -> None:
    name = "k" * 1_000_000
    problems = _problems(tomli_w.dumps({"sweep": {"engine": "deep"}, "fixed": {"hyperparameters": {name: 1}},
                                       "grid": {"hyperparameters": {name: [1, 2]}, "eval_rounds": [1, 2]}}))
    assert problems
    assert all(len(p) < 800 for p in problems), [len(p) for p in problems]
