"""``reproduce why``: the factorial of target x order, and the decomposition of SARSA minus Q-Learning."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from helpers import invoke

from rlcompare.studies.interface import UI
from rlcompare.studies.paper import why
from rlcompare.studies.paper.claims import paper_claim, within
from rlcompare.studies.paper.why import TERMS, decomposition, per_seed_returns, term_per_seed, why_configs
from rlcompare.studies.registry import WhyOptions

SEEDS, EPISODES = (0, 1, 2, 3), 120


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    out = tmp_path_factory.mktemp("why") / "why"
    runs = why.run(out, WhyOptions(seeds=len(SEEDS), episodes=EPISODES), UI())
    return out, runs


def test_the_factorial_has_every_target_and_order_per_schedule():
    configs = why_configs(SEEDS, EPISODES)
    cells = {(c.schedule, c.algorithm, c.next_action) for c in configs.values()}
    assert cells == {(s, a, o) for s in ("constant", "decay") for a in ("q_learning", "sarsa", "expected_sarsa")
                     for o in ("before_update", "after_update")}
    assert all(c.target_epsilon is None and c.alpha == 0.05 and c.gamma == 0.9 for c in configs.values())
    assert set(configs) == {f"{c.algorithm}-{c.schedule}-{c.next_action}" for c in configs.values()}


def test_each_cell_writes_its_run_directory_with_its_order(study):
    out, runs = study
    assert set(runs) == set(why_configs(SEEDS, EPISODES))
    for name, results in runs.items():
        stored = json.loads((out / name / "config.json").read_text())
        assert (stored["algorithm"], stored["schedule"], stored["next_action"]) == (
            results.config.algorithm, results.config.schedule, results.config.next_action)
    # the two orders of one method learn differently (the order matters on this grid)
    a, b = runs["q_learning-constant-before_update"], runs["q_learning-constant-after_update"]
    assert not np.array_equal(a.records.returns, b.records.returns)


def test_terms_by_hand():
    values = {("sarsa", "before_update"): [5.0, 7.0], ("sarsa", "after_update"): [3.0, 2.0],
              ("q_learning", "before_update"): [4.0, 1.0], ("q_learning", "after_update"): [1.0, 1.0],
              ("expected_sarsa", "before_update"): [0.0, 0.0], ("expected_sarsa", "after_update"): [2.0, -1.0]}
    cells = {cell: np.array(v) for cell, v in values.items()}
    np.testing.assert_array_equal(term_per_seed(cells, "SARSA - Q-Learning"), [4.0, 6.0])
    np.testing.assert_array_equal(term_per_seed(cells, "order"), [3.0, 0.0])
    np.testing.assert_array_equal(term_per_seed(cells, "target"), [2.0, 1.0])
    np.testing.assert_array_equal(term_per_seed(cells, "interaction"), [5 - 3 - 4 + 1, 7 - 2 - 1 + 1])
    np.testing.assert_array_equal(term_per_seed(cells, "expectation target"), [1.0, -2.0])
    np.testing.assert_array_equal(term_per_seed(cells, "order, expectation target"), [-2.0, 1.0])


def test_the_parts_add_up_to_the_total_on_real_runs(study):
    _, runs = study
    frame = decomposition(runs)
    assert len(frame) == 2 * 2 * 3  # schedules x returns x windows
    for row in frame.itertuples(index=False):
        parts = sum(getattr(row, term).value for term in ("order", "target", "interaction"))
        assert parts == pytest.approx(row[3].value, abs=1e-9)
    by_hand = (per_seed_returns(runs["sarsa-decay-before_update"], "behaviour", 0, EPISODES)
               - per_seed_returns(runs["q_learning-decay-after_update"], "behaviour", 0, EPISODES)).mean()
    total = frame[(frame["schedule"] == "decay") & (frame["return"] == "behaviour")
                  & (frame["episodes"] == "all training")]["SARSA - Q-Learning"].iloc[0]
    assert total.value == pytest.approx(by_hand, rel=1e-12)
    assert total.low <= total.value <= total.high


def test_windows_split_training_and_greedy_returns_read_the_rounds_inside():
    assert why.windows(5000) == {"all training": (0, 5000), "first 1000": (0, 1000), "last 1000": (4000, 5000)}
    assert why.windows(120) == {"all training": (0, 120), "first 60": (0, 60), "last 60": (60, 120)}


@pytest.mark.slow("trains the why study")
def test_report_opens_with_findings_and_names_every_term(study):
    out, runs = study
    path = why.report(out, runs=runs).path
    page = path.read_text()
    assert page.index("Findings") < page.index("Decomposition")
    for term in TERMS:
        assert term in page
    sentences = why.findings(decomposition(runs))
    assert any(s.startswith("With ε decaying, SARSA's return while learning") for s in sentences)
    assert (out / "figures" / "decomposition.png").stat().st_size > 10_000
    assert (out / "tables" / "decomposition.csv").is_file()


@pytest.mark.slow("trains the why study")
def test_the_paper_study_runs_the_order_ablation_and_its_report_opens_with_findings(study):
    from rlcompare.studies.paper.claims import CLAIMS
    from rlcompare.studies.paper.report import build_report
    from rlcompare.studies.paper.study import paper_configs, reproduce

    out, runs = study
    paper_dir = out.parent / "paper"
    configs = paper_configs(SEEDS, EPISODES)
    assert {c.name for c in configs} == {"random", *(f"{a}-{s}" for a in ("q_learning", "sarsa")
                                                     for s in ("decay", "constant")),
                                         *(f"q_learning-{s}-before_update" for s in ("decay", "constant")),
                                         *(f"sarsa-{s}-after_update" for s in ("decay", "constant"))}
    for _ in reproduce(paper_dir, configs):
        pass
    outcome = build_report(paper_dir, videos=False)
    assert [s[:len("With ε decaying, SARSA collects")] for s in outcome.lines[:2]] == [
        "With ε constant, SARSA collects", "With ε decaying, SARSA collects"]  # a sentence per schedule
    assert outcome.lines[2].startswith(f"Of the paper's {len(CLAIMS)} claims tested here:")
    # the same cells, run by either study, give the same decomposition
    assert outcome.lines[3:] == why.findings(decomposition(runs))[:len(outcome.lines) - 3]
    page = outcome.path.read_text()
    assert page.index(">The answer</h2>") < page.index('href="#setting"') < page.index(">Setting</h2>")


def test_the_opening_says_the_gaps_in_words_with_the_labels():
    import pandas as pd

    from rlcompare.report.findings import gap_and_interval, more_or_less, opening, tally
    from rlcompare.stats.compare import compare_paired
    from rlcompare.stats.intervals import Estimate

    claims = [paper_claim("a", "constant", "behaviour_return"), paper_claim("b", "constant", "greedy_return"),
              paper_claim("c", "decay", "behaviour_return", sign=-1),
              paper_claim("d", "decay", "greedy_return", kind="within", bounds=within(20)),
              paper_claim("e", "decay", "convergence_episode", kind="within", bounds=within(10))]
    verdicts = pd.DataFrame({"verdict": ["supported", "not resolved", "supported", "supported",
                                         "not resolved (fragile)"],
                             "p (Holm)": [0.01, 0.3, 0.02, 0.01, 0.5], "fragile": [False] * 4 + [True]})
    rng = np.random.default_rng(0)
    metrics = {name: pd.DataFrame({"behaviour_return": rng.normal(shift, 1, 8), "greedy_return": rng.normal(0, 5, 8)})
               for name, shift in (("sarsa-constant", 5), ("q_learning-constant", 0), ("sarsa-decay", -3),
                                   ("q_learning-decay", 0))}
    sentences = opening(claims, verdicts, metrics)
    gap = compare_paired(metrics["sarsa-constant"]["behaviour_return"].to_numpy(),
                         metrics["q_learning-constant"]["behaviour_return"].to_numpy(), improvement=False).difference
    words, interval = gap_and_interval(gap)
    assert sentences[0].startswith(f"With ε constant, SARSA collects {words} reward per episode than Q-Learning while "
                                   f"it learns ({interval}; SARSA better, with the 5 claims corrected together)")
    assert "; not resolved once the 5 claims are corrected together). 8 paired seeds." in sentences[0]
    assert " less reward per episode than Q-Learning while it learns (95% interval" in sentences[1]
    assert "; Q-Learning better, with the 5 claims corrected together)" in sentences[1]  # the claim: SARSA lower
    assert "; the same within ±20: supported)" in sentences[1]
    assert more_or_less(Estimate(8.68, 1.89, 14.5)) == "8.68 more (95% interval 1.89 to 14.5)"
    assert more_or_less(Estimate(-3.1, -5.0, -1.2)) == "3.1 less (95% interval 1.2 to 5)"
    assert more_or_less(Estimate(14.2, -19.8, 88.0)) == "14.2 more (95% interval 19.8 less to 88 more)"
    assert more_or_less(Estimate(-250.0, -600.0, -120.0)) == "250 less (95% interval 120 to 600)"
    assert more_or_less(Estimate(5.3e-05, 1e-06, 9.9e-05)) == "0.000053 more (95% interval 0.000001 to 0.000099)"
    assert tally(verdicts) == ("Of the paper's 5 claims tested here: 3 supported, 2 not resolved; "
                               "1 of them fragile (another convergence rule decides it the other way).")


@pytest.mark.slow("trains the why study")
def test_reproduce_why_through_the_cli_then_report_rebuilds_it(tmp_path):


    out = tmp_path / "why"
    result = invoke("reproduce", "why", "--allow-undecidable", "--seeds", "3", "--episodes", "60", "--out", str(out),
                    columns=None)
    assert result.exit_code == 0, result.output
    assert "With ε constant, SARSA's return while learning" in result.output
    assert len(list(out.glob("*/config.json"))) == 12
    page = (out / "report.html").read_bytes()
    from rlcompare.report.findings import BEHAVIOUR_AND_GREEDY

    assert BEHAVIOUR_AND_GREEDY.encode() in page  # it shows both returns, so it says why they differ
    (out / "report.html").unlink()
    again = invoke("report", str(out), columns=None)
    assert again.exit_code == 0, again.output
    assert (out / "report.html").read_bytes() == page


@pytest.mark.parametrize(("arguments", "field"), [
    (["run", "--next-action", "first"], "--next-action"),
    (["run", "--algorithm", "n_step_sarsa", "--next-action", "before_update"], "--next-action"),
    (["reproduce", "why", "--episodes", "0"], "--episodes"),
])
def test_bad_input_is_one_clear_message_and_exit_2(tmp_path, arguments, field):


    result = invoke(*arguments, "--out", str(tmp_path / "out"), columns=None)
    assert result.exit_code == 2
    assert field in result.output
    assert "Traceback" not in result.output
    assert not (tmp_path / "out").exists()


@pytest.mark.slow("trains the why study")
def test_a_missing_or_damaged_cell_is_named_and_the_rest_still_decomposed(study, tmp_path):
    import shutil

    out, _ = study
    copy = Path(shutil.copytree(out, tmp_path / "why"))
    shutil.rmtree(copy / "expected_sarsa-constant-before_update")
    (copy / "sarsa-decay-after_update" / "qtables.npz").write_bytes(b"damaged")
    path = why.report(copy).path
    page = path.read_text()
    assert "Read with care" in page
    assert "expected_sarsa-constant-before_update" in page
    assert "sarsa-decay-after_update" in page
    table = pd.read_csv(copy / "tables" / "decomposition.csv")
    assert set(table["schedule"]) == {"constant"}  # decay lost a cell the decomposition needs
    assert (table["order, expectation target"] == "not run").all()
    assert (table["order"] != "not run").all()


def test_the_answer_names_the_largest_part_of_each_schedule_in_brief():
    from rlcompare.stats.intervals import Estimate

    rows = [{"schedule": schedule, "return": "behaviour", "episodes": "all training",
             **dict(zip(("order", "target", "interaction"), map(lambda v: Estimate(v, v - 5, v + 5), values),
                        strict=True))}
            for schedule, values in (("constant", (15.6, -22.7, 15.9)), ("decay", (59.7, 12.0, -3.4)))]
    assert why.in_brief(pd.DataFrame(rows)) == (
        "Why, while learning: the largest part of the difference is, with ε constant, the target (the action taken "
        "against the max), at -22.7; with ε decaying, the order of choosing A' and updating, at +59.7.")
    assert why.in_brief(pd.DataFrame(rows[1:]).assign(schedule="decay")).count("with ε") == 1


@pytest.mark.slow("trains the why study")
def test_a_window_without_a_greedy_evaluation_says_so_instead_of_a_number(tmp_path):
    """30 episodes with evaluations every 50: the last window holds no greedy round; the answer says there is
    nothing to compare, never "nan"."""


    result = invoke("reproduce", "why", "--allow-undecidable", "--seeds", "2", "--episodes", "30", "--out",
                                      str(tmp_path / "why"), columns=300)
    assert result.exit_code == 0, result.output
    assert "no greedy evaluation fell in them, so there is nothing to compare" in result.output
    assert "nan" not in result.output
