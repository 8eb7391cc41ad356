"""Runs other libraries made, read into the tidy table: Stable-Baselines3's Monitor files (hand-written in its
format, and written by Stable-Baselines3 itself where it is installed), RL Zoo's evaluations.npz, tidy CSV and
Parquet; the grouping rule; and every malformed file refused with one message naming it."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rlcompare.experiment.formats import TIDY, OutsideRunError, read_monitor, read_tidy, read_zoo_evaluations
from rlcompare.experiment.outside import grouping, read_runs, run_files

RULE = "{method}/{env}/seed_{seed}/*"


def write_monitor(path: Path, returns: list[float], lengths: list[int]) -> Path:
    """A file as Stable-Baselines3's ``Monitor`` writes it: a JSON header line, then ``r,l,t`` per episode."""
    path.parent.mkdir(parents=True, exist_ok=True)
    rows = "".join(f"{r},{n},{0.01 * i:.6f}\n" for i, (r, n) in enumerate(zip(returns, lengths, strict=True)))
    path.write_text("#" + json.dumps({"t_start": 1.7e9, "env_id": "CartPole-v1"}) + "\nr,l,t\n" + rows)
    return path


def test_a_monitor_file_gives_each_return_at_the_steps_up_to_its_episodes_end(tmp_path):
    frame = read_monitor(write_monitor(tmp_path / "0.monitor.csv", [10.0, 22.0, 9.5], [10, 22, 14]))
    assert frame["step"].tolist() == [10, 32, 46]
    assert frame["value"].tolist() == [10.0, 22.0, 9.5]


@pytest.mark.slow("imports Stable-Baselines3 and torch (the bench extra)")
def test_stable_baselines3s_own_monitor_file_reads_as_its_episodes(tmp_path):
    gym = pytest.importorskip("gymnasium")
    monitor = pytest.importorskip("stable_baselines3.common.monitor")
    env = monitor.Monitor(gym.make("CartPole-v1"), str(tmp_path / "0"))
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    for _ in range(400):
        *_, terminated, truncated, _ = env.step(int(rng.integers(2)))
        if terminated or truncated:
            env.reset()
    returns, lengths = env.get_episode_rewards(), env.get_episode_lengths()
    env.close()
    frame = read_monitor(tmp_path / "0.monitor.csv")
    assert len(returns) > 5
    np.testing.assert_allclose(frame["value"], returns)
    np.testing.assert_array_equal(frame["step"], np.cumsum(lengths))


def test_rl_zoos_evaluations_give_each_evaluations_mean(tmp_path):
    path = tmp_path / "evaluations.npz"
    np.savez(path, timesteps=np.array([1000, 2000]), results=np.array([[1.0, 3.0], [5.0, 9.0]]),
             ep_lengths=np.array([[10, 30], [50, 90]]))
    frame = read_zoo_evaluations(path)
    assert frame["step"].tolist() == [1000, 2000]
    assert frame["value"].tolist() == [2.0, 7.0]


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_a_tidy_table_is_read_as_it_is(tmp_path, suffix):
    table = pd.DataFrame({"method": ["ppo", "dqn"], "env": ["CartPole-v1"] * 2, "seed": [0, 0], "step": [5, 5],
                          "value": [1.5, 2.5], "extra": ["kept out", "kept out"]})
    path = tmp_path / f"runs{suffix}"
    table.to_csv(path, index=False) if suffix == ".csv" else table.to_parquet(path)
    frame = read_tidy(path)
    assert list(frame.columns) == list(TIDY)
    assert frame["value"].tolist() == [1.5, 2.5]


def test_the_grouping_rule_names_each_files_method_environment_and_seed(tmp_path):
    rule = grouping(RULE)
    path = tmp_path / "ppo" / "CartPole-v1" / "seed_3" / "0.monitor.csv"
    assert rule.of(path, tmp_path) == {"method": "ppo", "env": "CartPole-v1", "seed": "3"}
    with pytest.raises(OutsideRunError, match="does not match the grouping rule") as refused:
        rule.of(tmp_path / "ppo" / "seed_3" / "0.monitor.csv", tmp_path)
    assert "ppo/seed_3/0.monitor.csv" in str(refused.value)


