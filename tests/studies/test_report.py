"""The paper study's report: tables and verdicts from stored runs, and what happens when runs are damaged."""

from __future__ import annotations

import itertools
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from helpers import invoke
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.transforms import Bbox

from rlcompare.experiment import rundir, store
from rlcompare.report.findings import BEHAVIOUR_AND_GREEDY
from rlcompare.stats import verdicts
from rlcompare.stats.convergence import RULES
from rlcompare.stats.intervals import interval
from rlcompare.stats.significance import VERDICTS
from rlcompare.stats.verdicts import columns, is_fragile
from rlcompare.studies.measures import per_seed_metrics
from rlcompare.studies.paper.claims import CLAIMS, NAMES, paper_claim, within
from rlcompare.studies.paper.figures import curve_figure, paired_difference_figure, stages_figure, visits_figure
from rlcompare.studies.paper.report import FIGURES, build_report, load_study
from rlcompare.studies.paper.study import paper_configs, reproduce
from rlcompare.studies.paper.videos import CONFIGURATIONS
from rlcompare.tabular.config import ExperimentConfig
from rlcompare.tabular.results import Results
from rlcompare.tabular.state import Records


def judge(*args, **kwargs):
    """:func:`rlcompare.stats.verdicts.judge` with the paper's names for A and B."""
    return verdicts.judge(*args, names=NAMES, **kwargs)

ABLATION = ("q_learning-constant-before_update", "q_learning-decay-before_update", "sarsa-constant-after_update",
            "sarsa-decay-after_update")
"""The order ablation's run directories, after the paper's five (``paper_configs``), in the order they load."""


