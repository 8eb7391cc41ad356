"""Figure 6.3 (``reproduce book-6.3``): the study through the command line at a tiny size, the memory its long
asymptotic runs take, and its verdicts on numbers with a known answer."""

from __future__ import annotations

import dataclasses
import json
import tracemalloc
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from helpers import invoke
from scipy import stats

from rlcompare.experiment import rundir, store
from rlcompare.experiment.engines import load_if_complete
from rlcompare.stats.intervals import mean_interval
from rlcompare.studies.book import figure_6_3 as book_6_3
from rlcompare.studies.registry import STUDIES
from rlcompare.tabular.config import ExperimentConfig
from rlcompare.tabular.memory import records_bytes


@pytest.mark.slow("trains Figure 6.3's grid")
def test_the_default_study_is_the_books_grid_at_the_books_run_counts() -> None:
    configs = book_6_3.configs(STUDIES["book-6.3"].options().seed_range)
    assert len(configs) == 2 * 3 * 10
    interim = [c for name, c in configs.items() if name.startswith("interim-")]
    asymptotic = [c for name, c in configs.items() if name.startswith("asymptotic-")]
    assert {(len(c.seeds), c.episodes) for c in interim} == {(50_000, 100)}
    assert {(c.seeds, c.episodes) for c in asymptotic} == {(tuple(range(10)), 100_000)}
    assert {c.alpha for c in interim} == {c.alpha for c in asymptotic} == {0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7,
                                                                          0.8, 0.9, 1.0}
    for c in configs.values():
        assert (c.env, c.schedule, c.epsilon, c.gamma, c.eval_every) == ("CliffWalking-v1", "constant", 0.1, 1.0, 0)
        assert c.seeds == tuple(range(len(c.seeds)))  # the same seeds for every method and α: paired
    assert configs["interim-expected_sarsa-alpha-0.3"].algorithm == "expected_sarsa"
    assert [book_6_3.asymptotic_runs(n) for n in (1, 2, 4, 5_000, 25_000, 50_000)] == [1, 2, 2, 2, 5, 10]
    assert book_6_3.configs((0, 1, 2), episodes=300)["asymptotic-sarsa-alpha-1"].episodes == 300


@pytest.mark.slow("trains Figure 6.3's grid")
def test_the_study_at_a_tiny_size_through_the_command_line(tmp_path: Path) -> None:
    out = tmp_path / "b63"
    result = invoke("reproduce", "book-6.3", "--allow-undecidable", "--runs", "4", "--episodes", "300", "--out",
                    str(out))
    assert result.exit_code == 0, result.output
    names = sorted(book_6_3.configs((0,)))
    assert sorted(p.name for p in out.iterdir()) == sorted([*names, "figures", "tables", "report.html",
                                                            rundir.MEMBERS_FILE, *store.OWN_FILES])
    for name in names:
        assert sorted(p.name for p in (out / name).iterdir()) == sorted(book_6_3.RUN_FILES + store.OWN_FILES)
        config = json.loads((out / name / "config.json").read_text())
        phase, method, _, alpha = name.split("-")
        assert (config["algorithm"], config["alpha"]) == (method, float(alpha))
        assert config["episodes"] == (100 if phase == "interim" else 300)
        runs = pd.read_parquet(out / name / book_6_3.RUNS_FILE)
        assert runs["seed"].tolist() == ([0, 1, 2, 3] if phase == "interim" else [0, 1])
        assert (runs["cut"] == 0).all()
        assert (runs["steps"] >= config["episodes"] * 13).all()
    table = pd.read_csv(out / "tables" / "fig6_3.csv")
    assert len(table) == 60
    assert set(table["phase"]) == {"interim", "asymptotic"}
    verdicts = pd.read_csv(out / "tables" / "verdicts.csv")
    assert len(verdicts) == 20 + 2 + 20
    html = (out / "report.html").read_text()
    assert "Figure 6.3" in html
    assert "figures/fig6_3.png" in html
    assert "4 runs x 100 episodes (interim) and 2 runs x 300 episodes (asymptotic)" in html
    assert "The study took" in html
    assert "Runs and seconds, per phase" in html
    assert (out / "figures" / "fig6_3.png").stat().st_size > 10_000

    # What the report reads is all in the run directories: rebuilt without training, the same numbers.
    rebuilt = invoke("report", str(out))
    assert rebuilt.exit_code == 0, rebuilt.output
    pd.testing.assert_frame_equal(pd.read_csv(out / "tables" / "fig6_3.csv"), table)
    # Run again, every configuration is loaded, not trained.
    again = invoke("reproduce", "book-6.3", "--allow-undecidable", "--runs", "4", "--episodes", "300", "--out",
                   str(out))
    assert again.exit_code == 0, again.output
    assert again.output.count("loaded (already complete)") == 60


