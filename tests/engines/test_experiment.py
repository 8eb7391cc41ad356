"""run(config): run directories, atomic writes, resuming, and agents that act inside Gymnasium."""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet
import pytest
from gymnasium_play import gymnasium_returns

from rlcompare import ConfigError, ExperimentConfig, load_agent, run
from rlcompare.experiment import rundir, store
from rlcompare.experiment.engines import load_if_complete, load_run
from rlcompare.studies.paper.study import paper_configs, reproduce


def test_results_tables_are_long_format(small_config: ExperimentConfig) -> None:
    results = run(small_config, study="unit")
    episodes = results.episodes()
    assert len(episodes) == 3 * 200
    assert list(episodes.columns) == ["study", "env", "algorithm", "schedule", "seed", "episode", "epsilon",
                                      "return", "length", "terminated"]
    assert set(episodes["study"]) == {"unit"}
    assert (episodes["return"] == -episodes["length"]).all()  # -1 per step, the last one included
    assert episodes.groupby("seed")["episode"].apply(lambda e: list(e) == list(range(200))).all()
    evaluations = results.evaluations()
    assert len(evaluations) == 3 * 4 * 4  # seeds x rounds x episodes per round
    assert sorted(set(evaluations["after_episode"])) == [50, 100, 150, 200]
    assert episodes.loc[episodes["episode"] == 0, "epsilon"].eq(1.0).all()


def test_run_directory_round_trip(tmp_path: Path, small_config: ExperimentConfig) -> None:
    results = run(small_config, out=tmp_path / "run")
    assert sorted(p.name for p in (tmp_path / "run").iterdir()) == sorted(rundir.RUN_FILES + store.OWN_FILES)
    loaded = load_run(tmp_path / "run")
    assert loaded.config == small_config
    for name, array in results.records._asdict().items():
        np.testing.assert_array_equal(getattr(loaded.records, name), array, err_msg=name)
    pd.testing.assert_frame_equal(loaded.episodes(), results.episodes())
    np.testing.assert_array_equal(loaded.q_table(2, "final"), results.records.snapshots[2, -1])


def test_round_trip_keeps_the_order_of_seeds(tmp_path: Path, small_config: ExperimentConfig) -> None:
    results = run(dataclasses.replace(small_config, seeds=(5, 3, 9)), out=tmp_path / "run")
    loaded = load_run(tmp_path / "run")
    np.testing.assert_array_equal(loaded.records.returns, results.records.returns)
    np.testing.assert_array_equal(loaded.records.eval_returns, results.records.eval_returns)


def test_failed_rewrite_of_a_finished_run_is_not_taken_for_finished(
    tmp_path: Path, small_config: ExperimentConfig, monkeypatch: pytest.MonkeyPatch
) -> None:
    run(small_config, out=tmp_path / "run")
    changed = dataclasses.replace(small_config, alpha=0.5)
    write = store.write_bytes_atomic

    def disk_full_at_the_episodes(path: Path, data: bytes) -> None:
        if Path(path).name == rundir.EPISODES_FILE:
            raise store.StoreError(f"{path}: cannot write (no space left on the device)")
        write(path, data)

    monkeypatch.setattr(store, "write_bytes_atomic", disk_full_at_the_episodes)
    with pytest.raises(OSError, match="no space left"):
        run(changed, out=tmp_path / "run")
    assert not rundir.is_complete(tmp_path / "run")
    assert load_if_complete(tmp_path / "run", changed) is None
    assert load_if_complete(tmp_path / "run", small_config) is None


