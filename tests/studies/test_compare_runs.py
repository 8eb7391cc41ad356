"""``rlcompare compare`` on runs other libraries made: Monitor files in Stable-Baselines3's format, the same numbers
as a tidy table giving the same verdicts, the common grid and its metrics by hand, independent and paired seeds,
a declared margin, and bad input as one line naming the file, exit 2, nothing written."""

from __future__ import annotations

import html
import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from helpers import invoke
from scipy import stats

from rlcompare.experiment.outside import grouping, read_runs
from rlcompare.studies import compare_numbers

SEEDS = 5
LEVELS = {"ppo": 200.0, "dqn": 120.0}


def write_runs(root: Path, levels: dict[str, float] = LEVELS, seeds: int = SEEDS, episodes: int = 120) -> Path:
    """Monitor files as Stable-Baselines3 writes them, ``{method}/CartPole-v1/{seed}/0.monitor.csv``: returns
    that climb to each method's level, episodes of about 100 steps."""
    rng = np.random.default_rng(4)
    for method, level in levels.items():
        for seed in range(seeds):
            lengths = 100 + rng.integers(-5, 6, size=episodes)
            returns = level * np.cumsum(lengths) / lengths.sum() + rng.normal(0.0, 10.0, size=episodes)
            path = root / method / "CartPole-v1" / str(seed) / "0.monitor.csv"
            path.parent.mkdir(parents=True)
            episodes_rows = enumerate(zip(returns, lengths, strict=True))
            rows = "".join(f"{r:.6f},{n},{0.01 * i:.2f}\n" for i, (r, n) in episodes_rows)
            path.write_text("#" + json.dumps({"t_start": 0.0, "env_id": "CartPole-v1"}) + "\nr,l,t\n" + rows)
    return root


@pytest.fixture
def runs(tmp_path):
    return write_runs(tmp_path / "runs")


def test_the_final_window_and_the_area_are_each_runs_own_points_by_hand(runs):
    """The final window: the mean of the episodes that end in the last tenth of the common range; the area: each
    episode's return held from its end to the next one's, averaged over the range."""
    frame = read_runs(sorted(runs.rglob("*.monitor.csv")), runs, grouping("{method}/{env}/{seed}/*"))
    (read,) = compare_numbers.numbers(frame)
    ends = frame.groupby(["method", "seed"])["step"].agg(["min", "max"])
    assert (read.start, read.end) == (ends["min"].max(), ends["max"].min())
    one = frame[(frame["method"] == "dqn") & (frame["seed"] == "3")]
    steps, values = one["step"].to_numpy(), one["value"].to_numpy()
    low = read.end - 0.1 * (read.end - read.start)
    final = values[(steps >= low) & (steps <= read.end)].mean()
    held = sum(value * (min(following, read.end) - max(step, read.start))
               for step, following, value in zip(steps, [*steps[1:], np.inf], values, strict=True)
               if following > read.start and step < read.end) / (read.end - read.start)
    seed = read.seeds["dqn"].index("3")
    assert read.values["dqn"]["final"][seed] == pytest.approx(final)
    assert read.values["dqn"]["auc"][seed] == pytest.approx(held)
    (curve,) = compare_numbers.curves(frame)  # the pictures' grid: interpolated
    np.testing.assert_array_equal(curve.values["dqn"][curve.seeds["dqn"].index("3")],
                                  np.interp(curve.steps, steps, values))


@pytest.mark.slow("bootstraps every comparison and draws the report")
def test_compare_turns_monitor_files_into_a_report_with_independent_seeds(runs, tmp_path):
    result = invoke("compare", str(runs), "--out", str(tmp_path / "out"), columns=300)
    assert result.exit_code == 0, result.output
    assert result.output.index("What each file was taken as") < result.output.index("On CartPole-v1")
    table = pd.read_csv(tmp_path / "out" / "tables" / "verdicts.csv")
    assert table["metric"].tolist() == ["final"]  # the primary metric alone, unless --metric declares more
    assert (table["verdict"] == "ppo better").all()
    frame = read_runs(sorted(runs.rglob("*.monitor.csv")), runs, grouping("{method}/{env}/{seed}/*"))
    finals = compare_numbers.numbers(frame)[0].values
    p = stats.mannwhitneyu(finals["dqn"]["final"], finals["ppo"]["final"], alternative="two-sided").pvalue
    assert table["p (Holm)"].iloc[0] == pytest.approx(p)  # a family of one
    assert p == pytest.approx(2 / math.comb(2 * SEEDS, SEEDS))
    page = (tmp_path / "out" / "report.html").read_text()
    assert page.index(">The answer</h2>") < page.index(">Verdicts</h2>")
    assert "independent samples" in page
    assert "No margin was declared" in page