def test_reproduce_refuses_a_bad_episode_count(tmp_path: Path) -> None:
    result = invoke("reproduce", "book-6.3", "--episodes", "0", "--out", str(tmp_path / "b63"))
    assert result.exit_code == 2
    assert "--episodes" in result.output


@pytest.mark.slow("trains Figure 6.3's grid")
def test_the_asymptotic_phase_keeps_memory_bounded(monkeypatch) -> None:
    # The default asymptotic runs (10 x 100,000 episodes) train in blocks whose records stay under BLOCK_BYTES,
    # and so would any number of runs.
    default = book_6_3.configs(tuple(range(50_000)))
    for config in default.values():
        block = book_6_3.block_runs(config)
        assert block * book_6_3.run_bytes(config) <= book_6_3.BLOCK_BYTES
        assert records_bytes(dataclasses.replace(config, seeds=config.seeds[:block])) < book_6_3.BLOCK_BYTES
    assert book_6_3.block_runs(default["interim-sarsa-alpha-1"]) == 5457  # 10 blocks of 50,000 runs
    many = dataclasses.replace(default["asymptotic-sarsa-alpha-1"], seeds=tuple(range(1000)))
    assert book_6_3.block_runs(many) == 13  # 100,000-episode runs, 13 at a time, however many there are
    # return, length and ending of each episode, and the configuration's ε of each (counted once a run)
    assert book_6_3.run_bytes(many) == pytest.approx(100_000 * (8 + 8 + 1 + 8), rel=0.01)

    # Measured: the default asymptotic configuration (10 runs x 100,000 episodes) allocates under BLOCK_BYTES ...
    config = default["asymptotic-expected_sarsa-alpha-1"]
    book_6_3.summarise(dataclasses.replace(config, seeds=(0,), episodes=10))  # compile or load outside the count
    summary, peak = _peak(lambda: book_6_3.summarise(config))
    assert summary.meta["timings"]["blocks"] == 1
    assert peak < book_6_3.BLOCK_BYTES
    assert summary.runs["return"].between(-25, -18).all()  # Expected SARSA's safe path, about -20 an episode
    # ... and with blocks of one run, three runs allocate one run's worth at a time, not three.
    three = dataclasses.replace(config, seeds=(0, 1, 2))
    monkeypatch.setattr(book_6_3, "BLOCK_BYTES", book_6_3.run_bytes(three))
    summary, peak = _peak(lambda: book_6_3.summarise(three))
    assert summary.meta["timings"]["blocks"] == 3
    assert peak < 1.5 * book_6_3.run_bytes(three)


def _peak(call):
    """What ``call()`` returns, and the most memory Python and NumPy had allocated at once during it."""
    tracemalloc.start()
    try:
        return call(), tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def _synthetic(interim: dict[str, float], asymptotic: dict[str, dict[float, float]], noise: float = 1.0
               ) -> dict[str, book_6_3.PhaseRuns]:
    """Runs whose per-run mean returns are the given means plus shared per-seed noise (as common random numbers
    give) and a little of their own."""
    configs = {name: dataclasses.replace(config, seeds=tuple(range(10))) if book_6_3.phase_of(config) == "asymptotic"
               else config for name, config in book_6_3.configs(tuple(range(200)), 1000).items()}
    rng = np.random.default_rng(0)
    shared = {phase: rng.normal(0, 5, len(configs[f"{phase}-sarsa-alpha-1"].seeds)) for phase in book_6_3.PHASES}
    runs = {}
    for name, config in configs.items():
        phase, method, alpha = book_6_3.phase_of(config), config.algorithm, config.alpha
        mean = interim[method] if phase == "interim" else asymptotic[method][alpha]
        values = mean + shared[phase] + rng.normal(0, noise, len(config.seeds))
        frame = pd.DataFrame({"seed": list(config.seeds), "return": values, "steps": 0, "cut": 0})
        runs[name] = book_6_3.PhaseRuns(config, frame, np.zeros((len(config.seeds), 0, 48, 4)), {})
    return runs


