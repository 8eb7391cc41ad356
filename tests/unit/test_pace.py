"""A plan's time on this machine: each training keeps its pace as it runs, under the key its plan looks up, and the
plan adds them up as computed here by hand; what has never run here is named, not guessed."""

from __future__ import annotations

import json
import os
from dataclasses import replace
from pathlib import Path

import pytest
from helpers import invoke

from rlcompare import pace
from rlcompare.studies.plans import StudyPlan, Training, duration, tabular_training
from rlcompare.tabular.config import ExperimentConfig
from rlcompare.tabular.train import train


@pytest.fixture
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A pace file of the test's own, where rlcompare's cache directory keeps it."""
    monkeypatch.delenv("RLCOMPARE_PACE_FILE")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))  # numba's was chosen at import and stays where it was
    return tmp_path / "rlcompare" / pace.PACE_FILE


def test_a_pace_is_kept_per_seed_unit_and_thread_and_read_back(cache: Path) -> None:
    # 4 seeds x 5 episodes in 10 s on 2 threads: each seed's episode took 10 * 2 / 20 = 1 s of one thread
    pace.record("tabular X a", wall_seconds=10.0, compile_seconds=3.0, seeds=4, amount=5, unit="episodes", threads=2)
    kept = pace.stored()["tabular X a"]
    assert (kept.seconds_per_unit, kept.compile_seconds, kept.unit) == (1.0, 3.0, "episodes")
    # 6 seeds x 10 episodes on 3 threads: 3 + 1 * 60 / 3
    assert kept.seconds(6, 10, 3) == 23.0
    # one seed runs on one thread however many there are
    assert kept.seconds(1, 10, 8) == 13.0
    pace.record("tabular X a", wall_seconds=2.0, compile_seconds=0.5, seeds=1, amount=4, unit="episodes")
    assert pace.stored()["tabular X a"].seconds_per_unit == 0.5  # the newest measurement replaces the older
    assert json.loads(cache.read_text()).keys() == {"tabular X a"}


def test_the_suite_keeps_its_paces_apart_from_the_users(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    assert "rlcompare-pace-" in os.environ["RLCOMPARE_PACE_FILE"]  # tests/conftest.py
    monkeypatch.setenv("RLCOMPARE_PACE_FILE", str(tmp_path / "mine.json"))
    pace.record("k", wall_seconds=1.0, compile_seconds=0.0, seeds=1, amount=1, unit="episodes")
    assert json.loads((tmp_path / "mine.json").read_text()).keys() == {"k"}


def test_nothing_is_kept_of_an_empty_training_and_a_damaged_or_unwritable_file_costs_nothing(cache: Path) -> None:
    pace.record("k", wall_seconds=0.0, compile_seconds=1.0, seeds=1, amount=1, unit="episodes")
    assert not cache.exists()
    cache.parent.mkdir(parents=True)
    cache.write_text("{not json")
    assert pace.stored() == {}
    cache.write_text(json.dumps({"k": {"seconds_per_unit": "fast"}}))
    assert pace.stored() == {}
    cache.unlink()
    os.chmod(cache.parent, 0o500)
    try:
        if os.access(cache.parent, os.W_OK):
            pytest.skip("running as a user who writes anywhere")
        pace.record("k", wall_seconds=1.0, compile_seconds=0.0, seeds=1, amount=1, unit="episodes")  # no error
        assert pace.stored() == {}
    finally:
        os.chmod(cache.parent, 0o700)


def test_a_plan_adds_the_kept_paces_and_names_the_trainings_that_never_ran_here() -> None:
    trainings = (Training("a", 4, 100, "episodes", "tabular E a", 2), Training("b", 2, 50, "episodes", "tabular E b"),
                 Training("c", 3, 10, "episodes", "tabular E c"))
    paces = {"tabular E a": pace.Pace(0.5, 1.0, "episodes", "2026-01-02"),
             "tabular E b": pace.Pace(0.2, 0.0, "episodes", "2026-03-04"),
             "report s": pace.Pace(30.0, 0.0, "report", "2026-02-01")}
    plan = StudyPlan(trainings)
    # a: 1 + 0.5 * 400 / 2 = 101; b: 0.2 * 100 = 20; the report 30: 151 s
    line = plan.time_line(paces, "report s")
    assert line.startswith(f"Time: about {duration(151)} on this machine")
    assert duration(151) == "2.5 min"
    assert "newest 2026-03-04" in line
    assert line.endswith("not counted, never run here with these settings: c.")
    assert plan.time_line({}, "report s").startswith("Time: not known yet")
    assert "not counted" not in StudyPlan(trainings[:2]).time_line(paces)
    assert [duration(s) for s in (40, 89.4, 108, 600, 5400, 12600)] == ["40 s", "89 s", "1.8 min", "10 min", "1.5 h",
                                                                      "3.5 h"]


def test_a_paces_key_leaves_out_how_much_is_trained_and_keeps_how() -> None:
    config = ExperimentConfig(algorithm="sarsa", seeds=(0, 1, 2), episodes=20)
    assert pace.key("tabular", config) == pace.key("tabular", replace(config, seeds=(5,), episodes=900))
    assert pace.key("tabular", config) != pace.key("tabular", replace(config, alpha=0.5))
    assert {"seeds", "episodes", "eval_every"}.isdisjoint(pace.settings_of(config))
    assert pace.without_amounts({"a": 1, "hyperparameters": {"total_steps": 9, "lr": 2}}) == {
        "a": 1, "hyperparameters": {"lr": 2}}
    assert pace.settings_of(config)["alpha"] == config.alpha


def test_trainings_run_two_at_once_take_half_their_sum() -> None:
    trainings = tuple(Training(name, 1, 10, "episodes", "k") for name in "abc")
    paces = {"k": pace.Pace(1.0, 2.0, "episodes", "2026-01-01")}
    # three trainings of 2 + 10 s, two at once: 36 / 2; one training alone is not sped up
    assert StudyPlan(trainings, workers=2).time_line(paces).startswith("Time: about 18 s")
    assert StudyPlan(trainings[:1], workers=2).time_line(paces).startswith("Time: about 12 s")


def test_trainings_finished_already_are_not_counted() -> None:
    trainings = (Training("a", 1, 10, "episodes", "k"), Training("b", 1, 10, "episodes", "k"))
    paces = {"k": pace.Pace(1.0, 0.0, "episodes", "2026-01-01")}
    assert StudyPlan(trainings).time_line(paces, finished=["a"]) == (
        "Time: about 10 s on this machine, from the pace of its trainings measured here (newest 2026-01-01); "
        "1 training finished already, read and not counted.")


@pytest.mark.slow("trains a tabular configuration")
def test_a_training_keeps_its_pace_where_its_plan_looks(cache: Path) -> None:
    config = ExperimentConfig(algorithm="sarsa", seeds=(0, 1, 2), episodes=20, eval_every=10, eval_episodes=2)
    results = train(config)
    training = tabular_training(config.name, config)
    kept = pace.stored()[training.pace_key]
    assert training.pace_key.startswith("tabular MountainCar-v0 sarsa-decay ")
    timings = results.meta["timings"]
    threads = timings["threads"]
    assert kept.seconds_per_unit == pytest.approx(timings["wall_seconds"] * threads / (3 * 20))
    assert kept.unit == "episodes"


@pytest.mark.slow("runs a small paper study twice")
def test_a_study_run_once_plans_its_time_from_its_own_pace(cache: Path, tmp_path: Path) -> None:
    args = ("reproduce", "--seeds", "3", "--episodes", "5", "--no-videos", "--allow-undecidable")
    before = invoke(*args, "--plan", "--out", str(tmp_path / "a"))
    assert before.output.splitlines()[1].startswith("Time: not known yet"), before.output
    ran = invoke(*args, "--out", str(tmp_path / "a"))
    assert ran.exit_code == 0, ran.output
    assert ran.output.splitlines()[1].startswith("Time: not known yet")
    after = invoke(*args, "--plan", "--out", str(tmp_path / "b"))
    assert after.output.splitlines()[1].startswith("Time: about "), after.output
    assert "not counted" not in after.output
    assert "report paper" in pace.stored()


def test_a_plan_names_its_largest_training_known_before_it_runs() -> None:
    small, large = Training("a", 1, 1, "episodes", memory=3 * 2**20), Training("b", 1, 1, "episodes", memory=2**31)
    assert "Memory: the largest training known before it runs holds 3.0 MiB (a: " in StudyPlan((small,)).lines()[-1]
    assert "holds 2.0 GiB (b: " in StudyPlan((small, large)).lines()[-1]
    assert not any(line.startswith("Memory") for line in StudyPlan((Training("c", 1, 1, "steps"),)).lines())
    config = ExperimentConfig(env="CliffWalking-v1", seeds=(0, 1), episodes=10, eval_every=0)
    # records: 2 x 10 x 17 + 10 x 8 (returns, lengths, endings; epsilon), snapshots 2 x 3 x 48 x 4 x 8, visits
    # 2 x 48 x 8, the snapshots' episodes 3 x 8; then each seed's weights twice and streams: 2 x (2 x 1,536 + 192)
    assert tabular_training("x", config).memory == 340 + 80 + 9_216 + 768 + 24 + 2 * (2 * 1_536 + 192) == 16_956