def test_the_same_numbers_as_a_tidy_table_give_the_same_verdicts(runs, tmp_path):
    frame = read_runs(sorted(runs.rglob("*.monitor.csv")), runs, grouping("{method}/{env}/{seed}/*"))
    tidy = tmp_path / "tidy.csv"
    frame.drop(columns="source").to_csv(tidy, index=False)
    from_monitors = invoke("compare", str(runs), "--out", str(tmp_path / "a"), columns=300)
    from_table = invoke("compare", str(tidy), "--out", str(tmp_path / "b"), columns=300)
    assert from_monitors.exit_code == from_table.exit_code == 0, from_table.output
    pd.testing.assert_frame_equal(pd.read_csv(tmp_path / "a" / "tables" / "verdicts.csv"),
                                  pd.read_csv(tmp_path / "b" / "tables" / "verdicts.csv"))


def test_paired_seeds_and_a_declared_margin_are_what_the_report_says(tmp_path):
    runs = write_runs(tmp_path / "runs", {"sarsa": 150.0, "q": 151.0})
    result = invoke("compare", str(runs), "--paired", "--margin", "40", "--out", str(tmp_path / "out"),
                    columns=300)
    assert result.exit_code == 0, result.output
    table = pd.read_csv(tmp_path / "out" / "tables" / "verdicts.csv")
    assert table["verdict"].tolist() == ["equivalent (within ±40)"]
    page = (tmp_path / "out" / "report.html").read_text()
    assert "Seeds paired by their labels" in page
    assert "±40" in page


def test_a_seed_missing_from_one_method_is_refused_when_paired_and_fine_when_independent(runs, tmp_path):
    for path in (runs / "dqn" / "CartPole-v1" / "4").iterdir():
        path.unlink()
    (runs / "dqn" / "CartPole-v1" / "4").rmdir()
    result = invoke("compare", str(runs), "--paired", "--out", str(tmp_path / "out"), columns=300)
    assert result.exit_code == 2
    assert "lacks seed 4" in result.output
    assert "Traceback" not in result.output
    assert not (tmp_path / "out").exists()
    independent = invoke("compare", str(runs), "--out", str(tmp_path / "out"), columns=300)
    assert independent.exit_code == 0, independent.output
    assert pd.read_csv(tmp_path / "out" / "tables" / "verdicts.csv")["seeds"].tolist() == [SEEDS - 1]


def test_a_run_of_another_budget_is_one_line_naming_its_file(runs, tmp_path):
    short = runs / "ppo" / "CartPole-v1" / "2" / "0.monitor.csv"
    short.write_text("\n".join(short.read_text().splitlines()[:60]) + "\n")
    result = invoke("compare", str(runs), "--out", str(tmp_path / "out"), columns=300)
    assert result.exit_code == 2
    assert str(short) in result.output
    assert "expected runs of one budget" in result.output
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(("arguments", "said"), [
    (["--group", "{method}/{seed}/*"], "--group"),
    (["--group", "{method}/{env}/x{seed}/*"], "does not match the grouping rule"),
    (["--margin", "0"], "--margin"),
])
def test_bad_options_are_one_line(runs, tmp_path, arguments, said):
    result = invoke("compare", str(runs), *arguments, "--out", str(tmp_path / "out"), columns=300)
    assert result.exit_code == 2
    assert said in result.output
    assert "Traceback" not in result.output
    assert not (tmp_path / "out").exists()


def test_an_empty_directory_is_one_line(tmp_path):
    (tmp_path / "empty").mkdir()
    result = invoke("compare", str(tmp_path / "empty"), "--out", str(tmp_path / "out"), columns=300)
    assert result.exit_code == 2
    assert "no run found" in result.output


