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


def measured(units: int, seconds: float, compile_seconds: float = 0.0, compiled: bool = False,
             day: str = "2026-01-01") -> pace.Measure:
    """A measurement of ``units`` units a seed in ``seconds`` (one seed, one thread)."""
    return pace.Measure(units, seconds, compile_seconds, compiled, "episodes", day)


def kept_at(*measures: pace.Measure) -> pace.Pace:
    return pace.Pace(measures)


def test_a_pace_is_kept_per_seed_and_thread_with_its_size_and_read_back(cache: Path) -> None:
    # 4 seeds x 5 episodes in 10 s on 2 threads: each seed's 5 episodes took 10 * 2 / 4 = 5 s of one thread
    pace.record("tabular X a", wall_seconds=10.0, compile_seconds=3.0, seeds=4, amount=5, unit="episodes", threads=2)
    kept = pace.stored()["tabular X a"]
    assert kept.measures == (pace.Measure(5, 5.0, 3.0, False, "episodes", kept.measured),)
    # 6 seeds x 5 episodes on 3 threads: 3 + 5 * 6 / 3
    assert kept.seconds(6, 5, 3) == 13.0
    # one seed runs on one thread however many there are
    assert kept.seconds(1, 5, 8) == 8.0
    # a run of 6 episodes is of about the same size (within 1.5 times): the newest replaces it
    pace.record("tabular X a", wall_seconds=3.0, compile_seconds=0.5, seeds=1, amount=6, unit="episodes")
    assert [(m.units, m.seconds) for m in pace.stored()["tabular X a"].measures] == [(6, 3.0)]
    # other sizes are kept beside it, the newest four
    for episodes in (60, 600, 6_000, 60_000):
        pace.record("tabular X a", wall_seconds=episodes / 10, compile_seconds=0.0, seeds=1, amount=episodes,
                    unit="episodes")
    assert [m.units for m in pace.stored()["tabular X a"].measures] == [60, 600, 6_000, 60_000]
    assert json.loads(cache.read_text()).keys() == {"tabular X a"}


def test_a_seeds_time_is_read_between_the_sizes_measured_on_a_log_log_line() -> None:
    # a seed's 100 episodes took 10 s, its 10,000 took 100 s (later episodes are shorter): 1,000 lies halfway
    # between on a log scale, so its time lies halfway between log 10 and log 100: 10 ** 1.5 = 31.6 s
    kept = kept_at(measured(10_000, 100.0), measured(100, 10.0))
    assert kept.per_seed(1_000) == pytest.approx(10 ** 1.5)
    assert kept.per_seed(100) == 10.0
    assert kept.per_seed(10_000) == 100.0
    # 2 seeds on 2 threads: one seed's time; 4 seeds on 2 threads: two seeds' time
    assert kept.seconds(2, 1_000, 2) == pytest.approx(31.62, abs=0.01)
    assert kept.seconds(4, 1_000, 2) == pytest.approx(63.25, abs=0.01)
    assert not kept.far(1_000)
    assert not kept.far(40_000)
    assert kept.far(40_001)


def test_a_small_runs_pace_is_not_applied_blindly_to_a_huge_one() -> None:
    # 100 episodes in 2 s (long early episodes: 0.02 s each), 1,000 in 5 s (0.005 s each): 100,000 episodes are
    # read from the nearest size, 1,000, in proportion (500 s), not from the smallest's pace (2,000 s)
    kept = kept_at(measured(100, 2.0), measured(1_000, 5.0))
    assert kept.per_seed(100_000) == pytest.approx(500.0)
    assert kept.far(100_000)
    assert kept.nearest(100_000).units == 1_000
    # and the plan names what it extrapolated
    trainings = (Training("huge", 1, 100_000, "episodes", "k"), Training("near", 1, 1_000, "episodes", "k"))
    assert StudyPlan(trainings).time_line({"k": kept}) == (
        f"Time: about {duration(505)} on this machine, from the pace of its trainings measured here (newest "
        "2026-01-01); extrapolated for 1 training, from runs of 1,000 episodes: huge trains 100,000.")


def test_a_compile_is_counted_as_the_cache_will_load_it() -> None:
    # compiled afresh in 30 s: the cache holds it now, so the next run loads it (at most LOAD_SECONDS)
    assert kept_at(measured(10, 1.0, 30.0, compiled=True)).compile() == pace.LOAD_SECONDS
    assert kept_at(measured(10, 1.0, 0.3, compiled=True)).compile() == 0.3
    # a load measured before is what the next run takes; the run itself took its 30 s
    kept = kept_at(measured(1_000, 1.0, 0.5), measured(10, 1.0, 30.0, compiled=True))
    assert kept.compile() == 0.5
    assert kept.seconds(1, 10, 1) == 1.5
    assert kept.seconds(1, 10, 1, as_run=True) == 31.0


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
    cache.write_text(json.dumps({"k": [{"units": 1, "seconds": "fast"}]}))
    assert pace.stored() == {}
    # a pace kept in the older form (no size) is not read
    cache.write_text(json.dumps({"k": {"seconds_per_unit": 1.0, "compile_seconds": 0.0, "unit": "episodes",
                                       "measured": "2026-01-01"}}))
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


