"""``rlcompare compare`` on runs Stable-Baselines3 trained itself (the ``bench`` extra; skipped without it): PPO and
DQN on CartPole-v1 over 3 seeds with ``Monitor`` and ``EvalCallback``, read from its Monitor files and from its
evaluations, and the verdicts on its files equal to those on the same numbers given as a tidy table."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pandas as pd
import pytest
from helpers import invoke

from rlcompare.bench.deep import unlogged
from rlcompare.experiment.outside import grouping, read_runs, run_files

# found, not imported: torch's import (seconds) is paid by the tests that train, not by every worker's collection
pytestmark = [pytest.mark.skipif(importlib.util.find_spec("stable_baselines3") is None,
                                 reason="the bench extra (Stable-Baselines3) is not installed"),
              pytest.mark.slow("trains Stable-Baselines3's PPO and DQN on CartPole over 3 seeds")]
SEEDS, STEPS = 3, 1_024


def train(method: str, seed: int, root: Path) -> None:
    """One SB3 training whose Monitor file goes to ``root/monitor/...`` and evaluations to ``root/eval/...``."""
    import gymnasium as gym
    import stable_baselines3 as sb3
    from stable_baselines3.common.callbacks import EvalCallback
    from stable_baselines3.common.monitor import Monitor

    monitor_dir = root / "monitor" / method / "CartPole-v1" / str(seed)
    eval_dir = root / "eval" / method / "CartPole-v1" / str(seed)
    monitor_dir.mkdir(parents=True)
    eval_dir.mkdir(parents=True)
    env = Monitor(gym.make("CartPole-v1"), str(monitor_dir / "0"))
    model = (sb3.PPO("MlpPolicy", env, n_steps=256, batch_size=64, seed=seed, device="cpu") if method == "ppo"
             else sb3.DQN("MlpPolicy", env, learning_starts=256, train_freq=4, seed=seed, device="cpu"))
    unlogged(model)  # else SB3 leaves a directory of its logger's in the system's temporary directory
    callback = EvalCallback(Monitor(gym.make("CartPole-v1")), eval_freq=256, n_eval_episodes=3,
                            log_path=str(eval_dir), verbose=0)
    model.learn(total_timesteps=STEPS, callback=callback)
    env.close()


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """The runs' directory, and what their trainings left in the system's temporary directory (a fresh one)."""
    import tempfile

    import torch

    torch.set_num_threads(1)
    root = tmp_path_factory.mktemp("sb3")
    system_temporary = tmp_path_factory.mktemp("system-temporary")
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(tempfile, "tempdir", str(system_temporary))
        for method in ("ppo", "dqn"):
            for seed in range(SEEDS):
                train(method, seed, root)
    return root, sorted(p.name for p in system_temporary.iterdir())


@pytest.fixture(scope="module")
def runs(trained):
    return trained[0]


def test_the_trainings_leave_no_logger_directory_in_the_system_temporary_directory(trained):
    assert [name for name in trained[1] if name.startswith("SB3-")] == []  # torch's own compile cache may be there


@pytest.mark.parametrize("kind", ["monitor", "eval"])
def test_sb3s_own_files_become_a_report_with_the_verdicts_of_the_same_numbers_as_a_table(runs, tmp_path, kind):
    result = invoke("compare", str(runs / kind), "--cut-to-shortest", "--out", str(tmp_path / "files"), columns=300)
    assert result.exit_code == 0, result.output
    pairing = pd.read_csv(tmp_path / "files" / "tables" / "pairing.csv")
    assert sorted(set(zip(pairing["method"], pairing["seed"], strict=True))) == [
        (m, s) for m in ("dqn", "ppo") for s in range(SEEDS)]
    if kind == "eval":
        assert (pairing["last_step"] == STEPS).all()  # EvalCallback evaluates every 256 steps, the last at 1,024
    root, files = run_files([runs / kind])
    table = tmp_path / "tidy.parquet"
    read_runs(files, root, grouping("{method}/{env}/{seed}/*")).drop(columns="source").to_parquet(table)
    again = invoke("compare", str(table), "--cut-to-shortest", "--out", str(tmp_path / "table"), columns=300)
    assert again.exit_code == 0, again.output
    pd.testing.assert_frame_equal(pd.read_csv(tmp_path / "files" / "tables" / "verdicts.csv"),
                                  pd.read_csv(tmp_path / "table" / "tables" / "verdicts.csv"))
    page = (tmp_path / "files" / "report.html").read_text()
    assert "independent samples" in page