@pytest.mark.slow("writes 10 TensorBoard files and draws the report")
def test_tensorboard_files_in_cleanrls_layout_become_a_report(tmp_path):
    pytest.importorskip("tensorboard")
    from tensorboard.summary import Writer

    rng = np.random.default_rng(1)
    for method, level in LEVELS.items():
        for seed in range(SEEDS):
            writer = Writer(str(tmp_path / "runs" / f"CartPole-v1__{method}__{seed}__1700000000"))
            for step in range(0, 20_000, 250):
                writer.add_scalar("charts/episodic_return", level * step / 20_000 + rng.normal(0, 5), step=step)
            writer.add_scalar("losses/td_loss", 1.0, step=0)
            writer.close()
    result = invoke("compare", str(tmp_path / "runs"), "--group", "{env}__{method}__{seed}__*/*", "--out",
                    str(tmp_path / "out"), columns=300)
    assert result.exit_code == 0, result.output
    pairing = pd.read_csv(tmp_path / "out" / "tables" / "pairing.csv")
    assert len(pairing) == 2 * SEEDS
    assert (pairing["points"] == 80).all()
    assert (pd.read_csv(tmp_path / "out" / "tables" / "verdicts.csv")["verdict"] == "ppo better").all()
    missing = invoke("compare", str(tmp_path / "runs"), "--group", "{env}__{method}__{seed}__*/*", "--tag",
                     "eval/mean_reward", "--out", str(tmp_path / "other"), columns=300)
    assert missing.exit_code == 2
    assert "expected the tag 'eval/mean_reward'" in missing.output
    assert not (tmp_path / "other").exists()


@pytest.mark.slow("bootstraps rliable's aggregates over two environments")
def test_two_environments_are_pooled_as_rliable_does_on_their_reference_scores(tmp_path):
    """Without reference scores, nothing is pooled (a scale of the methods' own means moves with the methods
    present); with --scores, each environment is normalised by them: a method's mean normalised score over the
    environments is computed here by hand."""
    runs = write_runs(tmp_path / "runs")
    for method in LEVELS:  # the same runs again as a second environment
        for seed_dir in (runs / method / "CartPole-v1").iterdir():
            target = runs / method / "Acrobot-v1" / seed_dir.name
            target.mkdir(parents=True)
            (target / "0.monitor.csv").write_text((seed_dir / "0.monitor.csv").read_text())
    unscaled = invoke("compare", str(runs), "--out", str(tmp_path / "unscaled"), columns=300)
    assert unscaled.exit_code == 0, unscaled.output
    assert not (tmp_path / "unscaled" / "tables" / "aggregates.csv").exists()
    assert "Not pooled: no reference scores for Acrobot-v1, CartPole-v1 (--scores" in html.unescape(
        (tmp_path / "unscaled" / "report.html").read_text())
    result = invoke("compare", str(runs), "--scores", "CartPole-v1=0:500", "--scores", "Acrobot-v1=0:250", "--out",
                    str(tmp_path / "out"), columns=300)
    assert result.exit_code == 0, result.output
    intervals = pd.read_csv(tmp_path / "out" / "tables" / "aggregates.csv")
    assert set(intervals.iloc[:, 0]) == {"dqn", "ppo"}
    frame = read_runs(sorted(runs.rglob("*.monitor.csv")), runs, grouping("{method}/{env}/{seed}/*"))
    finals = {n.env: n.values["ppo"]["final"] for n in compare_numbers.numbers(frame)}
    by_hand = np.mean([finals["CartPole-v1"] / 500, finals["Acrobot-v1"] / 250])
    mean = intervals.loc[intervals["method"] == "ppo", "mean [95% CI]"].iloc[0]
    assert float(str(mean).split()[0]) == pytest.approx(by_hand, abs=0.005)
    page = html.unescape((tmp_path / "out" / "report.html").read_text())
    assert "Across environments" in page
    assert "Acrobot-v1: 0 to 250; CartPole-v1: 0 to 500" in page
    (runs / "dqn" / "Acrobot-v1" / "4" / "0.monitor.csv").unlink()  # dqn: 4 seeds on one, 5 on the other
    uneven = invoke("compare", str(runs), "--scores", "CartPole-v1=0:500", "--scores", "Acrobot-v1=0:250", "--out",
                    str(tmp_path / "uneven"), columns=300)
    assert uneven.exit_code == 0, uneven.output
    assert "Acrobot-v1: dqn 4, ppo 5; CartPole-v1: dqn 5, ppo 5" in html.unescape(
        (tmp_path / "uneven" / "report.html").read_text())
    # the same directory again for other runs (one environment): refused without a word of --force, the earlier
    # report kept; with it, the earlier comparison's aggregates and figures go
    before = {p.name for p in (tmp_path / "out" / "figures").iterdir()}
    page = (tmp_path / "out" / "report.html").read_bytes()
    one_env = (str(runs / "dqn" / "CartPole-v1"), str(runs / "ppo" / "CartPole-v1"), "--group",
               "{method}/{env}/{seed}/*", "--out", str(tmp_path / "out"))
    refused = invoke("compare", *one_env, columns=300)
    assert refused.exit_code == 2, refused.output
    assert "holds the comparison of other runs (methods dqn, ppo; environments Acrobot-v1, CartPole-v1)" in " ".join(
        refused.output.split())
    assert (tmp_path / "out" / "report.html").read_bytes() == page
    one = invoke("compare", *one_env, "--force", columns=300)
    assert one.exit_code == 0, one.output
    assert not (tmp_path / "out" / "tables" / "aggregates.csv").exists()
    after = {p.name for p in (tmp_path / "out" / "figures").iterdir()}
    assert after < before


