"""``rlcompare bench atari`` at tiny sizes: the emulator's rows and the learner's are what they say (per core is the
rate over the cores, the learner's rate is its formula on the measured parts, the emulator's threads are ALE's
default pool), the timed PQN training cuts its evaluation to one step, and a missing Atari extra is one line."""

from __future__ import annotations

import dataclasses
import gc
import math
import os
import sys
from pathlib import Path

import pytest

pytest.importorskip("jax")
ale_py = pytest.importorskip("ale_py")

from helpers import invoke  # noqa: E402

from rlcompare.bench import atari as bench  # noqa: E402
from rlcompare.bench import emulator as bench_emulator  # noqa: E402
from rlcompare.deep.presets import dqn as dqn_config  # noqa: E402
from rlcompare.deep.presets import ppo as ppo_config  # noqa: E402


def number(cell: str) -> float:
    return float(cell.lstrip("~").replace(",", ""))


@pytest.mark.slow("makes a 2-game emulator and compiles its callback")
def test_the_emulators_rows_are_its_rates_per_core_beside_envpools() -> None:
    said: list[str] = []
    rates = bench_emulator.measure_emulator(bench_emulator.bench_env(), said.append, games=(2,), steps=32, turns=2)
    (rate,) = rates
    assert rate.games == 2
    assert all(math.isfinite(value) and value > 0 for value in (rate.alone, rate.callback))
    assert said == [f"2 games: {rate.alone:,.0f} steps/s alone, {rate.callback:,.0f} through the callback"]
    table = bench_emulator.emulator_table(rates, steps=32, turns=2)
    assert table.columns == ("what", "games", "ALE threads", "steps/s", "steps/s per core",
                             "per core / envpool's 1,100", "callback / alone")
    alone, callback = table.rows
    assert (alone[0], callback[0]) == ("alone, stepped from Python", "through the engine's callback")
    cores = os.cpu_count() or 1
    for row, value in ((alone, rate.alone), (callback, rate.callback)):
        assert row[1:3] == ("2", str(min(2, cores)))
        assert number(row[3]) == round(value)
        assert number(row[4]) == round(value / cores)
        assert float(row[5]) == pytest.approx(value / cores / 1_100, abs=0.006)
    assert float(callback[6]) == pytest.approx(rate.callback / rate.alone, abs=0.006)
    assert any("1,100 agent steps/s per core" in note for note in table.notes)


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="counts threads in /proc")
@pytest.mark.slow("makes emulators")
def test_ales_default_pool_is_one_thread_a_game_up_to_one_a_core() -> None:
    for games in (1, 3):
        before = len(os.listdir("/proc/self/task"))
        emulator = ale_py.AtariVectorEnv("breakout", games)
        try:
            assert len(os.listdir("/proc/self/task")) - before == bench_emulator.emulator_threads(games)
        finally:
            emulator.close()
            del emulator  # its threads end with the object
            gc.collect()


def test_steps_per_gradient_and_the_learners_formula() -> None:
    assert bench.steps_per_gradient(dqn_config.ATARI) == 4  # a gradient every 4 steps of 1 environment
    assert bench.steps_per_gradient(ppo_config.ATARI) == 1_024 / 16  # 4 epochs x 4 minibatches per 8 x 128
    assert bench.steps_per_gradient(bench.pqn_preset()) == 4_096 / 64  # 2 epochs x 32 minibatches per 128 x 32
    cost = bench.LearnerCost("x", 8, 1 / 8, 256, 64.0, forward_seconds=0.004, gradient_seconds=0.32)
    assert cost.seconds_per_step == pytest.approx(0.004 / 8 + 0.32 / 64)
    assert cost.steps_per_second == pytest.approx(1 / 0.0055)
    assert bench.learner_alone(100.0, 400.0) == pytest.approx(1 / (1 / 100 - 1 / 400))
    assert math.isnan(bench.learner_alone(100.0, 90.0))  # an emulator no faster than the whole: no estimate
    assert bench.together(100.0, 400.0) == pytest.approx(80.0)


@pytest.mark.slow("compiles a gradient step of Mnih et al.'s network")
def test_dqns_cost_is_its_formula_on_its_measured_parts() -> None:
    cost = bench.dqn_cost(bench_emulator.bench_env(), gradients=2, passes=2)
    assert (cost.forward_batch, cost.forwards_per_step, cost.gradient_batch, cost.steps_per_gradient) == (
        1, 1.0, 32, 4.0)
    assert 0 < cost.forward_seconds < cost.gradient_seconds  # a pass of 1 frame stack, a gradient of 32
    assert cost.steps_per_second == pytest.approx(1 / (cost.forward_seconds + cost.gradient_seconds / 4))