def test_failure_before_writing_keeps_the_finished_run(
    tmp_path: Path, small_config: ExperimentConfig, monkeypatch: pytest.MonkeyPatch
) -> None:
    first = run(small_config, out=tmp_path / "run")

    def broken_savez(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(np, "savez_compressed", broken_savez)
    with pytest.raises(OSError, match="disk full"):
        run(dataclasses.replace(small_config, alpha=0.5), out=tmp_path / "run")
    kept = load_if_complete(tmp_path / "run", small_config)
    assert kept is not None
    np.testing.assert_array_equal(kept.records.returns, first.records.returns)


def test_snapshots_are_taken_at_the_named_stages(small_config: ExperimentConfig) -> None:
    config = dataclasses.replace(small_config, schedule="constant", stages=(("early", 0.1), ("final", 1.0)))
    early = run(dataclasses.replace(config, episodes=20, stages=(("final", 1.0),)))  # same ε throughout
    full = run(config)
    np.testing.assert_array_equal(full.q_table(1, "early"), early.q_table(1, "final"))
    assert not np.array_equal(full.q_table(1, "early"), full.q_table(1, "final"))


def test_failed_write_leaves_nothing_that_looks_finished(
    tmp_path: Path, small_config: ExperimentConfig, monkeypatch: pytest.MonkeyPatch
) -> None:
    def broken_parquet(table, handle, **kwargs):
        handle.write(b"PAR1 half a file")
        raise OSError("disk full")

    monkeypatch.setattr(pyarrow.parquet, "write_table", broken_parquet)
    with pytest.raises(OSError, match="disk full"):
        run(small_config, out=tmp_path / "run")
    assert not (tmp_path / "run").exists()  # created by the run and nothing written into it: removed again
    monkeypatch.undo()
    write = store.write_bytes_atomic

    def full_at_the_evaluations(path: Path, data: bytes) -> None:
        if Path(path).name == rundir.EVALUATIONS_FILE:
            with open(Path(path).with_name(".evaluations.parquet.x.tmp"), "wb"):
                raise OSError("disk full")
        write(path, data)

    monkeypatch.setattr(store, "write_bytes_atomic", full_at_the_evaluations)
    with pytest.raises(OSError, match="disk full"):
        run(small_config, out=tmp_path / "run")
    left = sorted(p.name for p in (tmp_path / "run").iterdir() if not p.name.endswith(".tmp"))
    assert left == sorted([*store.OWN_FILES, rundir.CONFIG_FILE, rundir.EPISODES_FILE])  # no meta.json
    assert not rundir.is_complete(tmp_path / "run")
    assert load_if_complete(tmp_path / "run", small_config) is None
    monkeypatch.undo()
    again = run(small_config, out=tmp_path / "run")  # resumes over what it wrote, temporaries cleared
    assert not list((tmp_path / "run").glob("*.tmp"))
    assert load_run(tmp_path / "run").records.returns.tolist() == again.records.returns.tolist()


def test_study_resumes_and_reruns_only_what_is_unfinished(tmp_path: Path) -> None:
    configs = paper_configs((0, 1), episodes=60, eval_every=30, eval_episodes=2)
    first = {r.config.name: reused for r, reused in reproduce(tmp_path, configs)}
    assert first == dict.fromkeys(first, False)
    os.remove(tmp_path / "sarsa-decay" / rundir.META_FILE)  # as if interrupted while writing
    again = {r.config.name: (r, reused) for r, reused in reproduce(tmp_path, configs)}
    assert [n for n, (_, reused) in again.items() if not reused] == ["sarsa-decay"]
    rerun = again["sarsa-decay"][0]
    np.testing.assert_array_equal(rerun.records.returns, load_run(tmp_path / "sarsa-decay").records.returns)


def test_changed_config_is_not_taken_for_a_finished_run(tmp_path: Path, small_config: ExperimentConfig) -> None:
    run(small_config, out=tmp_path / "run")
    assert load_if_complete(tmp_path / "run", small_config) is not None
    assert load_if_complete(tmp_path / "run", dataclasses.replace(small_config, alpha=0.1)) is None


def test_output_path_that_is_a_file_is_refused(tmp_path: Path, small_config: ExperimentConfig) -> None:
    target = tmp_path / "taken"
    target.write_text("not a directory")
    with pytest.raises(store.StoreError, match="is a file"):
        run(small_config, out=target)
    assert target.read_text() == "not a directory"


def test_loading_an_incomplete_directory_names_what_is_missing(tmp_path: Path) -> None:
    (tmp_path / rundir.CONFIG_FILE).write_text("{}")
    with pytest.raises(store.StoreError, match=r"missing episodes\.parquet"):
        load_run(tmp_path)


def test_loaded_agent_acts_in_gymnasium_exactly_as_in_our_evaluation(tmp_path: Path) -> None:
    config = ExperimentConfig(algorithm="q_learning", schedule="decay", seeds=(7,), episodes=1500,
                              eval_every=1500, eval_episodes=20)
    results = run(config, out=tmp_path / "run")
    agent = load_agent(tmp_path / "run", seed=7, stage="final")
    _, eval_stream = np.random.SeedSequence(7).spawn(2)
    ours = results.records.eval_returns[0, -1]
    theirs = gymnasium_returns(agent, eval_stream, 20)
    np.testing.assert_array_equal(theirs, ours)
    assert (ours > -1000).mean() == results.records.eval_terminated[0, -1].mean()


def test_load_agent_rejects_unknown_seed_and_stage(tmp_path: Path, small_config: ExperimentConfig) -> None:
    run(small_config, out=tmp_path / "run")
    with pytest.raises(KeyError, match="seed 9"):
        load_agent(tmp_path / "run", seed=9)
    with pytest.raises(KeyError, match="'late'"):
        load_agent(tmp_path / "run", seed=0, stage="late")


def test_an_epsilon_greedy_agent_draws_a_coin_and_an_action_every_step_and_explores_below_epsilon(
        tmp_path: Path, small_config: ExperimentConfig) -> None:
    """``load_agent(epsilon=...)`` as an evaluation plays: each step ``u = rng.random()`` then ``a = rng.integers(3)``
    from ``default_rng(exploration_seed)``; ``a`` where ``u < ε``, else the greedy action."""
    run(small_config, out=tmp_path / "run")
    greedy = load_agent(tmp_path / "run", seed=1)
    assert load_agent(tmp_path / "run", seed=1, epsilon=0.0).__class__ is greedy.__class__
    observations = [np.array([-0.5 + 0.01 * k, 0.001 * (k % 5 - 2)], np.float32) for k in range(400)]
    by_hand = np.random.default_rng(11)
    expected = []
    for observation in observations:
        u, a = by_hand.random(), int(by_hand.integers(3))
        expected.append(a if u < 0.3 else greedy.act(observation))
    agent = load_agent(tmp_path / "run", seed=1, epsilon=0.3, exploration_seed=11)
    actions = [agent.act(observation) for observation in observations]
    assert actions == expected
    assert actions != [greedy.act(observation) for observation in observations]  # some steps explored
    always = load_agent(tmp_path / "run", seed=1, epsilon=1.0, exploration_seed=11)
    coins = np.random.default_rng(11)
    assert [always.act(o) for o in observations] == [(coins.random(), int(coins.integers(3)))[1] for _ in observations]
    for bad, field in ((1.5, "epsilon"), (-0.1, "epsilon"), (float("nan"), "epsilon")):
        with pytest.raises(ConfigError, match=field):
            load_agent(tmp_path / "run", seed=1, epsilon=bad)
    with pytest.raises(ConfigError, match="exploration_seed"):
        load_agent(tmp_path / "run", seed=1, epsilon=0.1, exploration_seed=-1)


def test_tile_coded_agent_acts_in_gymnasium_as_in_our_evaluation(tmp_path: Path) -> None:
    """Tiles read Gymnasium's float32 observation in the kernels as in a loaded agent, so the returns are equal."""
    config = ExperimentConfig(algorithm="sarsa", features="tiles", schedule="constant", epsilon=0.0, gamma=1.0,
                              alpha=0.5 / 8, seeds=(3,), episodes=200, eval_every=200, eval_episodes=20)
    results = run(config, out=tmp_path / "run")
    agent = load_agent(tmp_path / "run", seed=3)
    _, eval_stream = np.random.SeedSequence(3).spawn(2)
    ours = results.records.eval_returns[0, -1]
    theirs = np.array(gymnasium_returns(agent, eval_stream, 20))
    assert (ours > -1000).all()
    np.testing.assert_array_equal(theirs, ours)