@pytest.mark.parametrize("rule", ["{method}/{seed}/*", "{method}/{env}/{seed}/{run}", "{method}/{env}/{seed}/{seed}"])
def test_a_rule_that_does_not_name_each_field_once_is_refused(rule):
    with pytest.raises(ValueError, match=r"group: .*allowed"):
        grouping(rule)


def test_runs_of_two_methods_read_into_one_table(tmp_path):
    for method, scale in (("ppo", 1.0), ("dqn", 2.0)):
        for seed in range(3):
            write_monitor(tmp_path / method / "CartPole-v1" / f"seed_{seed}" / "0.monitor.csv",
                          [scale * seed, scale * (seed + 1)], [10, 20])
    frame = read_runs(tmp_path.rglob("*.monitor.csv"), tmp_path, grouping(RULE))
    assert list(frame.columns) == [*TIDY, "source", "kind"]
    assert set(frame["kind"]) == {"Monitor episodes"}
    assert len(frame) == 12
    assert frame.groupby("method")["seed"].nunique().to_dict() == {"dqn": 3, "ppo": 3}
    dqn = frame[(frame["method"] == "dqn") & (frame["seed"] == "2")]
    assert dqn["value"].tolist() == [4.0, 6.0]
    assert dqn["step"].tolist() == [10, 30]


@pytest.mark.parametrize(("name", "content", "said"), [
    ("0.monitor.csv", "", "expected a first line"),
    ("0.monitor.csv", "r,l,t\n1,2,3\n", "expected a first line"),
    ("0.monitor.csv", "#{}\nreward,length,time\n1,2,3\n", "expected r,l,t"),
    ("0.monitor.csv", "#{}\nr,l,t\n", "no episode"),
    ("0.monitor.csv", "#{}\nr,l,t\nten,2,3\n", "not a finite number"),
    ("0.monitor.csv", "#not json\nr,l,t\n1,2,3\n", "JSON"),
    ("evaluations.npz", "not an archive", "expected the arrays timesteps and results"),
    ("runs.csv", "method,env,seed,step\nppo,c,0,1\n", "no column value"),
    ("runs.csv", "", "expected the columns"),
    ("notes.txt", "hello", "not a run rlcompare reads"),
])
def test_a_file_that_is_not_what_its_name_says_is_one_message_naming_it(tmp_path, name, content, said):
    path = tmp_path / "ppo" / "CartPole-v1" / "seed_0" / name
    path.parent.mkdir(parents=True)
    path.write_text(content)
    with pytest.raises(OutsideRunError, match=said) as refused:
        read_runs([path], tmp_path, grouping(RULE))
    assert str(refused.value).startswith(str(path))
    assert "\n" not in str(refused.value)


def test_one_runs_monitor_files_in_one_directory_are_merged_by_wall_time(tmp_path):
    """A vectorised environment's files (0.monitor.csv, 1.monitor.csv) are one run, as Stable-Baselines3's
    ``load_results`` reads them: every episode in the order of its wall time (t after each file's t_start), at the
    steps of all episodes up to it. By hand: 0's episodes end at 1.7e9 + 0, 0.01; 1's at 1.7e9 + 0.005, 0.015."""
    run = tmp_path / "ppo" / "CartPole-v1" / "seed_0"
    first = write_monitor(run / "0.monitor.csv", [1.0, 3.0], [5, 7])
    second = run / "1.monitor.csv"
    second.write_text("#" + json.dumps({"t_start": 1.7e9 + 0.005}) + "\nr,l,t\n2.0,6,0.0\n4.0,8,0.01\n")
    frame = read_runs([first, second], tmp_path, grouping(RULE))
    assert frame["value"].tolist() == [1.0, 2.0, 3.0, 4.0]
    assert frame["step"].tolist() == [5, 11, 18, 26]
    assert frame["source"].nunique() == 1
    assert "2 files" in frame["source"].iloc[0]