@pytest.mark.slow("compiles and runs a PQN training on a 2-game emulator")
def test_the_timed_pqn_training_is_its_updates_with_a_one_step_evaluation() -> None:
    config = dataclasses.replace(bench.pqn_preset(), n_envs=2, n_steps=4, n_minibatches=2, hidden=(32,))
    training = bench.pqn_training(bench_emulator.bench_env(), 2, config)
    assert math.isfinite(training.steps_per_second)
    assert training.steps_per_second > 0
    assert training.compile_seconds > 0
    assert training.output.finished.done.shape == (1, 2, 4, 2)  # 1 round x 2 updates x 4 steps x 2 games
    assert training.output.eval_lengths.tolist() == [[1]]


def test_the_learners_table_names_its_rows_and_derives_them() -> None:
    emulator = {n: bench_emulator.EmulatorRates(n, alone=1_000.0 * n, callback=500.0 * n) for n in (1, 8, 128)}
    costs = [bench.LearnerCost("DQN, x", 1, 1.0, 32, 4.0, 0.001, 0.04),
             bench.LearnerCost("PPO, x", 8, 1 / 8, 256, 64.0, 0.004, 0.32)]
    training = bench.TrainingRate(200.0, 12.0, None)  # type: ignore[arg-type]  # the table reads no output
    sb3 = [bench.SB3Rate("SB3 DQN, x", 4.0, 90.0, 2)]
    table = bench.learner_table(costs, training, emulator, sb3)
    assert table.columns == ("what", "forward ms (batch)", "gradient ms (batch)", "steps per gradient",
                             "learner steps/s", "emulator alone steps/s", "whole steps/s")
    pqn_row, dqn_row, ppo_row, sb3_row = table.rows
    assert pqn_row[0] == "Q(λ) PQN preset, its training (2 updates)"
    assert number(pqn_row[4]) == round(bench.learner_alone(200.0, 64_000.0))
    assert (number(pqn_row[5]), number(pqn_row[6])) == (128_000, 200)
    assert dqn_row[1:4] == ("1.0 (1)", "40 (32)", "4")
    assert number(dqn_row[4]) == round(1 / (0.001 + 0.04 / 4))
    assert number(dqn_row[5]) == 1_000  # the emulator alone at DQN's 1 game
    assert dqn_row[6] == f"~{bench.together(1 / 0.011, 500.0):,.0f}"
    assert number(ppo_row[5]) == 8_000
    assert sb3_row == ("SB3 DQN, x", "", "", "4", "", "", "90")
    assert not any("not installed" in note for note in table.notes)
    alone = bench.learner_table(costs, training, emulator, None)
    assert len(alone.rows) == 3
    assert alone.notes[-1] == "Stable-Baselines3 is not installed: pip install -e '.[bench]'"


def test_without_the_atari_extra_the_command_says_so_in_one_line(monkeypatch: pytest.MonkeyPatch,
                                                                 tmp_path: Path) -> None:
    monkeypatch.setitem(sys.modules, "ale_py", None)  # import ale_py raises ImportError
    result = invoke("bench", "atari", "--out", str(tmp_path / "out"))
    assert result.exit_code == 2
    assert "pip install -e '.[atari]'" in result.output
    assert len(result.output.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()


@pytest.mark.slow("makes Stable-Baselines3's models on 9 Gymnasium emulators")
def test_sb3s_models_have_the_zoos_atari_settings() -> None:
    pytest.importorskip("stable_baselines3")
    from stable_baselines3.common.torch_layers import NatureCNN

    config = dataclasses.replace(dqn_config.ATARI, learning_starts=bench.SB3_DQN_LEARNING_STARTS)
    model = bench.sb3_dqn(config)
    assert model.observation_space.shape == (4, 84, 84)
    assert model.action_space.n == 18
    assert isinstance(model.policy.q_net.features_extractor, NatureCNN)
    assert (model.batch_size, model.learning_starts, model.buffer_size, model.train_freq.frequency,
            model.target_update_interval) == (32, 1_000, 100_000, 4, 1_000)
    ppo = bench.sb3_ppo(ppo_config.ATARI)
    assert (ppo.n_envs, ppo.n_steps, ppo.batch_size, ppo.n_epochs) == (8, 128, 256, 4)
    assert isinstance(ppo.policy.features_extractor, NatureCNN)
    assert ppo.policy.share_features_extractor
