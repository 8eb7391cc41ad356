"""The sensitivity study: a grid through the sweep engine, paired SARSA minus Q-Learning per cell, Holm's marks."""

from __future__ import annotations

import hashlib
import itertools
import shutil
import socket
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from helpers import invoke

from rlcompare.experiment import store
from rlcompare.experiment.sweep import SweepError, derive_seeds
from rlcompare.experiment.sweep_store import read_manifest, trial_path
from rlcompare.stats.intervals import Estimate, paired_difference
from rlcompare.studies.sensitivity import figures as sensitivity_figures
from rlcompare.studies.sensitivity import grid as sensitivity_grid
from rlcompare.studies.sensitivity import words as sensitivity_words
from rlcompare.studies.sensitivity.grid import NOT_RESOLVED, Q_BETTER, SARSA_BETTER
from rlcompare.tabular.config import ExperimentConfig

TINY = ("--grid", "alpha=0.05,0.5", "--grid", "gamma=0.9", "--grid", "epsilon_end=0", "--grid",
        "truncation_as_terminal=true", "--grid", "epsilon=0.5", "--seeds", "3", "--episodes", "30")
"""The cross, 2 α x 1 γ x 1 ε_end x 1 time limit, and the schedule block's one constant ε, each for 2
algorithms: 18 trials of 30 episodes."""


def trial_files(root: Path) -> dict[str, str]:
    """Every trial's ``meta.json`` and its checksum."""
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.glob("sweep/trials/*/*/meta.json"))}