def test_sb3s_plain_monitor_csv_is_read(tmp_path):
    path = write_monitor(tmp_path / "ppo" / "CartPole-v1" / "seed_0" / "monitor.csv", [1.0, 2.0], [5, 6])
    root, files = run_files([tmp_path])
    assert files == [path.resolve()]
    assert read_runs(files, root, grouping(RULE))["step"].tolist() == [5, 11]


def test_one_run_in_two_directories_is_refused_naming_both(tmp_path):
    first = write_monitor(tmp_path / "ppo" / "CartPole-v1" / "seed_0" / "a" / "0.monitor.csv", [1.0], [5])
    second = write_monitor(tmp_path / "ppo" / "CartPole-v1" / "seed_0" / "b" / "0.monitor.csv", [1.0], [5])
    with pytest.raises(OutsideRunError, match="again") as refused:
        read_runs([first, second], tmp_path, grouping("{method}/{env}/{seed}/*/*"))
    assert str(first) in str(refused.value)
    assert str(second) in str(refused.value)


def test_an_evaluations_archive_without_its_arrays_is_refused(tmp_path):
    path = tmp_path / "ppo" / "CartPole-v1" / "seed_0" / "evaluations.npz"
    path.parent.mkdir(parents=True)
    np.savez(path, steps=np.arange(3))
    with pytest.raises(OutsideRunError, match="timesteps and results"):
        read_runs([path], tmp_path, grouping(RULE))


def write_events(directory: Path, tag: str, steps: np.ndarray, values: np.ndarray) -> Path:
    """An event file written by TensorBoard's own writer."""
    from tensorboard.summary import Writer

    writer = Writer(str(directory))
    for step, value in zip(steps, values, strict=True):
        writer.add_scalar(tag, float(value), step=int(step))
    writer.close()
    (path,) = directory.glob("events.out.tfevents.*")
    return path


def test_tensorboard_files_under_cleanrls_tag_names_read_as_their_scalars(tmp_path):
    pytest.importorskip("tensorboard")
    steps, values = np.arange(0, 5000, 100), np.linspace(-3.0, 40.0, 50)
    for method, seed in (("ppo", 1), ("dqn", 2)):
        write_events(tmp_path / f"CartPole-v1__{method}__{seed}__1700000000", "charts/episodic_return", steps,
                     values * seed)
    rule = grouping("{env}__{method}__{seed}__*/*")
    frame = read_runs(sorted(tmp_path.rglob("events.out.tfevents.*")), tmp_path, rule)
    dqn = frame[frame["method"] == "dqn"]
    assert set(dqn["env"]) == {"CartPole-v1"}
    assert set(dqn["seed"]) == {"2"}
    np.testing.assert_array_equal(dqn["step"], steps)
    np.testing.assert_allclose(dqn["value"], values * 2, rtol=1e-6)  # stored as float32


def test_a_tag_the_file_lacks_is_one_message_naming_the_tags_there(tmp_path):
    pytest.importorskip("tensorboard")
    path = write_events(tmp_path / "ppo" / "CartPole-v1" / "0", "losses/value_loss", np.arange(3), np.ones(3))
    with pytest.raises(OutsideRunError, match="expected one of the tags charts/episodic_return") as refused:
        read_runs([path], tmp_path, grouping(RULE.replace("seed_", "")))
    assert "losses/value_loss" in str(refused.value)
    with pytest.raises(OutsideRunError, match="expected the tag 'eval/mean_reward'"):
        read_runs([path], tmp_path, grouping(RULE.replace("seed_", "")), tag="eval/mean_reward")
    assert len(read_runs([path], tmp_path, grouping(RULE.replace("seed_", "")), tag="losses/value_loss")) == 3


def test_a_file_named_as_events_that_is_not_is_one_message(tmp_path):
    pytest.importorskip("tensorboard")
    path = tmp_path / "ppo" / "CartPole-v1" / "0" / "events.out.tfevents.1.host"
    path.parent.mkdir(parents=True)
    path.write_bytes(b"\x00" * 40 + b"not an event file")
    with pytest.raises(OutsideRunError) as refused:
        read_runs([path], tmp_path, grouping(RULE.replace("seed_", "")))
    assert str(refused.value).startswith(str(path))


