"""The paper's question on other problems: the cartpole study, and the cliff report set against Mountain Car."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest
from helpers import invoke, paper_study

from rlcompare.experiment.engines import load_run
from rlcompare.studies.book.contrast import contrast_table, load_pairs, sibling_studies


@pytest.mark.slow("trains and reports studies on other environments")
def test_cartpole_study_runs_the_papers_grid_and_reports_it_without_the_papers_numbers(tmp_path: Path) -> None:
    out = tmp_path / "cartpole"
    result = invoke("reproduce", "cartpole", "--allow-undecidable", "--seeds", "3", "--episodes", "300",
                    "--no-videos", "--out", str(out))
    assert result.exit_code == 0, result.output
    for name in ("random", "q_learning-decay", "q_learning-constant", "sarsa-decay", "sarsa-constant"):
        loaded = load_run(out / name)
        assert (loaded.config.env, loaded.config.bins, loaded.config.max_steps) == ("CartPole-v1", (1, 1, 6, 12), 500)
        assert (loaded.config.alpha, loaded.config.gamma) == (0.05, 0.9)  # the paper's settings
        assert loaded.meta["study"] == "cartpole"
    table_ii = pd.read_csv(out / "tables" / "table_ii.csv")
    assert table_ii["paper (Table II)"].isna().all()  # the paper's values are Mountain Car's
    verdicts = pd.read_csv(out / "tables" / "verdicts.csv")
    assert len(verdicts) == 8  # every claim but the two about Mountain Car's first action
    assert not verdicts["metric"].eq("first_action_left").any()
    html = (out / "report.html").read_text()
    assert "On- and off-policy control on CartPole-v1" in html
    assert "1 x 1 x 6 x 12 uniform cells" in html
    assert sorted(p.name for p in (out / "figures").iterdir()) == sorted(
        f"{name}.png" for name in ("fig3-random", "fig4-q_learning-constant", "fig5-sarsa-constant",
                                   "fig6-constant", "fig7-q_learning-decay", "fig8-sarsa-decay", "fig9-decay",
                                   "decomposition", "paired-differences", "aggregate-intervals",
                                   "probability-of-improvement", "performance-profiles", "sample-efficiency"))
    # CartPole is solved by balancing to the limit, not by terminating: greedy success counts those episodes.
    sarsa = load_run(out / "sarsa-decay")
    balanced = (~sarsa.records.eval_terminated[:, -1]) & (sarsa.records.eval_lengths[:, -1] == 500)
    row = table_ii.set_index("configuration").loc["sarsa-decay"]
    assert row["greedy success"] == f"{balanced.mean():.0%}"


@pytest.fixture(scope="module")
def studies(tmp_path_factory) -> Path:
    """A small paper study (its runs: the cliff's report reads no more of it) and the cliff study beside it."""
    root = tmp_path_factory.mktemp("studies")
    paper_study(root / "paper", seeds=4, episodes=400)
    assert invoke("reproduce", "cliff", "--allow-undecidable", "--seeds", "8", "--out",
                  str(root / "cliff")).exit_code == 0
    return root


@pytest.mark.slow("trains and reports studies on other environments")
def test_cliff_report_sets_the_cliff_against_mountain_car_in_numbers(studies: Path) -> None:
    table = contrast_table({"cliff": load_pairs(studies / "cliff"), **sibling_studies(studies / "cliff")})
    assert list(table["study"]) == ["cliff", "paper", "paper"]
    assert list(table["exploration"]) == ["ε = 0.1", "ε = 0.5", "ε decaying"]
    cliff = table.iloc[0]
    assert cliff["online: better"] == "SARSA better"  # the book's contrast: safe path online ...
    assert cliff["greedy: better"] == "Q-Learning better"  # ... the edge path greedy
    assert cliff["greedy: Q-Learning"] == "-13.0"
    html = (studies / "cliff" / "report.html").read_text()
    assert "Cliff Walking against Mountain Car: the contrast in numbers" in html
    for difference in table["online: SARSA - Q-Learning"]:
        assert difference in html  # each online difference, with its interval, is in the report
    assert "MountainCar-v0 (ε = 0.5, 4 seeds): online SARSA - Q-Learning" in html


@pytest.mark.slow("trains the book's 50 runs")
def test_cliff_runs_the_books_50_runs_and_says_how_to_add_mountain_car(tmp_path: Path) -> None:
    assert invoke("reproduce", "cliff", "--allow-undecidable", "--out", str(tmp_path / "cliff")).exit_code == 0
    assert load_run(tmp_path / "cliff" / "sarsa").seeds == tuple(range(50))
    html = (tmp_path / "cliff" / "report.html").read_text()
    assert "Mountain Car&#x27;s side is missing" in html
    assert f"reproduce --out {tmp_path / 'paper'}" in html