@pytest.fixture(scope="module")
def tiny_study(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    out = tmp_path_factory.mktemp("sensitivity") / "study"
    result = invoke("reproduce", "sensitivity", "--allow-undecidable", *TINY, "--workers", "2", "--out", str(out))
    assert result.exit_code == 0, result.output
    return out, result.output


# --- the study through the command line --------------------------------------------------------------------


@pytest.mark.slow("runs the sensitivity sweep")
def test_the_study_runs_a_sweep_inside_its_directory_and_reports(tiny_study: tuple[Path, str]) -> None:
    out, output = tiny_study
    assert "6 configurations x 3 seeds = 18 trials of 30 episodes" in output
    assert "18 trials run, 0 already finished" in output
    assert store.owner_of(out) == store.Owner("study", "sensitivity")
    assert store.owner_of(out / "sweep") == store.SWEEP
    manifest = read_manifest(out / "sweep")
    assert len(manifest["trials"]) == 18
    assert {t["status"] for t in manifest["trials"]} == {"done"}
    for name in ("report.html", "tables/cells.csv", "tables/cells.md", "figures/heatmap-behaviour.png",
                 "figures/heatmap-greedy.png", "figures/schedule-behaviour.png", "figures/schedule-greedy.png"):
        assert (out / name).is_file(), name
    table = pd.read_csv(out / "tables" / "cells.csv")
    assert list(zip(table["α"], table["ε"], strict=True)) == [(0.05, "constant 0.5"), (0.05, "decaying to 0"),
                                                            (0.5, "decaying to 0")]
    assert set(table["seeds"]) == {3}
    html = (out / "report.html").read_text()
    assert html.index("Summary") < html.index("The grid") < html.index("The ε schedule") < html.index("Cells")
    assert ("3 cells: 2 of α at γ = 0.9, ε_end = 0, time limit terminal (ε decaying from 1) and 2 of the ε schedule "
            "(constant 0.5; decaying from 1 to 0) at γ = 0.9, α = 0.05, time limit terminal, 1 of them in both") in html
    assert "each metric is one family of 3 tests" in html


@pytest.mark.slow("runs the sensitivity sweep")
def test_report_rebuilds_the_study_from_its_store(tiny_study: tuple[Path, str], tmp_path: Path) -> None:
    out = tmp_path / "copy"
    shutil.copytree(tiny_study[0], out)
    (out / "report.html").write_text("stale")
    result = invoke("report", str(out))
    assert result.exit_code == 0, result.output
    assert "Behaviour return (mean ε-greedy return over training):" in result.output
    assert "Sensitivity: SARSA against Q-Learning" in (out / "report.html").read_text()


@pytest.mark.slow("runs the sensitivity sweep")
def test_resume_does_not_retrain_finished_trials(tiny_study: tuple[Path, str], tmp_path: Path) -> None:
    out = tmp_path / "copy"
    shutil.copytree(tiny_study[0], out)
    before = trial_files(out)
    again = invoke("reproduce", "sensitivity", "--allow-undecidable", *TINY, "--out", str(out))
    assert again.exit_code == 0, again.output
    assert "0 trials run, 18 already finished" in again.output
    assert trial_files(out) == before
    first = read_manifest(out / "sweep")["trials"][0]
    removed = trial_path(out / "sweep", first["config_hash"], first["seed"])
    shutil.rmtree(removed)
    resumed = invoke("reproduce", "sensitivity", "--allow-undecidable", *TINY, "--out", str(out))
    assert resumed.exit_code == 0, resumed.output
    assert "1 trials run, 17 already finished" in resumed.output
    kept = {k: v for k, v in before.items() if not k.startswith(str(removed.relative_to(out)))}
    assert len(kept) == 17
    assert {k: v for k, v in trial_files(out).items() if k in kept} == kept
    assert (removed / "meta.json").is_file()


@pytest.mark.slow("runs the sensitivity sweep")
def test_a_wider_schedule_block_trains_only_its_new_configurations(tiny_study: tuple[Path, str],
                                                                   tmp_path: Path) -> None:
    out = tmp_path / "copy"
    shutil.copytree(tiny_study[0], out)
    before = trial_files(out)
    wider = [*TINY[:TINY.index("epsilon=0.5")], "epsilon=0.25,0.5", *TINY[TINY.index("epsilon=0.5") + 1:]]
    result = invoke("reproduce", "sensitivity", "--allow-undecidable", *wider, "--out", str(out))
    assert result.exit_code == 0, result.output
    assert "6 trials run, 18 already finished" in result.output  # constant ε = 0.25, both algorithms, 3 seeds
    assert {k: v for k, v in trial_files(out).items() if k in before} == before
    cells = sensitivity_grid.compare_cells(sensitivity_grid.seed_returns(out / "sweep"))
    assert sorted(cells.loc[cells["schedule"] == "constant", "epsilon_end"]) == [0.25, 0.5]


@pytest.mark.slow("runs the sensitivity sweep")
def test_the_paired_difference_of_a_cell_is_the_one_computed_by_hand(tiny_study: tuple[Path, str]) -> None:
    root = tiny_study[0] / "sweep"
    cells = sensitivity_grid.compare_cells(sensitivity_grid.seed_returns(root))
    by_hand: dict[tuple[str, float, str], dict[int, tuple[float, float]]] = {}
    for trial in read_manifest(root)["trials"]:
        trial_dir = trial_path(root, trial["config_hash"], trial["seed"])
        config = ExperimentConfig.from_dict({k: v for k, v in store.read_json(trial_dir / "config.json").items()
                                             if k not in ("seeds", "stages")})
        episodes = pd.read_parquet(trial_dir / "episodes.parquet")
        evaluations = pd.read_parquet(trial_dir / "evaluations.parquet")
        last = evaluations[evaluations["round"] == evaluations["round"].max()]
        by_hand.setdefault((config.schedule, config.alpha, config.algorithm), {})[trial["seed"]] = (
            float(np.mean(episodes["return"])), float(np.mean(last["return"])))
    for schedule, alpha in (("decay", 0.05), ("decay", 0.5), ("constant", 0.05)):
        row = cells[(cells["schedule"] == schedule) & (cells["alpha"] == alpha)].iloc[0]
        assert row["epsilon_end"] == (0.5 if schedule == "constant" else 0.0)  # a constant cell's ε: its ε_end
        seeds = sorted(by_hand[schedule, alpha, "sarsa"])
        for column, metric in enumerate(("behaviour", "greedy")):
            a = np.array([by_hand[schedule, alpha, "sarsa"][s][column] for s in seeds])
            b = np.array([by_hand[schedule, alpha, "q_learning"][s][column] for s in seeds])
            assert row[f"{metric}_difference"] == pytest.approx(np.mean(a - b), abs=1e-9)
            assert row[f"{metric}_sarsa"] == pytest.approx(np.mean(a), abs=1e-9)
            expected = paired_difference(a, b)
            assert (row[f"{metric}_low"], row[f"{metric}_high"]) == pytest.approx((expected.low, expected.high))
    assert len(cells) == 3
    assert cells.loc[cells["alpha"] == 0.5, "behaviour_difference"].iloc[0] != 0  # the two methods differ


# --- the grid ----------------------------------------------------------------------------------------------


def test_the_default_grid_covers_the_required_values_on_common_seeds() -> None:
    sweep, text = sensitivity_grid.plan()
    assert 'schedule = "decay"' in text
    cross = {(c.algorithm, c.alpha, c.gamma, c.epsilon_end, c.truncation_as_terminal) for c in sweep.configs
             if c.schedule == "decay"}
    assert cross == set(itertools.product(("q_learning", "sarsa"), (0.01, 0.05, 0.1, 0.2, 0.5), (0.9, 0.99, 1.0),
                                          (0.0, 0.01, 0.05), (False, True)))
    assert len(sweep.configs) == 180 + 18
    assert sweep.seeds == derive_seeds(0, sensitivity_grid.DEFAULT_SEEDS)
    assert {c.seeds for c in sweep.configs} == {sweep.seeds}  # paired: every configuration, the same seeds
    for config in sweep.configs:  # everything else is the paper's setting
        assert config == ExperimentConfig(algorithm=config.algorithm, schedule=config.schedule, alpha=config.alpha,
                                          gamma=config.gamma, epsilon=config.epsilon, epsilon_end=config.epsilon_end,
                                          truncation_as_terminal=config.truncation_as_terminal,
                                          episodes=sensitivity_grid.DEFAULT_EPISODES, seeds=sweep.seeds)
    assert (sweep.configs[0].epsilon_start, sweep.configs[0].bins, sweep.configs[0].max_steps) == (1.0, 20, 1000)


def test_the_grid_holds_the_schedule_block_constant_and_decaying_epsilon_by_gamma() -> None:
    """Constant ε at 0.1, 0.25 and the paper's 0.5, and ε decaying to each ε_end, each with γ 0.9, 0.99 and 1 at
    the paper's α and time limit; the decaying ones are the cross's own configurations."""
    sweep, text = sensitivity_grid.plan()
    at_block = [c for c in sweep.configs if c.alpha == 0.05 and c.truncation_as_terminal]
    found = {(c.algorithm, c.schedule, c.epsilon if c.schedule == "constant" else c.epsilon_end, c.gamma)
             for c in at_block}
    assert found == set(itertools.product(("q_learning", "sarsa"), ("constant",), (0.1, 0.25, 0.5),
                                          (0.9, 0.99, 1.0))) | set(itertools.product(
        ("q_learning", "sarsa"), ("decay",), (0.0, 0.01, 0.05), (0.9, 0.99, 1.0)))
    constant = [c for c in sweep.configs if c.schedule == "constant"]
    assert len(constant) == 18
    assert all(c in at_block for c in constant)
    assert text.count("[[include]]") == 18  # the decaying cells are not run twice
    assert sensitivity_grid.cell_count() == 99


def test_a_cross_without_the_blocks_setting_gets_the_blocks_decaying_cells_of_its_own() -> None:
    grid = {**sensitivity_grid.AXES, "alpha": (0.1,), "gamma": (0.9, 1.0)}
    sweep, _ = sensitivity_grid.plan(grid, seeds=2, episodes=10)
    decaying = {(c.alpha, c.gamma, c.epsilon_end, c.truncation_as_terminal) for c in sweep.configs
                if c.schedule == "decay" and c.alpha == 0.05}
    assert decaying == set(itertools.product((0.05,), (0.9, 1.0), (0.0, 0.01, 0.05), (True,)))
    assert len(sweep.configs) == 2 * (12 + 6 + 6) == 2 * sensitivity_grid.cell_count(grid)


def test_the_default_size_can_resolve_a_cell_after_holm() -> None:
    """The smallest two-sided Wilcoxon p-value of n seeds, 2 / 2**n, must pass Holm's first threshold over every
    cell of both blocks."""
    assert sensitivity_grid.LEVEL / sensitivity_grid.cell_count() > 2 / 2**sensitivity_grid.DEFAULT_SEEDS


def test_a_grid_option_overrides_one_axis_and_keeps_the_others() -> None:
    grid = sensitivity_grid.parse_grid(["alpha=0.1, 0.3", "truncation_as_terminal=TRUE"])
    assert grid["alpha"] == (0.1, 0.3)
    assert grid["truncation_as_terminal"] == (True,)
    assert grid["gamma"] == sensitivity_grid.GRID["gamma"]
    assert grid["epsilon"] == (0.1, 0.25, 0.5)
    assert sensitivity_grid.parse_grid(["epsilon=0.2"])["epsilon"] == (0.2,)


@pytest.mark.parametrize(("grid", "field"), [
    ({"alpha": ()}, "grid.alpha: empty"),
    ({"beta": (0.1,)}, "grid.beta: unknown key"),
    ({"alpha": (0.0,)}, "grid.alpha[0]: got 0.0; allowed: a number in (0, 1]"),
    ({"epsilon": ()}, "grid.epsilon: empty"),
    ({"epsilon": (0.5, 2.0)}, "grid.epsilon[1]: got 2.0; allowed: a number in [0, 1]"),
    ({"epsilon": (0.1, 0.1)}, "grid.epsilon[1]: the same configuration as grid.epsilon[0]"),
])
def test_a_bad_grid_names_its_field(grid: dict, field: str) -> None:
    with pytest.raises(SweepError, match=field.replace("[", r"\[").replace("(", r"\(").replace("]", r"\]")):
        sensitivity_grid.plan(grid, seeds=2, episodes=10)


@pytest.mark.parametrize(("args", "option", "message"), [
    (["--grid", "alpha="], "--grid", "alpha: empty; allowed: at least one value"),
    (["--grid", "beta=0.1"], "--grid", "alpha, gamma, epsilon_end, truncation_as_terminal"),
    (["--grid", "truncation_as_terminal=maybe"], "--grid", "truncation_as_terminal: got 'maybe'; allowed: true or "
     "false"),
    (["--grid", "gamma=high"], "--grid", "gamma: got 'high'; allowed: finite numbers"),
    (["--grid", "alpha=nan"], "--grid", "alpha: got 'nan'; allowed: finite numbers"),
    (["--grid", "alpha=0.1,0.1"], "--grid", "grid.alpha[1]: the same configuration as grid.alpha[0]"),
    (["--grid", "alpha=2"], "--grid", "grid.alpha[0]: got 2.0; allowed: a number in (0, 1]"),
    (["--grid", "epsilon_end=0,-0.1"], "--grid", "grid.epsilon_end[1]: got -0.1; allowed: a number in [0, 1]"),
    (["--grid", "epsilon=0.5,1.5"], "--grid", "grid.epsilon[1]: got 1.5; allowed: a number in [0, 1]"),
    (["--episodes", "0"], "--episodes", "allowed: an integer >= 1"),
    (["--seeds", "0"], "--seeds", "allowed: an integer >= 1"),
    (["--workers", "0"], "--workers", "allowed: an integer >= 1"),
    (["--first-seed", "3"], "--first-seed", "No such option"),  # its seeds come from its sweep
])
def test_bad_input_gets_one_clear_message_and_exit_code_2(args: list[str], option: str, message: str,
                                                          tmp_path: Path) -> None:
    result = invoke("reproduce", "sensitivity", "--allow-undecidable", *args, "--out", str(tmp_path / "out"))
    assert result.exit_code == 2, result.output
    assert option in result.output
    assert message in result.output
    assert isinstance(result.exception, SystemExit)
    assert not (tmp_path / "out").exists()


def test_a_ray_address_where_no_cluster_listens_is_one_clear_error(tmp_path: Path) -> None:
    pytest.importorskip("ray")
    with socket.socket() as probe:  # a port where nothing listens
        probe.bind(("127.0.0.1", 0))
        address = f"127.0.0.1:{probe.getsockname()[1]}"
    result = invoke("reproduce", "sensitivity", "--allow-undecidable", *TINY, "--address", address, "--out",
                    str(tmp_path / "out"))
    assert result.exit_code == 2
    assert f"no Ray cluster at '{address}'" in result.output
    assert not (tmp_path / "out").exists()


def test_reproduce_lists_the_study() -> None:
    result = invoke("reproduce", "--list")
    assert result.exit_code == 0
    assert "\nsensitivity " in "\n" + result.output


# --- Holm and the marks ------------------------------------------------------------------------------------


def test_marks_need_the_holm_adjusted_p_value_and_the_interval_on_one_side() -> None:
    above, below, spanning = Estimate(5.0, 1.0, 9.0), Estimate(-5.0, -9.0, -1.0), Estimate(5.0, -1.0, 9.0)
    adjusted, marks = sensitivity_grid.mark_family([above, below, spanning, Estimate(1.0, np.nan, np.nan)],
                                              [0.001, 0.002, 0.001, 0.001])
    assert marks == [SARSA_BETTER, Q_BETTER, NOT_RESOLVED, NOT_RESOLVED]
    np.testing.assert_allclose(adjusted, [0.004, 0.004, 0.004, 0.004])
    alone = sensitivity_grid.mark_family([above], [0.02])[1]
    together = sensitivity_grid.mark_family([above, above, above], [0.02, 0.03, 0.04])[1]
    assert alone == [SARSA_BETTER]
    assert together == [NOT_RESOLVED] * 3  # each below 0.05, none below Holm's thresholds


# --- the summary and the heatmap ---------------------------------------------------------------------------


def cell(schedule: str, alpha: float, gamma: float, end: float, terminal: bool, value: float, mark: str,
         low: float | None = None, high: float | None = None) -> dict:
    """One row of :func:`sensitivity_grid.compare_cells`, both metrics alike."""
    row = {"schedule": schedule, "alpha": alpha, "gamma": gamma, "epsilon_end": end, "truncation_as_terminal": terminal,
           "seeds": 20}
    for metric in sensitivity_grid.METRICS:
        row |= {f"{metric}_sarsa": -200.0 + value, f"{metric}_q_learning": -200.0, f"{metric}_difference": value,
                f"{metric}_low": value - 5 if low is None else low,
                f"{metric}_high": value + 5 if high is None else high, f"{metric}_p": 1e-5,
                f"{metric}_holm": 1e-3, f"{metric}_mark": mark}
    return row


def synthetic_cells() -> pd.DataFrame:
    """The cross alone, 2 α x 2 ε_end x 2 γ x 2 time limits: SARSA better everywhere but at α = 0.5, γ = 1
    (Q-Learning better with the time limit terminal, not resolved with it bootstrapped)."""
    rows = []
    for alpha, end, gamma, terminal in itertools.product((0.05, 0.5), (0.0, 0.05), (0.9, 1.0), (False, True)):
        flipped = alpha == 0.5 and gamma == 1.0
        rows.append(cell("decay", alpha, gamma, end, terminal, -20.0 if flipped else 30.0,
                         (Q_BETTER if terminal else NOT_RESOLVED) if flipped else SARSA_BETTER))
    return pd.DataFrame(rows)


def schedule_cells(flip: bool) -> pd.DataFrame:
    """A cross SARSA wins everywhere (2 α x 2 ε_end x 2 γ x 2 time limits) and the schedule block at α = 0.05,
    time limit terminal: constant ε 0.1 (SARSA better) and 0.5 by γ 0.9 and 1, where constant 0.5 at γ = 1 is
    Q-Learning better when ``flip``, not resolved otherwise."""
    rows = [cell("decay", alpha, gamma, end, terminal, 30.0, SARSA_BETTER)
            for alpha, end, gamma, terminal in itertools.product((0.05, 0.5), (0.0, 0.05), (0.9, 1.0), (False, True))]
    for gamma in (0.9, 1.0):
        rows.append(cell("constant", 0.05, gamma, 0.1, True, 21.0, SARSA_BETTER))
    rows.append(cell("constant", 0.05, 0.9, 0.5, True, -0.6, NOT_RESOLVED, -2.7, 1.4))
    rows.append(cell("constant", 0.05, 1.0, 0.5, True, -10.0, Q_BETTER if flip else NOT_RESOLVED, -12.9, -6.4))
    return pd.DataFrame(rows)


CROSS_NEVER = ("The conclusion never flips on this metric over α x γ x ε_end x time limit (ε decaying from 1): no "
               "cell there has Q-Learning better.")
SCHEDULE_NEVER = ("The conclusion never flips on this metric over the ε schedule (constant 0.1, 0.5; decaying from 1 "
                  "to 0, 0.05) x γ (0.9, 1) at α = 0.05, time limit terminal: no cell there has Q-Learning better.")


def test_the_summary_counts_each_way_and_says_where_the_conclusion_flips() -> None:
    lines = sensitivity_words.summary(synthetic_cells())
    text = "\n".join(lines)
    assert "SARSA better in 12 of 16 cells, Q-Learning better in 2, not resolved in 2" in text
    assert "The conclusion flips (Q-Learning better) in 2 cells, 2 regions" in text
    for end in ("0", "0.05"):
        assert (f"Flips at ε_end = {end} with γ = 1 (α = 0.5, time limit terminal): SARSA - Q-Learning -20.0 [-25.0, "
                "-15.0] at γ = 1 (beside it, γ = 0.9: 30.0 [25.0, 35.0], SARSA better).") in lines
    assert "Not resolved in 2 cells, by setting: α: 0.05 0 of 8, 0.5 2 of 8; γ: 0.9 0 of 8, 1 2 of 8" in text
    assert "never flips" not in text  # it flips in the cross, and there is no schedule block
    assert "ε schedule" not in text
    assert "The paper's setting (α = 0.05, γ = 0.9, ε_end = 0, time limit terminal)" in text
    assert "16 cells: 16 of α x γ x ε_end x time limit (ε decaying from 1)." in text
    assert "family of 16 tests" in text


def test_a_flip_in_the_schedule_block_is_named_with_its_numbers_from_the_cells() -> None:
    lines = sensitivity_words.summary(schedule_cells(flip=True))
    region = ("Flips at constant ε = 0.5 with γ = 1 (α = 0.05, time limit terminal): SARSA - Q-Learning -10.0 [-12.9, "
              "-6.4] at γ = 1 (beside it, γ = 0.9: -0.6 [-2.7, 1.4], not resolved).")
    for metric in ("Behaviour", "Greedy"):
        at = next(i for i, line in enumerate(lines) if line.startswith(metric))
        assert lines[at + 1].startswith("The conclusion flips (Q-Learning better) in 1 cell, 1 region")
        assert lines[at + 2] == region
    assert lines.count(CROSS_NEVER) == 2  # said of the cross, which does not flip, naming its axes
    assert not any("never flips" in line and "ε schedule" in line for line in lines)
    assert lines[0].startswith(
        "20 cells: 16 of α x γ x ε_end x time limit (ε decaying from 1) and 8 of the ε schedule (constant 0.1, 0.5; "
        "decaying from 1 to 0, 0.05) x γ (0.9, 1) at α = 0.05, time limit terminal, 4 of them in both")
    assert ("The paper's constant-ε setting (α = 0.05, γ = 0.9, constant ε = 0.5, time limit terminal): SARSA - "
            "Q-Learning, behaviour -0.6 [-2.7, 1.4]: not resolved") in "\n".join(lines)


def test_without_a_flip_the_summary_says_never_flips_over_each_blocks_axes() -> None:
    lines = sensitivity_words.summary(schedule_cells(flip=False))
    assert lines.count(CROSS_NEVER) == 2
    assert lines.count(SCHEDULE_NEVER) == 2
    assert not any("Flips at" in line or "The conclusion flips" in line for line in lines)


@pytest.mark.parametrize(("flipped", "regions"), [
    ((True, True, True), ["every γ (0.9, 0.99, 1)"]),
    ((False, True, True), ["γ ≥ 0.99"]),
    ((True, True, False), ["γ ≤ 0.99"]),
    ((False, True, False), ["γ = 0.99"]),
    ((True, False, True), ["γ = 0.9", "γ = 1"]),
    ((False, False, False), []),
])
def test_a_region_is_each_run_of_neighbouring_gammas_that_flip(flipped: tuple[bool, ...], regions: list[str]) -> None:
    cells = pd.DataFrame([cell("constant", 0.05, gamma, 0.5, True, -7.0 if flips else 3.0,
                               Q_BETTER if flips else NOT_RESOLVED)
                          for gamma, flips in zip((0.9, 0.99, 1.0), flipped, strict=True)])
    found = sensitivity_words.flip_regions(cells, "behaviour")
    assert [text.split(" (α")[0] for text in found] == [f"constant ε = 0.5 with {region}" for region in regions]
    for text in found:
        assert "-7.0 [-12.0, -2.0] at γ = " in text


def test_the_heatmap_has_a_panel_per_gamma_and_time_limit_and_annotates_each_cell() -> None:
    figure = sensitivity_figures.heatmap_figure(synthetic_cells(), "greedy")
    panels = [ax for ax in figure.axes if ax.get_title()]
    assert len(panels) == 4
    assert {ax.get_title() for ax in panels} == {f"γ = {g}, time limit {t}" for g in ("0.9", "1")
                                                 for t in ("bootstrapped", "terminal")}
    flipped = next(ax for ax in panels if ax.get_title() == "γ = 1, time limit terminal")
    assert sorted(t.get_text() for t in flipped.texts) == ["+30.0\nSARSA", "+30.0\nSARSA", "-20.0\nQ-Learning",
                                                           "-20.0\nQ-Learning"]
    image = flipped.images[0]
    assert image.norm.vmin == -image.norm.vmax == -30.0  # centred on 0


def test_the_cross_heatmap_leaves_the_constant_cells_to_the_schedule_map() -> None:
    figure = sensitivity_figures.heatmap_figure(schedule_cells(flip=True), "behaviour")
    texts = [t.get_text() for ax in figure.axes for t in ax.texts]
    assert len(texts) == 16
    assert set(texts) == {"+30.0\nSARSA"}


def test_the_schedule_map_draws_the_schedule_by_gamma_cells_with_their_marks() -> None:
    figure = sensitivity_figures.schedule_figure(schedule_cells(flip=True), "behaviour")
    panels = [ax for ax in figure.axes if ax.get_title()]
    assert len(panels) == 1
    (ax,) = panels
    assert ax.get_title() == "α = 0.05, time limit terminal"
    rows = [label.get_text() for label in ax.get_yticklabels()]
    assert rows == ["constant 0.1", "constant 0.5", "decaying to 0", "decaying to 0.05"]
    assert [label.get_text() for label in ax.get_xticklabels()] == ["0.9", "1"]
    drawn = {(rows[round(t.get_position()[1])], round(t.get_position()[0])): t.get_text() for t in ax.texts}
    assert drawn == {("constant 0.1", 0): "+21.0\nSARSA", ("constant 0.1", 1): "+21.0\nSARSA",
                     ("constant 0.5", 0): "-0.6\nn.r.", ("constant 0.5", 1): "-10.0\nQ-Learning",
                     **{(f"decaying to {end}", g): "+30.0\nSARSA" for end in ("0", "0.05") for g in (0, 1)}}
    bold = {t.get_text() for t in ax.texts if t.get_fontweight() == "bold"}
    assert "-0.6\nn.r." not in bold
    assert "-10.0\nQ-Learning" in bold
    image = ax.images[0]
    assert image.norm.vmin == -image.norm.vmax == -30.0
    assert "Holm over 20 cells" in figure.get_suptitle()