@pytest.mark.slow("starts a pool of processes")
def test_many_tensorboard_files_read_in_processes_equal_them_read_here(tmp_path, monkeypatch):
    pytest.importorskip("tensorboard")
    from rlcompare.experiment import formats

    for seed in range(4):
        write_events(tmp_path / f"CartPole-v1__ppo__{seed}__0", "charts/episodic_return", np.arange(50) * 10,
                     np.sin(np.arange(50) + seed))
    files = sorted(tmp_path.rglob("events.out.tfevents.*"))
    rule = grouping("{env}__{method}__{seed}__*/*")
    here = read_runs(files, tmp_path, rule)
    monkeypatch.setattr(formats, "PARALLEL_FROM", 2)
    monkeypatch.setattr(formats.os, "cpu_count", lambda: 2)
    pd.testing.assert_frame_equal(read_runs(files, tmp_path, rule), here)


def write_wandb_chart(path: Path, runs: dict[str, list[float | None]], metric: str = "charts/episodic_return",
                      steps: tuple[int, ...] = (100, 200, 300, 400)) -> Path:
    """A line chart's CSV as W&B exports it: steps, then per run its values (empty where it logged none) and the
    line's __MIN and __MAX."""
    columns: dict[str, list[object]] = {"Step": list(steps)}
    for name, values in runs.items():
        shown = ["" if v is None else v for v in values]
        columns |= {f"{name} - {metric}": shown, f"{name} - {metric}__MIN": shown, f"{name} - {metric}__MAX": shown}
    pd.DataFrame(columns).to_csv(path, index=False)
    return path


def test_a_wandb_charts_export_reads_each_run_by_its_name_without_its_bounds(tmp_path):
    runs = {"CartPole-v1__ppo__1__1700": [10.0, 20.0, None, 40.0], "CartPole-v1__a2c__1__1701": [5.0, None, 7.0, 8.0]}
    chart = write_wandb_chart(tmp_path / "chart.csv", runs)
    read = read_runs([chart], tmp_path, grouping("{env}__{method}__{seed}__*"))
    by_hand = pd.DataFrame({"method": ["ppo"] * 3 + ["a2c"] * 3, "env": "CartPole-v1", "seed": "1",
                            "step": [100, 200, 400, 100, 300, 400], "value": [10.0, 20.0, 40.0, 5.0, 7.0, 8.0]})
    pd.testing.assert_frame_equal(read[list(TIDY)], by_hand[list(TIDY)], check_dtype=False)
    assert set(read["kind"]) == {"W&B chart charts/episodic_return"}
    with pytest.raises(OutsideRunError, match=r"its run 'CartPole-v1__ppo__1__1700' does not match the grouping rule "
                                              r"'\{method\}/\{env\}/\{seed\}/\*'.*--group"):
        read_runs([chart], tmp_path, grouping("{method}/{env}/{seed}/*"))


def test_a_wandb_chart_of_two_metrics_or_a_run_without_values_is_refused(tmp_path):
    first = write_wandb_chart(tmp_path / "a.csv", {"x__ppo__1__0": [1.0, 2.0, 3.0, 4.0]})
    second = pd.read_csv(first).assign(**{"x__a2c__1__0 - eval/return": [1.0, 2.0, 3.0, 4.0]})
    second.to_csv(tmp_path / "b.csv", index=False)
    rule = grouping("{env}__{method}__{seed}__*")
    with pytest.raises(OutsideRunError, match="the metrics charts/episodic_return, eval/return; expected one a chart"):
        read_runs([tmp_path / "b.csv"], tmp_path, rule)
    empty = write_wandb_chart(tmp_path / "c.csv", {"x__ppo__1__0": [None] * 4})
    with pytest.raises(OutsideRunError, match="the run 'x__ppo__1__0' has no value"):
        read_runs([empty], tmp_path, rule)
