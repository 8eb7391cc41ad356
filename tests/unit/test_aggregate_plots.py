"""rliable's aggregate figures as drawn here: what each panel, bar, line and label shows, read back from the figure."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from matplotlib.collections import LineCollection
from matplotlib.colors import to_rgba
from matplotlib.patches import Rectangle
from scipy import stats

from rlcompare.report.aggregate_plots import (
    improvement_figure,
    interval_figure,
    method_colors,
    profile_figure,
    sample_efficiency_figure,
)
from rlcompare.stats.aggregates import improvement_estimates, interval_estimates, iqm_curve

RESAMPLES = 200


@pytest.fixture(scope="module")
def scores() -> dict[str, np.ndarray]:
    rng = np.random.default_rng(0)
    return {"SARSA(λ)": rng.normal(0.8, 0.2, (3, 10)), "Q(λ)": rng.normal(0.5, 0.3, (3, 10)),
            "PPO": rng.normal(1.0, 0.1, (3, 10))}


def _bars(ax) -> list[Rectangle]:
    return [p for p in ax.patches if isinstance(p, Rectangle)]


def _labels(ax) -> list[str]:
    return [label.get_text() for label in ax.get_yticklabels()]


def test_the_interval_figure_has_a_panel_per_metric_and_a_bar_per_method_over_its_interval(scores):
    estimates = interval_estimates(scores, resamples=RESAMPLES)
    figure = interval_figure(scores, estimates=estimates)
    axes = figure.axes
    assert [ax.get_title() for ax in axes] == ["median", "IQM", "mean", "optimality gap (lower is better)"]
    assert _labels(axes[0]) == ["SARSA(λ)", "Q(λ)", "PPO"]
    assert all(_labels(ax) == [] for ax in axes[1:])
    for ax, metric in zip(axes, ["median", "IQM", "mean", "optimality gap"], strict=True):
        bars = _bars(ax)
        assert len(bars) == 3
        expected = estimates[estimates["metric"] == metric]
        np.testing.assert_allclose([b.get_x() for b in bars], expected["low"])
        np.testing.assert_allclose([b.get_x() + b.get_width() for b in bars], expected["high"])
        ticks = [c.get_segments()[0] for c in ax.collections if isinstance(c, LineCollection)]
        np.testing.assert_allclose([segment[0, 0] for segment in ticks], expected["value"])
    colors = method_colors(list(scores))
    assert [b.get_facecolor() for b in _bars(axes[0])] == [to_rgba(colors[m], 0.75) for m in scores]
    assert len(set(colors.values())) == 3


def test_a_method_without_an_interval_gets_its_tick_and_no_bar():
    scores = {"one run": np.array([[0.2], [0.4]]), "two runs": np.array([[0.1, 0.3], [0.5, 0.7]])}
    figure = interval_figure(scores, resamples=RESAMPLES)
    assert all(len(_bars(ax)) == 1 for ax in figure.axes)


def test_the_improvement_figure_has_a_row_per_ordered_pair_and_a_line_at_one_half(scores):
    estimates = improvement_estimates(scores, resamples=RESAMPLES)
    figure = improvement_figure(scores, estimates=estimates)
    ax, twin = figure.axes
    assert len(_bars(ax)) == 6
    assert _labels(ax) == ["SARSA(λ)", "SARSA(λ)", "Q(λ)", "Q(λ)", "PPO", "PPO"]
    assert _labels(twin) == ["Q(λ)", "PPO", "SARSA(λ)", "PPO", "SARSA(λ)", "Q(λ)"]
    assert any(np.allclose(line.get_xdata(), 0.5) for line in ax.get_lines())
    np.testing.assert_allclose([b.get_x() for b in _bars(ax)], estimates["low"])
    assert ax.get_xlim() == (0.0, 1.0)
    chosen = improvement_figure(scores, [("PPO", "Q(λ)")], resamples=RESAMPLES)
    assert _labels(chosen.axes[0]) == ["PPO"]
    assert _labels(chosen.axes[1]) == ["Q(λ)"]


def test_the_sample_efficiency_figure_draws_each_methods_iqm_curve_with_its_band():
    rng = np.random.default_rng(1)
    x = np.arange(1, 6) * 1000
    curves = {"a": np.linspace(0, 1, 5) + rng.normal(0, 0.1, (2, 6, 5)), "b": rng.normal(0, 0.1, (2, 6, 5))}
    figure = sample_efficiency_figure(x, curves, "environment steps", resamples=RESAMPLES)
    ax, = figure.axes
    lines = ax.get_lines()
    assert [line.get_label() for line in lines] == ["a", "b"]
    np.testing.assert_allclose(lines[0].get_xdata(), x)
    np.testing.assert_allclose(lines[0].get_ydata(), iqm_curve(curves["a"]))
    assert len(ax.collections) == 2  # one band per method
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("environment steps", "IQM of normalised score")
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["a", "b"]


def test_the_profile_figure_draws_a_falling_profile_and_band_per_method(scores):
    figure = profile_figure(scores, "score", resamples=RESAMPLES)
    ax, = figure.axes
    lines = ax.get_lines()
    assert [line.get_label() for line in lines] == list(scores)
    for line in lines:
        assert np.all(np.diff(line.get_ydata()) <= 0)
        assert line.get_ydata()[0] == 1.0
        assert line.get_ydata()[-1] == 0.0
    assert len(ax.collections) == 3
    assert ax.get_xlabel() == "score τ"
    thresholds = np.linspace(0, 2, 5)
    chosen = profile_figure(scores, thresholds=thresholds, resamples=RESAMPLES)
    np.testing.assert_allclose(chosen.axes[0].get_lines()[0].get_xdata(), thresholds)


# --- the deep study's aggregates over environments, from stand-ins for its runs ---------------------------------

def _deep_run(algorithm: str, env: str, finals: list[float], steps_per_round: int, rounds: int = 4):
    """A stand-in for a deep run directory: what the report reads, each seed's greedy return rising linearly to
    its final value over ``rounds`` evaluation rounds of two episodes."""
    from types import SimpleNamespace

    rows = [{"seed": seed, "round": r, "after_step": (r + 1) * steps_per_round, "return": final * (r + 1) / rounds}
            for seed, final in enumerate(finals) for r in range(rounds) for _ in range(2)]
    return SimpleNamespace(config=SimpleNamespace(algorithm=algorithm, env=env), seeds=tuple(range(len(finals))),
                           evaluations=pd.DataFrame(rows))


def _findings(runs, envs, across=None, drawn=(None, {})):
    """What the deep study's report reads of its aggregates, as :func:`~rlcompare.studies.paired_report.findings`
    gives it."""
    from rlcompare.studies.paired_report import Findings

    return Findings(runs, {}, [], envs, {}, pd.DataFrame(), across, *drawn)


def test_the_deep_study_normalises_each_environment_between_random_and_its_best_method(tmp_path):
    deep = pytest.importorskip("rlcompare.studies.deep.study")  # the deep extra
    from rlcompare.studies.paired_report import across as across_environments
    from rlcompare.studies.paired_report import draw_across

    runs = {"pqn_q_lambda-CartPole-v1": _deep_run("pqn_q_lambda", "CartPole-v1", [100, 200, 300], 1000),
            "dqn-CartPole-v1": _deep_run("dqn", "CartPole-v1", [400, 500, 500], 500),
            "pqn_q_lambda-Acrobot-v1": _deep_run("pqn_q_lambda", "Acrobot-v1", [-300, -200, -100], 1000),
            "dqn-Acrobot-v1": _deep_run("dqn", "Acrobot-v1", [-500, -500, -500], 500),
            "ppo-Acrobot-v1": _deep_run("ppo", "Acrobot-v1", [-90, -90, -90], 700)}  # not run on CartPole
    floors = {"CartPole-v1": 20.0, "Acrobot-v1": -500.0}
    envs = ["CartPole-v1", "Acrobot-v1"]
    across = across_environments(runs, envs, floors, deep.DEEP.method_order)
    assert across.envs == envs
    assert list(across.scores) == ["pqn_q_lambda", "dqn"]  # PPO ran one environment of the two
    cartpole_best = 1400 / 3 - 20  # DQN's mean final return over the random policy's
    np.testing.assert_allclose(across.scores["dqn"][0], (np.array([400, 500, 500]) - 20) / cartpole_best)
    # on Acrobot, Q(λ)'s mean -200 is the best of the two kept (PPO's -90 is not), the floor -500
    np.testing.assert_allclose(across.scores["pqn_q_lambda"][1], [2 / 3, 1, 4 / 3])
    np.testing.assert_allclose(across.scores["dqn"][1], 0)
    assert across.xlabel == "share of each training's environment steps"  # budgets differ by method
    np.testing.assert_allclose(across.x, [0.25, 0.5, 0.75, 1])
    np.testing.assert_allclose(across.curves["dqn"][..., -1], across.scores["dqn"])
    same = {name: run for name, run in runs.items() if name.startswith("pqn")}
    same["ppo-CartPole-v1"] = _deep_run("ppo", "CartPole-v1", [30, 40, 50], 1000)
    assert across_environments(same, envs, floors, deep.DEEP.method_order).xlabel == "environment steps"

    drawn = draw_across(deep.DEEP, across, tmp_path / "tables", tmp_path / "figures")
    section = deep.aggregate_section(_findings(runs, envs, across, drawn))
    assert [table[0] for table in section.tables] == ["Aggregates of normalised final returns",
                                                      "Probability of improvement"]
    assert section.tables[0][2] == "tables/deep_aggregates.csv"
    assert section.tables[0][1]["method"].tolist() == ["Q(λ), network", "DQN"]  # the study's labels
    assert len(section.tables[1][1]) == 2  # both ordered pairs
    assert [path for path, _ in section.figures] == [
        "figures/aggregate-intervals.png", "figures/probability-of-improvement.png",
        "figures/performance-profiles.png", "figures/sample-efficiency.png"]
    assert all((tmp_path / path).is_file() for path, _ in section.figures)
    assert (tmp_path / "tables" / "deep_aggregates.csv").is_file()
    assert "Acrobot-v1 -500.0" in section.paragraphs[0]
    one_method = across_environments({"dqn-CartPole-v1": runs["dqn-CartPole-v1"],
                                      "dqn-Acrobot-v1": runs["dqn-Acrobot-v1"]}, envs, floors, ["dqn"])
    assert draw_across(deep.DEEP, one_method, tmp_path / "t", tmp_path / "f") == (None, {})
    alone = deep.aggregate_section(_findings({"dqn-CartPole-v1": runs["dqn-CartPole-v1"]}, ["CartPole-v1"]))
    assert alone.figures == []
    assert "two or more" in alone.paragraphs[0]


# --- a sweep's aggregates over its environments, from stand-ins for its configurations ----------------------------

def _tabular_configuration(env: str, algorithm: str, alpha: float, finals: list[float], rounds: int = 3):
    """A stand-in for a tabular configuration of a sweep and its per-seed metrics: greedy returns rising linearly to
    ``finals`` over ``rounds`` evaluation rounds of two episodes, every 10 episodes."""
    from types import SimpleNamespace

    finals = np.asarray(finals, np.float64)
    eval_returns = np.repeat((finals[:, None] * np.arange(1, rounds + 1) / rounds)[..., None], 2, axis=2)
    config = SimpleNamespace(env=env, algorithm=algorithm, alpha=alpha, eval_every=10, name=algorithm)
    results = SimpleNamespace(config=config, seeds=tuple(range(len(finals))),
                              records=SimpleNamespace(eval_returns=eval_returns))
    return results, pd.DataFrame({"greedy_return": finals, "behaviour_return": finals / 2})


@pytest.mark.slow("compiles or trains for a second or more")
def test_a_sweep_over_environments_aggregates_the_configurations_that_ran_on_all_of_them(tmp_path):
    from rlcompare.studies.sweep_report import aggregate_section

    made = {f"{env}-{algorithm}-{alpha}": _tabular_configuration(env, algorithm, alpha, finals)
            for env, algorithm, alpha, finals in (
                ("CliffWalking-v1", "sarsa", 0.1, [-30, -20, -10]), ("CliffWalking-v1", "q_learning", 0.1, [-90] * 3),
                ("FrozenLake-v1", "sarsa", 0.1, [0, 1, 1]), ("FrozenLake-v1", "q_learning", 0.1, [0, 0, 1]),
                ("FrozenLake-v1", "q_learning", 0.5, [1, 1, 1]),  # on one environment of the two
                ("Taxi-v4", "sarsa", 0.5, [5, 6, 7]))}  # alone on its environment
    runs = {name: results for name, (results, _) in made.items()}
    metrics = {name: frame for name, (_, frame) in made.items()}
    swept = ["env", "algorithm", "alpha"]
    section = aggregate_section(runs, metrics, swept, "tabular", tmp_path / "tables", tmp_path / "figures")
    intervals = section.tables[0][1]
    assert intervals["method"].tolist() == ["algorithm=sarsa, alpha=0.1", "algorithm=q_learning, alpha=0.1"]
    # per environment, the worst configuration's mean is 0 and the best's 1: CliffWalking -90 and -20, FrozenLake
    # 1/3 and 2/3 (q_learning at α = 0.5 left out, so not the best)
    sarsa = np.concatenate([(np.array([-30, -20, -10]) + 90) / 70, (np.array([0, 1, 1]) - 1 / 3) / (1 / 3)])
    assert intervals.loc[0, "mean [95% CI]"].startswith("1.00 [")
    assert intervals.loc[1, "mean [95% CI]"].startswith("0.00 [")
    assert intervals.loc[0, "IQM [95% CI]"].startswith(f"{stats.trim_mean(sarsa, 0.25):.2f} [")  # 1.25
    assert [path for path, _ in section.figures][-1] == "figures/sample-efficiency.png"
    assert len(section.figures) == 4
    text = section.paragraphs[0]
    assert "algorithm=q_learning, alpha=0.5" in text
    assert "one configuration alone: Taxi-v4" in text
    one_env = {name: run for name, run in runs.items() if name.startswith("Cliff")}
    assert aggregate_section(one_env, metrics, swept, "tabular", tmp_path, tmp_path) is None
    apart = {name: run for name, run in runs.items() if name.endswith("0.5")}  # one configuration per environment
    assert aggregate_section(apart, metrics, swept, "tabular", tmp_path, tmp_path).figures == []