def _books_answer() -> tuple[dict[str, float], dict[str, dict[float, float]]]:
    alphas = book_6_3.ALPHAS
    sarsa = dict.fromkeys(alphas, -25.0) | {0.9: -45.0, 1.0: -100.0}  # collapses, below Q-Learning at α = 1
    return ({"sarsa": -70.0, "expected_sarsa": -55.0, "q_learning": -80.0},
            {"sarsa": sarsa, "expected_sarsa": dict.fromkeys(alphas, -20.0),
             "q_learning": dict.fromkeys(alphas, -50.0)})


def test_verdicts_on_synthetic_numbers_with_a_known_answer() -> None:
    interim, asymptotic = _books_answer()
    asymptotic["expected_sarsa"][0.3] = -26.0  # 1 below SARSA: exactly on the margin, neither shown nor refuted
    table = book_6_3.verdicts(book_6_3.claims(), _synthetic(interim, asymptotic)).set_index("claim")
    assert len(table) == 42
    assert table.loc["Q-Learning's asymptotic return below SARSA's, α = 1", "verdict"] == "contradicted"
    assert table.loc["Expected SARSA at least as good as SARSA, asymptotic, α = 0.3", "verdict"] == "not resolved"
    others = table.drop(["Q-Learning's asymptotic return below SARSA's, α = 1",
                         "Expected SARSA at least as good as SARSA, asymptotic, α = 0.3"])
    assert (others["verdict"] == "supported").all(), others[others["verdict"] != "supported"]
    drop = table.loc["SARSA's asymptotic return collapses at large α", "mean [95% t interval]"]
    assert float(drop.split()[0]) == pytest.approx(75, abs=1.5)


def test_verdicts_turn_when_the_book_is_wrong() -> None:
    interim, asymptotic = _books_answer()
    interim["expected_sarsa"] = -75.0  # Expected SARSA 5 worse than SARSA: beyond the margin of 1
    asymptotic["expected_sarsa"] = {alpha: -20.0 - 20 * alpha for alpha in book_6_3.ALPHAS}  # falls by 18
    asymptotic["sarsa"] = dict.fromkeys(book_6_3.ALPHAS, -25.0)  # does not collapse
    table = book_6_3.verdicts(book_6_3.claims(), _synthetic(interim, asymptotic)).set_index("claim")
    interim_claims = table.loc[[f"Expected SARSA at least as good as SARSA, interim, α = {a:g}"
                                for a in book_6_3.ALPHAS]]
    assert (interim_claims["verdict"] == "contradicted").all()
    assert table.loc["SARSA's asymptotic return collapses at large α", "verdict"] == "contradicted"
    assert table.loc["Expected SARSA's asymptotic return does not collapse at large α", "verdict"] == "contradicted"


def test_mean_interval_is_students_t_with_the_modules_conventions() -> None:
    values = np.random.default_rng(1).normal(3.0, 2.0, 50_000)
    estimate = mean_interval(values)
    low, high = stats.t.interval(0.95, values.size - 1, loc=values.mean(), scale=stats.sem(values))
    assert estimate.value == pytest.approx(values.mean())
    assert (estimate.low, estimate.high) == (pytest.approx(low), pytest.approx(high))
    assert mean_interval(np.array([2.0, 2.0])) == (2.0, 2.0, 2.0)
    assert np.isnan(mean_interval(np.array([1.0])).low)
    assert np.isnan(mean_interval(np.array([1.0, np.nan])).value)


def test_a_damaged_run_directory_is_trained_again(tmp_path: Path) -> None:
    config = ExperimentConfig(algorithm="sarsa", alpha=0.5, episodes=20, seeds=(0, 1), **book_6_3.SETTINGS)
    first = book_6_3.train(config, out=tmp_path / "run")
    assert load_if_complete(tmp_path / "run", config, book_6_3.PhaseRuns.load).runs.equals(first.runs)
    assert load_if_complete(tmp_path / "run", dataclasses.replace(config, alpha=0.6), book_6_3.PhaseRuns.load) is None
    (tmp_path / "run" / book_6_3.RUNS_FILE).write_bytes(b"damaged")
    assert load_if_complete(tmp_path / "run", config, book_6_3.PhaseRuns.load) is None