def test_a_plan_adds_the_kept_paces_and_the_rest_and_names_the_trainings_that_never_ran_here() -> None:
    trainings = (Training("a", 4, 100, "episodes", "tabular E a", 2), Training("b", 2, 50, "episodes", "tabular E b"),
                 Training("c", 3, 10, "episodes", "tabular E c"))
    paces = {"tabular E a": kept_at(measured(100, 50.0, 1.0, day="2026-01-02")),
             "tabular E b": kept_at(measured(50, 10.0, day="2026-03-04")),
             "rest s": kept_at(pace.Measure(1, 30.0, 0.0, False, "rest", "2026-02-01"))}
    plan = StudyPlan(trainings)
    # a: 1 + 50 * 4 / 2 = 101; b: 10 * 2 = 20; the rest of the study's last run 30: 151 s
    line = plan.time_line(paces, "rest s")
    assert line.startswith(f"Time: about {duration(151)} on this machine")
    assert duration(151) == "2.5 min"
    assert "newest 2026-03-04" in line
    assert line.endswith("not counted, never run here with these settings: c.")
    assert plan.training_seconds(paces) == 121
    assert plan.time_line({}, "rest s").startswith("Time: not known yet")
    assert StudyPlan(trainings[:2]).time_line(paces, "rest t").endswith("; the report not counted (never run here).")
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
    from rlcompare.deep.config import DeepConfig

    deep = DeepConfig(algorithm="pqn_q_lambda", env="CartPole-v1", seeds=(0, 1), vmap_width=2)
    # a deep training's seeds side by side (its vmap width, at most its seeds) are how many, not how
    assert pace.key("deep", deep) == pace.key("deep", replace(deep, seeds=(0, 1, 2), vmap_width=3))


def test_trainings_run_two_at_once_take_half_their_sum() -> None:
    trainings = tuple(Training(name, 1, 10, "episodes", "k") for name in "abc")
    paces = {"k": kept_at(measured(10, 10.0, 2.0))}
    # three trainings of 2 + 10 s, two at once: 36 / 2; one training alone is not sped up
    assert StudyPlan(trainings, workers=2).time_line(paces).startswith("Time: about 18 s")
    assert StudyPlan(trainings[:1], workers=2).time_line(paces).startswith("Time: about 12 s")


def test_trainings_finished_already_are_not_counted() -> None:
    trainings = (Training("a", 1, 10, "episodes", "k"), Training("b", 1, 10, "episodes", "k"))
    paces = {"k": kept_at(measured(10, 10.0))}
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
    [measure] = kept.measures
    assert measure.seconds == pytest.approx(timings["wall_seconds"] * threads / 3)
    assert (measure.units, measure.unit) == (20, "episodes")
    assert measure.compile_seconds == timings["compile_seconds"]


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
    rest = pace.stored()["rest paper no-videos"].per_seed(1)
    trained = sum(m.seconds for key, p in pace.stored().items() if key.startswith("tabular") for m in p.measures)
    assert 0 < rest < 60
    assert trained > 0


def test_a_plan_names_its_largest_training_known_before_it_runs() -> None:
    small, large = Training("a", 1, 1, "episodes", memory=3 * 2**20), Training("b", 1, 1, "episodes", memory=2**31)
    assert "Memory: the largest training known before it runs holds 3.0 MiB (a: " in StudyPlan((small,)).lines()[-1]
    assert "holds 2.0 GiB (b: " in StudyPlan((small, large)).lines()[-1]
    assert not any(line.startswith("Memory") for line in StudyPlan((Training("c", 1, 1, "steps"),)).lines())
    config = ExperimentConfig(env="CliffWalking-v1", seeds=(0, 1), episodes=10, eval_every=0)
    # records: 2 x 10 x 17 + 10 x 8 (returns, lengths, endings; epsilon), snapshots 2 x 3 x 48 x 4 x 8, visits
    # 2 x 48 x 8, the snapshots' episodes 3 x 8; then each seed's weights twice and streams: 2 x (2 x 1,536 + 192)
    assert tabular_training("x", config).memory == 340 + 80 + 9_216 + 768 + 24 + 2 * (2 * 1_536 + 192) == 16_956