def test_force_writes_beside_a_users_files_and_leaves_them(runs, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "mine.txt").write_text("keep me")
    refused = invoke("compare", str(runs), "--out", str(out), columns=300)
    assert refused.exit_code == 2
    assert "--force" in refused.output
    forced = invoke("compare", str(runs), "--out", str(out), "--force", columns=300)
    assert forced.exit_code == 0, forced.output
    assert (out / "mine.txt").read_text() == "keep me"
    assert (out / "report.html").exists()


@pytest.mark.slow("compares runs twice through the command line")
def test_a_wandb_charts_export_gives_the_verdicts_of_the_same_numbers_as_a_tidy_table(tmp_path):
    """Five seeds of two methods as W&B exports a chart (CleanRL's run names, a gap where a run logged nothing),
    and the same points as a tidy table."""
    rng = np.random.default_rng(5)
    steps = np.arange(1, 41) * 500
    chart: dict[str, object] = {"Step": steps}
    rows = []
    for method, level in (("ppo", 200.0), ("a2c", 120.0)):
        for seed in range(5):
            values = level * steps / steps[-1] + rng.normal(0, 10, steps.size)
            shown = [None if (i + seed) % 7 == 0 else v for i, v in enumerate(values)]
            name = f"CartPole-v1__{method}__{seed}__17000000{seed}"
            chart |= {f"{name} - charts/episodic_return": shown, f"{name} - charts/episodic_return__MIN": shown,
                      f"{name} - charts/episodic_return__MAX": shown}
            rows += [{"method": method, "env": "CartPole-v1", "seed": seed, "step": s, "value": v}
                     for s, v in zip(steps, shown, strict=True) if v is not None]
    pd.DataFrame(chart).to_csv(tmp_path / "chart.csv", index=False)
    pd.DataFrame(rows).to_csv(tmp_path / "tidy.csv", index=False)
    from_chart = invoke("compare", str(tmp_path / "chart.csv"), "--group", "{env}__{method}__{seed}__*", "--out",
                        str(tmp_path / "a"), columns=300)
    from_table = invoke("compare", str(tmp_path / "tidy.csv"), "--out", str(tmp_path / "b"), columns=300)
    assert from_chart.exit_code == from_table.exit_code == 0, from_chart.output
    pd.testing.assert_frame_equal(pd.read_csv(tmp_path / "a" / "tables" / "verdicts.csv"),
                                  pd.read_csv(tmp_path / "b" / "tables" / "verdicts.csv"))
    assert "ppo better" in pd.read_csv(tmp_path / "a" / "tables" / "verdicts.csv")["verdict"].tolist()