@pytest.fixture(scope="module")
def study(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A small paper study: 4 seeds x 400 episodes of every configuration, trained once for the module."""
    path = tmp_path_factory.mktemp("study")
    list(reproduce(path, paper_configs((0, 1, 2, 3), episodes=400, eval_every=50, eval_episodes=3)))
    return path


@pytest.fixture
def study_copy(study: Path, tmp_path: Path) -> Path:
    return Path(shutil.copytree(study, tmp_path / "study"))


@pytest.mark.slow("trains a study and builds its report")
def test_report_writes_tables_figures_and_page(study_copy: Path) -> None:
    outcome = build_report(study_copy, videos=False)
    assert outcome.problems == []
    for name in ("table_i", "table_ii", "verdicts"):
        assert (study_copy / "tables" / f"{name}.csv").is_file()
        assert (study_copy / "tables" / f"{name}.md").read_text().startswith("| ")
    table_ii = pd.read_csv(study_copy / "tables" / "table_ii.csv")
    assert list(table_ii["configuration"]) == [*CONFIGURATIONS, *ABLATION]
    decomposition = pd.read_csv(study_copy / "tables" / "decomposition.csv")
    assert set(decomposition["schedule"]) == {"constant", "decay"}
    assert (decomposition["expectation target"] == "not run").all()  # the paper study runs no Expected SARSA
    assert table_ii.set_index("configuration").loc["sarsa-constant", "paper (Table II)"] == -176
    verdicts = pd.read_csv(study_copy / "tables" / "verdicts.csv")
    assert len(verdicts) == len(CLAIMS)
    assert list(verdicts.columns) == columns(NAMES)
    assert {v.removesuffix(" (fragile)") for v in verdicts["verdict"]} <= set(VERDICTS)
    assert (verdicts["p (Holm)"].dropna() >= verdicts["p"].dropna()).all()
    floored = verdicts[verdicts["metric"] == "first_action_left"]
    assert len(floored) == 2
    assert floored["noise floor"].str.contains("gap .* spread", regex=True).all()
    rules = pd.read_csv(study_copy / "tables" / "verdict_rules.csv")
    assert list(rules["claim"]) == [c.text for c in CLAIMS if c.metric == "convergence_episode"]
    behaviour_rules = [r.name for r in RULES if r.curve == "behaviour"]
    assert [name for name in rules.columns if name.startswith("band")] == behaviour_rules
    fragile = [is_fragile([str(v).removesuffix(" (fragile)") for v in row])
               for row in rules.drop(columns="claim").to_numpy()]
    assert list(rules["verdict"].str.endswith("(fragile)")) == fragile
    for file_name, _, _ in FIGURES:
        assert (study_copy / "figures" / f"{file_name}.png").stat().st_size > 10_000
    stages = sorted(p.name for p in (study_copy / "figures").glob("stages-*.png"))
    assert stages == sorted(f"stages-{name}.png" for name in CONFIGURATIONS if name != "random")  # boxes only
    page = (study_copy / "report.html").read_text()
    assert page.count("<img ") == len(list((study_copy / "figures").glob("*.png")))
    assert "Table I" in page
    assert "to the end of training" in page
    assert "Holm" in page
    assert "fragile" in page
    assert 'class="verdict-' in page
    assert "Read with care" not in page
    assert BEHAVIOUR_AND_GREEDY in page


def overlapping_or_cut(figure: Figure) -> list[str]:
    """What of a figure's laid-out panels lies outside it, or over another panel (its labels included)."""
    renderer = FigureCanvasAgg(figure).get_renderer()
    whole = figure.bbox
    panels = [(ax.get_title() or ax.get_ylabel() or "colorbar", ax.get_tightbbox(renderer))
              for ax in figure.axes if ax.axison]
    problems = [name for name, box in panels
                if box.x0 < whole.x0 - 1 or box.y0 < whole.y0 - 1 or box.x1 > whole.x1 + 1 or box.y1 > whole.y1 + 1]
    for (name, box), (other, other_box) in itertools.combinations(panels, 2):
        overlap = Bbox.intersection(box, other_box)
        if overlap is not None and overlap.width > 1 and overlap.height > 1:
            problems.append(f"{name} over {other}")
    return problems


@pytest.mark.slow("trains a study and builds its report")
def test_figures_laid_out_by_hand_keep_every_label_inside_and_apart(study: Path) -> None:
    runs, _ = load_study(study)
    learners = [runs[name] for name in CONFIGURATIONS if name != "random"]
    stages = stages_figure(learners[0])
    figures = {"stages": stages, "visits": visits_figure(learners),
               "curves": curve_figure([runs[name] for name in FIGURES[3][1]], FIGURES[3][2])}
    assert {name: overlapping_or_cut(figure) for name, figure in figures.items()} == {name: [] for name in figures}
    maps = [ax for ax in stages.axes if ax.get_xlabel() == "position"]
    columns = {round(ax.get_position().x0, 6) for ax in maps}
    assert len(columns) == len(maps) // 2  # the policy maps above line up with the value maps below
    assert {round(ax.get_position().width, 6) for ax in maps} == {round(maps[0].get_position().width, 6)}


def _synthetic(algorithm: str, schedule: str, returns: np.ndarray, greedy: np.ndarray,
               seeds: tuple[int, ...] = (0, 1, 2)) -> Results:
    """A run with the given behaviour returns ``(seeds, episodes)`` and greedy returns ``(seeds, rounds,
    episodes)``, every 50 episodes; nothing else of it is read by the figures."""
    runs, episodes = returns.shape
    config = ExperimentConfig(algorithm=algorithm, schedule=schedule, seeds=seeds, episodes=episodes, eval_every=50,
                              eval_episodes=greedy.shape[2])
    records = Records(returns=returns, lengths=np.ones((runs, episodes), dtype=np.int64),
                      terminated=np.ones((runs, episodes), dtype=bool), eval_returns=greedy,
                      eval_lengths=np.ones(greedy.shape, dtype=np.int64), eval_terminated=np.ones(greedy.shape, bool),
                      snapshots=np.zeros((runs, 3, 4, 3)), snapshot_episodes=np.array([1, 2, 3]),
                      visits=np.zeros((runs, 4), dtype=np.int64))
    return Results(config=config, epsilons=np.full(episodes, 0.5), records=records, meta={})


def _synthetic_pair(schedule: str = "constant", episodes: int = 300, gap: float = 10.0, seed: int = 0
                    ) -> tuple[Results, Results]:
    rng = np.random.default_rng(seed)
    q = rng.normal(-400, 50, (3, episodes))
    sarsa = q + gap + rng.normal(0, 5, (3, episodes))
    q_greedy = rng.normal(-200, 20, (3, episodes // 50, 2))
    return (_synthetic("sarsa", schedule, sarsa, q_greedy + rng.normal(gap, 8, q_greedy.shape)),
            _synthetic("q_learning", schedule, q, q_greedy))


def _trailing_mean(values: np.ndarray, window: int) -> np.ndarray:
    return np.array([values[max(0, i + 1 - window):i + 1].mean() for i in range(values.size)])


def test_curves_of_sarsa_and_q_learning_draw_their_paired_difference_below() -> None:
    sarsa, q = _synthetic_pair()
    figure = curve_figure([q, sarsa], "Fig. 6")
    behaviour, greedy, difference, greedy_difference = figure.axes[:4]
    assert "behaviour" in difference.get_title()
    assert "100" in difference.get_title()
    assert "greedy" in greedy_difference.get_title()
    gap = sarsa.records.returns - q.records.returns
    by_hand = np.mean([_trailing_mean(seed, 100) for seed in gap], axis=0)  # each seed smoothed, then the mean
    line, zero = difference.get_lines()
    np.testing.assert_allclose(line.get_xdata(), np.arange(1, 301))
    np.testing.assert_allclose(line.get_ydata(), by_hand)
    assert zero.get_ydata()[0] == 0
    (band,) = difference.collections
    low, high = band.get_paths()[0].vertices[:, 1].min(), band.get_paths()[0].vertices[:, 1].max()
    assert low < by_hand.min()
    assert by_hand.max() < high
    greedy_gap = (sarsa.records.eval_returns.mean(axis=2) - q.records.eval_returns.mean(axis=2)).mean(axis=0)
    np.testing.assert_allclose(greedy_difference.get_lines()[0].get_ydata(), greedy_gap)  # unsmoothed, as above
    np.testing.assert_allclose(greedy_difference.get_lines()[0].get_xdata(), [50, 100, 150, 200, 250, 300])
    assert "3 paired seeds" in line.get_label()
    assert behaviour.get_ylabel().startswith("behaviour")
    assert greedy.get_ylabel().startswith("greedy")
    assert overlapping_or_cut(figure) == []


def test_curves_draw_no_difference_unless_sarsa_and_q_learning_share_their_seeds() -> None:
    sarsa, q = _synthetic_pair()
    assert len(curve_figure([sarsa], "Fig. 5").axes) == 2
    other_seeds = _synthetic("q_learning", "constant", q.records.returns, q.records.eval_returns, seeds=(3, 4, 5))
    assert len(curve_figure([other_seeds, sarsa], "Fig. 6").axes) == 2
    assert len(curve_figure([q, _synthetic_pair(seed=1)[1]], "two Q-Learning").axes) == 2


def _panel(figure: Figure, metric: str):
    return next(ax for ax in figure.axes if ax.get_title().startswith(metric))


def test_paired_difference_figure_draws_each_seed_and_the_mean_with_its_interval() -> None:
    constant, decay = _synthetic_pair("constant", gap=10.0), _synthetic_pair("decay", gap=-20.0, seed=2)
    runs = {"sarsa-constant": constant[0], "q_learning-constant": constant[1], "sarsa-decay": decay[0],
            "q_learning-decay": decay[1]}
    figure = paired_difference_figure(runs)
    assert "3 seeds" in figure.get_suptitle()
    for metric, per_seed in (("behaviour", lambda r: r.records.returns.mean(axis=1)),
                             ("greedy", lambda r: r.records.eval_returns[:, -1].mean(axis=1))):
        ax = _panel(figure, metric)
        for schedule, (sarsa, q) in (("constant", constant), ("decay", decay)):
            differences = per_seed(sarsa) - per_seed(q)
            (dots,) = [c for c in ax.collections if c.get_gid() == f"seeds-{schedule}"]
            np.testing.assert_allclose(dots.get_offsets()[:, 1], differences)  # one dot a seed, in seed order
            (bar,) = [c for c in ax.collections if c.get_gid() == f"interval-{schedule}"]
            ((_, low), (_, high)), = bar.get_segments()
            estimate = interval(differences)
            assert (low, high) == pytest.approx((estimate.low, estimate.high))
            assert low < differences.mean() < high
        assert [line.get_ydata()[0] for line in ax.get_lines() if line.get_linestyle() == "-"][-1] == 0
    assert np.mean(_panel(figure, "behaviour").collections[0].get_offsets()[:, 1]) == pytest.approx(10, abs=3)
    del runs["q_learning-decay"]
    one = paired_difference_figure(runs)
    assert [c.get_gid() for c in _panel(one, "behaviour").collections if c.get_gid()] == [
        "seeds-constant", "interval-constant"]
    assert paired_difference_figure({"sarsa-decay": decay[0]}) is None


@pytest.mark.slow("trains a study and builds its report")
def test_paired_difference_figure_reads_the_numbers_of_table_ii(study: Path) -> None:
    runs, _ = load_study(study)
    metrics = {name: per_seed_metrics(results) for name, results in runs.items()}
    figure = paired_difference_figure(runs, metrics)
    assert overlapping_or_cut(figure) == []
    for metric in ("behaviour_return", "greedy_return"):
        ax = _panel(figure, metric.split("_")[0])
        for schedule in ("constant", "decay"):
            sarsa, q = metrics[f"sarsa-{schedule}"], metrics[f"q_learning-{schedule}"]
            (dots,) = [c for c in ax.collections if c.get_gid() == f"seeds-{schedule}"]
            np.testing.assert_allclose(dots.get_offsets()[:, 1], sarsa[metric] - q[metric])
    np.testing.assert_allclose(paired_difference_figure(runs).axes[0].collections[0].get_offsets(),
                               figure.axes[0].collections[0].get_offsets())  # the same numbers from the runs alone


@pytest.mark.slow("trains a study and builds its report")
def test_report_on_damaged_runs_names_what_is_missing_and_builds_the_rest(study_copy: Path) -> None:
    (study_copy / "sarsa-decay" / rundir.EPISODES_FILE).unlink()
    (study_copy / "q_learning-constant" / rundir.QTABLES_FILE).write_bytes(b"not a zip file")
    shutil.rmtree(study_copy / "random")
    result = invoke("report", str(study_copy), "--no-videos")
    assert result.exit_code == 2
    assert "sarsa-decay" in result.output
    assert "episodes.parquet" in result.output
    assert "q_learning-constant" in result.output
    assert "random: no run directory" in result.output
    assert isinstance(result.exception, SystemExit)
    table_ii = pd.read_csv(study_copy / "tables" / "table_ii.csv")
    assert list(table_ii["configuration"]) == ["q_learning-decay", "sarsa-constant", *ABLATION]
    assert (study_copy / "figures" / "stages-sarsa-constant.png").is_file()
    assert not (study_copy / "figures" / "fig3-random.png").exists()
    page = (study_copy / "report.html").read_text()
    assert "Read with care" in page
    assert "sarsa-decay" in page


def test_report_on_a_directory_with_no_runs_is_a_clear_error(tmp_path: Path) -> None:
    result = invoke("report", str(tmp_path), "--no-videos")
    assert result.exit_code == 2
    assert "was not written by rlcompare" in result.output
    store.claim(tmp_path / "study", store.Owner("study", "paper"))
    result = invoke("report", str(tmp_path / "study"), "--no-videos")
    assert result.exit_code == 2
    assert "no configuration of the paper study could be read" in result.output
    result = invoke("report", str(tmp_path / "absent"))
    assert result.exit_code == 2
    assert "STUDY_DIR" in result.output


def _metrics(sarsa: list[float], q: list[float], metric: str = "behaviour_return") -> dict[str, pd.DataFrame]:
    seeds = np.arange(len(sarsa))
    return {"sarsa-constant": pd.DataFrame({"seed": seeds, metric: sarsa}),
            "q_learning-constant": pd.DataFrame({"seed": seeds, metric: q})}


def test_judge_reads_the_direction_of_each_claim() -> None:
    rng = np.random.default_rng(0)
    q = rng.normal(-300, 5, 20)
    better = paper_claim("SARSA higher", "constant", "behaviour_return", sign=1)
    lower = paper_claim("SARSA lower", "constant", "behaviour_return", sign=-1)
    clear = judge([better, lower], _metrics(list(q + 20), list(q)), episodes=100)
    assert list(clear["verdict"]) == ["supported", "contradicted"]
    noise = judge([better], _metrics(list(q + rng.normal(0, 5, 20)), list(q)), episodes=100)
    assert list(noise["verdict"]) == ["not resolved"]


def test_judge_counts_a_run_that_never_converged_as_the_last_episode() -> None:
    claim = paper_claim("SARSA faster", "constant", "convergence_episode", sign=-1)
    row = judge([claim], _metrics([100.0, 120.0, 110.0], [np.nan, 400.0, 390.0], "convergence_episode"),
                episodes=500).iloc[0]
    assert row["Q-Learning"] == pytest.approx((500 + 400 + 390) / 3)


def test_judge_ratio_equivalence_and_level_claims() -> None:
    rng = np.random.default_rng(1)
    sarsa = rng.normal(1000, 30, 30)
    metrics = _metrics(list(sarsa), list(4 * sarsa + rng.normal(0, 30, 30)), "convergence_episode")
    four = paper_claim("4 times", "constant", "convergence_episode", kind="ratio", value=4.0)
    two = paper_claim("2 times", "constant", "convergence_episode", kind="ratio", value=2.0)
    assert list(judge([four, two], metrics, episodes=10_000)["verdict"]) == ["supported", "contradicted"]
    close = _metrics(list(sarsa), list(sarsa + rng.normal(0, 1, 30)))
    same = paper_claim("same", "constant", "behaviour_return", kind="within", bounds=within(5.0))
    assert judge([same], close, episodes=1)["verdict"].iloc[0] == "supported"
    apart = _metrics(list(sarsa), list(sarsa + 50))
    assert judge([same], apart, episodes=1)["verdict"].iloc[0] == "contradicted"
    shares = _metrics(list(rng.uniform(0.7, 0.9, 30)), list(rng.uniform(0.1, 0.3, 30)), "first_action_left")
    sarsa_left = paper_claim("SARSA left", "constant", "first_action_left", kind="level", sign=1, value=0.5)
    q_left = paper_claim("Q left", "constant", "first_action_left", kind="level", sign=1, value=0.5, reads="b")
    assert list(judge([sarsa_left, q_left], shares, episodes=1)["verdict"]) == ["supported", "contradicted"]


def test_judge_refuses_unpaired_seeds() -> None:
    metrics = _metrics([1.0, 2.0], [1.0, 2.0])
    metrics["q_learning-constant"]["seed"] = [5, 6]
    with pytest.raises(ValueError, match="different seeds"):
        judge([paper_claim("x", "constant", "behaviour_return")], metrics, episodes=10)


def test_a_time_to_converge_around_the_end_of_the_decay_is_flagged_as_the_schedule() -> None:
    from types import SimpleNamespace

    from rlcompare.studies.paper.report import schedule_notes
    from rlcompare.tabular.config import ExperimentConfig

    runs = {name: SimpleNamespace(config=ExperimentConfig(algorithm=algorithm, schedule=schedule, episodes=5000))
            for name, algorithm, schedule in (("sarsa-decay", "sarsa", "decay"), ("q_learning-decay", "q_learning",
                                              "decay"), ("sarsa-constant", "sarsa", "constant"))}
    around = pd.DataFrame({"convergence_episode": [2400.0, 2450, 2550, 2600, np.nan]})
    later = pd.DataFrame({"convergence_episode": [3500.0, 3600, 3700, 3800]})
    notes = schedule_notes(runs, {"sarsa-decay": around, "q_learning-decay": later, "sarsa-constant": around})
    assert len(notes) == 1
    assert notes[0].startswith("sarsa-decay: ε reaches 0 at episode 2500, inside its time to converge 2500 [")
    assert notes[0].endswith("From there SARSA's target is Q-Learning's.")


@pytest.mark.slow("trains a study and builds its report")
def test_the_paper_report_draws_rliable_s_aggregates_of_the_four_learners(study_copy: Path) -> None:
    from rlcompare.studies.paper.report import load_study, paper_aggregates

    runs, _ = load_study(study_copy)
    aggregates = paper_aggregates(runs, study_copy / "figures")
    assert aggregates is not None
    means = {row["method"]: float(row["mean [95% CI]"].split()[0]) for _, row in aggregates.intervals.iterrows()}
    assert len(means) == 4
    assert max(means.values()) == 1.0  # the best learner's mean is the upper anchor, by construction
    best = max(runs[n].records.returns.mean() for n in CONFIGURATIONS if n != "random")
    floor = runs["random"].records.returns.mean()
    worst = min(runs[n].records.returns.mean() for n in CONFIGURATIONS if n != "random")
    assert min(means.values()) == pytest.approx(round((worst - floor) / (best - floor), 2), abs=0.006)
    assert len(aggregates.improvements) == 4 * 3  # every ordered pair of the four
    assert [Path(path).name for path, _ in aggregates.figures] == [
        "aggregate-intervals.png", "probability-of-improvement.png", "performance-profiles.png",
        "sample-efficiency.png"]
    runs.pop("random")
    assert paper_aggregates(runs, study_copy / "figures") is None  # no floor without the random baseline
