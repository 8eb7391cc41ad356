"""``rlcompare compare`` attacked: episodes of unequal length, ties at a cap, the same runs given twice, two kinds of
points on one environment, a resumed TensorBoard run, values that are not finite, steps past any training, runs
that never overlap and a method alone. Each right answer is computed by hand; each refusal is one line naming the
file, exit 2, and nothing written."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from helpers import invoke

from rlcompare.experiment.outside import grouping, read_runs, run_files
from rlcompare.stats import power
from rlcompare.studies import compare_numbers, compare_runs

RULE = "{method}/{env}/{seed}/*"


def monitor(path: Path, returns: np.ndarray, lengths: np.ndarray) -> Path:
    """A Monitor file as Stable-Baselines3 writes it."""
    path.parent.mkdir(parents=True, exist_ok=True)
    rows = "".join(f"{r:.6f},{n},{0.01 * i:.2f}\n" for i, (r, n) in enumerate(zip(returns, lengths, strict=True)))
    path.write_text("#" + json.dumps({"t_start": 0.0, "env_id": "CartPole-v1"}) + "\nr,l,t\n" + rows)
    return path


def tidy(path: Path, rows: list[tuple[str, str, int, float, float]]) -> Path:
    pd.DataFrame(rows, columns=["method", "env", "seed", "step", "value"]).to_csv(path, index=False)
    return path


def pairing_of(frame: pd.DataFrame) -> set[tuple[str, str]]:
    return {(str(m), str(s)) for m, s in zip(frame["method"], frame["seed"], strict=True)}


def refused(tmp_path: Path, *args: str) -> str:
    """``compare ARGS`` into a fresh directory: exit 2, one message, nothing written; the output."""
    out = tmp_path / "refused"
    result = invoke("compare", *args, "--out", str(out), columns=400)
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    assert not out.exists()
    return result.output


def test_long_episodes_weigh_no_more_than_short_ones(tmp_path: Path) -> None:
    """Return equals length (CartPole's), both methods averaging 250 a episode: 'bimodal' episodes of 10 or 490 at
    random, 'steady' ones of 250. On a grid even in steps the bimodal runs scored 181 more, since a step lands on
    an episode in proportion to its length. Read from the episodes: each seed's final number is the mean of the
    episodes that end in the final window, computed here by hand, and the two methods are not told apart."""
    rng = np.random.default_rng(7)
    for seed in range(6):
        bimodal = rng.choice([10, 490], size=600)
        monitor(tmp_path / "runs" / "bimodal" / "CartPole-v1" / str(seed) / "0.monitor.csv", bimodal, bimodal)
        steady = np.full(600, 250)
        monitor(tmp_path / "runs" / "steady" / "CartPole-v1" / str(seed) / "0.monitor.csv", steady, steady)
    frame = read_runs(sorted((tmp_path / "runs").rglob("*.monitor.csv")), tmp_path / "runs", grouping(RULE))
    (read,) = compare_numbers.numbers(frame)
    low = read.end - 0.1 * (read.end - read.start)
    for seed, label in enumerate(read.seeds["bimodal"]):
        run = frame[(frame["method"] == "bimodal") & (frame["seed"] == label)]
        ending = run[(run["step"] >= low) & (run["step"] <= read.end)]["value"]
        assert read.values["bimodal"]["final"][seed] == pytest.approx(ending.mean())
    assert abs(read.values["bimodal"]["final"].mean() - 250) < 20
    assert (read.values["steady"]["final"] == 250).all()
    result = invoke("compare", str(tmp_path / "runs"), "--out", str(tmp_path / "out"), columns=300)
    assert result.exit_code == 0, result.output
    verdicts = pd.read_csv(tmp_path / "out" / "tables" / "verdicts.csv")
    assert verdicts.loc[verdicts["metric"] == "final", "verdict"].tolist() == ["not resolved"]


def test_ties_at_a_cap_get_the_exact_p_and_holm_over_both_metrics(tmp_path: Path) -> None:
    """4 seeds a side, A at the cap of 500 on every seed, B at 100, 200, 300 and 400: the exact rank-sum p is
    2 / C(8, 4) = 0.0286 (scipy's normal approximation said 0.021). With both metrics declared, Holm doubles it to
    0.057: not resolved, and the answer says this design cannot decide, and that 5 seeds a side could. With the
    primary metric alone, 0.0286 passes 0.05: capped better."""
    rows = [(method, "CartPole-v1", seed, step, value)
            for method, levels in (("capped", [500.0] * 4), ("other", [100.0, 200.0, 300.0, 400.0]))
            for seed, value in enumerate(levels) for step in (100, 200, 300)]
    path = tidy(tmp_path / "runs.csv", rows)
    primary = invoke("compare", str(path), "--out", str(tmp_path / "primary"), columns=400)
    assert primary.exit_code == 0, primary.output
    alone = pd.read_csv(tmp_path / "primary" / "tables" / "verdicts.csv")
    assert alone["p (Holm)"].tolist() == pytest.approx([2 / 70])
    assert alone["verdict"].tolist() == ["capped better"]
    result = invoke("compare", str(path), "--metric", "final,auc", "--out", str(tmp_path / "out"), columns=400)
    assert result.exit_code == 0, result.output
    verdicts = pd.read_csv(tmp_path / "out" / "tables" / "verdicts.csv")
    assert verdicts["p (Holm)"].tolist() == pytest.approx([4 / 70, 4 / 70])
    assert verdicts["verdict"].tolist() == ["not resolved"] * 2
    words = " ".join(result.output.split())
    assert "cannot give a p below 0.0286; Holm asks 0.025 of the smallest over the 2 tests" in words
    assert "(with 5 seeds a side it can)" in words


def test_the_same_runs_given_twice_are_refused_naming_both_sources(tmp_path: Path) -> None:
    returns, lengths = np.arange(1.0, 21.0), np.full(20, 10)
    for method in ("ppo", "a2c"):
        monitor(tmp_path / "runs" / method / "CartPole-v1" / "0" / "0.monitor.csv", returns, lengths)
    table = tidy(tmp_path / "runs" / "runs.csv",
                 [("ppo", "CartPole-v1", 0, 10 * (i + 1), r) for i, r in enumerate(returns)])
    said = refused(tmp_path, str(tmp_path / "runs"), str(table))
    assert "method ppo, environment CartPole-v1, seed 0 again" in said
    assert "runs.csv" in said
    assert "0.monitor.csv" in said


def test_two_runs_of_one_method_under_other_settings_are_refused_not_merged(tmp_path: Path) -> None:
    """SARSA at α 0.05 and at 0.5, two run directories of one configuration name: once both became 'sarsa' and
    nothing was compared, exit 0."""
    for alpha in ("0.05", "0.5"):
        assert invoke("run", "--algorithm", "sarsa", "--alpha", alpha, "--seeds", "2", "--episodes", "5", "--out",
                      str(tmp_path / f"sarsa-{alpha}")).exit_code == 0
    said = refused(tmp_path, str(tmp_path / "sarsa-0.05"), str(tmp_path / "sarsa-0.5"))
    assert "method sarsa-decay, environment MountainCar-v0, seed 0 again" in said


def test_evaluations_against_training_episodes_on_one_environment_are_refused(tmp_path: Path) -> None:
    monitor(tmp_path / "runs" / "a2c" / "CartPole-v1" / "0" / "0.monitor.csv", np.ones(5), np.full(5, 10))
    evaluations = tmp_path / "runs" / "ppo" / "CartPole-v1" / "0" / "evaluations.npz"
    evaluations.parent.mkdir(parents=True)
    np.savez(evaluations, timesteps=np.array([10, 20, 30]), results=np.ones((3, 2)))
    said = refused(tmp_path, str(tmp_path / "runs"))
    assert "RL Zoo evaluations on CartPole-v1, where" in said
    assert "Monitor episodes" in said


def test_a_tensorboard_run_whose_steps_restart_is_refused(tmp_path: Path) -> None:
    pytest.importorskip("tensorboard")
    from tensorboard.summary import Writer

    directory = tmp_path / "runs" / "ppo" / "CartPole-v1" / "0"
    writer = Writer(str(directory))
    for step, value in ((100, 1.0), (200, 2.0), (50, 1.5), (150, 2.5)):  # a resumed run appended to the first
        writer.add_scalar("charts/episodic_return", value, step=step)
    writer.close()
    said = refused(tmp_path, str(tmp_path / "runs"))
    assert "its steps go back from 200 to 50" in said


@pytest.mark.parametrize(("rows", "said"), [
    ([("a", "e", 0, 10, float("inf"))], "is inf; expected finite values"),
    ([("a", "e", 0, 1e19, 1.0)], "a step of 1e+19; expected whole numbers from 0 to"),
    ([("a", "e", 0, 10.5, 1.0)], "a step of 10.5"),
    ([("a", "e", 0, -1, 1.0)], "a step of -1"),
])
def test_values_and_steps_no_run_can_hold_are_refused(tmp_path: Path, rows: list, said: str) -> None:
    rows = [*rows, ("b", "e", 0, 10, 1.0), ("a", "e", 0, 20, 1.0), ("b", "e", 0, 20, 1.0)]
    assert said in refused(tmp_path, str(tidy(tmp_path / "runs.csv", rows)))


def test_an_infinite_return_in_a_monitor_file_is_refused_naming_it(tmp_path: Path) -> None:
    path = monitor(tmp_path / "runs" / "a" / "e" / "0" / "0.monitor.csv", np.array([1.0, np.inf]), np.array([5, 5]))
    monitor(tmp_path / "runs" / "b" / "e" / "0" / "0.monitor.csv", np.array([1.0, 2.0]), np.array([5, 5]))
    said = refused(tmp_path, str(tmp_path / "runs"))
    assert str(path) in said
    assert "not a finite number" in said


def test_runs_that_never_overlap_are_refused_even_cut_to_the_shortest(tmp_path: Path) -> None:
    rows = [("a", "e", 0, step, 1.0) for step in (10, 20, 30)] + [("b", "e", 0, step, 2.0) for step in (40, 50)]
    said = refused(tmp_path, str(tidy(tmp_path / "runs.csv", rows)), "--cut-to-shortest")
    assert "share no steps" in said


def test_an_unknown_metric_is_one_line_naming_the_option(tmp_path: Path) -> None:
    rows = [(m, "e", 0, step, 1.0) for m in ("a", "b") for step in (10, 20)]
    said = refused(tmp_path, str(tidy(tmp_path / "runs.csv", rows)), "--metric", "final,median")
    assert "'--metric'" in said
    assert "final, auc" in said


def test_a_method_alone_is_refused(tmp_path: Path) -> None:
    rows = [("a", "e", seed, step, 1.0) for seed in (0, 1) for step in (10, 20)]
    assert "a alone on e" in refused(tmp_path, str(tidy(tmp_path / "runs.csv", rows)))


@pytest.mark.parametrize("given", ["CartPole-v1=500:0", "CartPole-v1=low:high", "=0:1", "CartPole-v1"])
def test_reference_scores_that_are_not_a_range_are_one_line_naming_the_option(tmp_path: Path, given: str) -> None:
    rows = [(m, "CartPole-v1", 0, step, 1.0) for m in ("a", "b") for step in (10, 20)]
    said = refused(tmp_path, str(tidy(tmp_path / "runs.csv", rows)), "--scores", given)
    assert "'--scores'" in said
    assert "ENV=LOW:HIGH" in said


def test_an_atari_games_published_scores_are_its_references() -> None:
    """Breakout's published random and human scores (1.7 and 30.5), by each of its spellings."""
    names = ["ALE/Breakout-v5", "BreakoutNoFrameskip-v4", "Breakout-Atari", "CartPole-v1"]
    found = compare_runs.reference_scores(names, {"CartPole-v1": (0.0, 500.0)})
    assert found == {**dict.fromkeys(names[:3], (1.7, 30.5)), "CartPole-v1": (0.0, 500.0)}


def test_runs_reached_through_a_link_out_of_the_tree_are_read_below_the_directory_given(tmp_path: Path) -> None:
    """Monitor files linked from the directory given to files elsewhere: once ``ValueError ... is not in the
    subpath``, a traceback; the rule reads the path as given."""
    for method in ("a", "b"):
        target = monitor(tmp_path / "elsewhere" / f"{method}.monitor.csv", np.ones(4), np.full(4, 5))
        link = tmp_path / "given" / method / "e" / "0" / "0.monitor.csv"
        link.parent.mkdir(parents=True)
        link.symlink_to(target)
    result = invoke("compare", str(tmp_path / "given"), "--out", str(tmp_path / "out"), columns=300)
    assert result.exit_code == 0, result.output
    assert "Traceback" not in result.output


def test_a_linked_directory_of_runs_is_read_as_a_directory_and_a_link_back_up_ends(tmp_path: Path) -> None:
    """``given/b`` links to a directory of runs kept elsewhere (once: "no run found", without a word of the link);
    ``given/b/e/loop`` links back up to ``given``, which is read once, not forever."""
    for method in ("a", "b"):
        place = tmp_path / ("given" if method == "a" else "elsewhere") / (method if method == "a" else "")
        for seed in range(2):
            monitor(place / "e" / str(seed) / "0.monitor.csv", np.full(4, 1.0 + seed), np.full(4, 5))
    (tmp_path / "given" / "b").symlink_to(tmp_path / "elsewhere", target_is_directory=True)
    (tmp_path / "elsewhere" / "e" / "loop").symlink_to(tmp_path / "given", target_is_directory=True)
    root, files = run_files([tmp_path / "given"])
    assert root == tmp_path / "given"
    assert sorted(f.relative_to(root).as_posix() for f in files) == [
        f"{m}/e/{s}/0.monitor.csv" for m in ("a", "b") for s in range(2)]
    assert pairing_of(read_runs(files, root, grouping(RULE))) == {("a", "0"), ("a", "1"), ("b", "0"), ("b", "1")}


def test_the_plan_states_the_family_its_reach_and_each_detectable_difference_and_writes_nothing(
        tmp_path: Path) -> None:
    """3 seeds of A (1, 2, 3) against 5 of B (2, 4, 6, 8, 10), each run constant: the pooled spread is
    sqrt((2 * 1 + 4 * 10) / 6) = sqrt(7); Mann-Whitney's smallest p is 2 / C(8, 3) = 0.0357, under 0.05 alone and
    over the 0.025 Holm asks of two tests (a declared margin adds the equivalence test)."""
    values = {"A": [1, 2, 3], "B": [2, 4, 6, 8, 10]}
    rows = [(method, "E", seed, step, float(value)) for method, runs in values.items()
            for seed, value in enumerate(runs) for step in range(0, 101, 10)]
    table = tidy(tmp_path / "runs.csv", rows)
    out = tmp_path / "out"
    alone = invoke("compare", str(table), "--plan", "--out", str(out), columns=400)
    assert alone.exit_code == 0, alone.output
    assert "This design can decide each pair of methods on each environment (one comparison)" in alone.output
    assert "the rank-sum test on 3 and 5 seeds can give a p of 0.036, at or below the level 0.05" in alone.output
    by_hand = power.detectable_difference(np.sqrt(7), 3, 0.05, other_seeds=5) / np.sqrt(3 / np.pi)
    assert f"E, A against B (final): {by_hand:.4g}" in alone.output
    with_margin = invoke("compare", str(table), "--plan", "--margin", "1", "--out", str(out), columns=400)
    assert with_margin.exit_code == 0, with_margin.output
    assert "This design cannot decide" in with_margin.output
    assert "above the 0.025 Holm asks over 2 tests" in with_margin.output
    assert "E, A against B (final): none (these seeds cannot pass the level)" in with_margin.output
    assert not out.exists()


def test_a_report_is_replaced_by_one_of_the_same_runs_and_never_by_another_comparisons(tmp_path: Path) -> None:
    rows = [(method, "E", seed, step, float(value + seed)) for method, value in (("A", 1), ("B", 5))
            for seed in range(4) for step in range(0, 101, 10)]
    table, out = tidy(tmp_path / "runs.csv", rows), tmp_path / "out"
    assert invoke("compare", str(table), "--out", str(out)).exit_code == 0
    margin = invoke("compare", str(table), "--margin", "1", "--out", str(out), columns=400)
    assert margin.exit_code == 0, margin.output  # the same runs, another margin: the report is replaced
    assert "Margin of no difference, declared on the command line: ±1" in (out / "report.html").read_text()
    other = tidy(tmp_path / "other.csv", [(m, e, s, t, v + 1) for m, e, s, t, v in rows])
    refused = invoke("compare", str(other), "--out", str(out), columns=400)
    assert refused.exit_code == 2
    assert f"{out}: holds the comparison of other runs (methods A, B; environments E)" in refused.output
    assert "Margin of no difference, declared on the command line: ±1" in (out / "report.html").read_text()


def test_a_tidy_table_given_twice_over_is_refused_and_episodes_that_end_together_pass(tmp_path: Path) -> None:
    """The rows of seed 0 of A twice (a table appended to itself): every step holds two points, which would have
    been read as one run; a step that holds two episodes of a vectorised environment (step 20 here) passes."""
    rows = [(m, "e", s, step, float(s + step)) for m in ("a", "b") for s in range(2) for step in (10, 20, 30)]
    said = refused(tmp_path, str(tidy(tmp_path / "twice.csv", [*rows, *rows[:3]])))
    assert "twice.csv: method a, environment e, seed 0 has 2 points at step 10 and at every other step" in said
    together = tidy(tmp_path / "together.csv", [*rows, ("a", "e", 0, 20, 5.0)])
    frame = read_runs([together], tmp_path, grouping(RULE))
    assert len(frame) == 13


def test_a_monitor_file_a_resumed_run_was_appended_to_is_refused(tmp_path: Path) -> None:
    """SB3's Monitor(override_existing=False) appends a resumed run's episodes, their wall times from its own start:
    t goes back (here from 0.02 s to 0.00 s at the fourth episode), and sorting by it interleaved the two runs."""
    path = monitor(tmp_path / "runs" / "a" / "e" / "0" / "0.monitor.csv", np.arange(1.0, 4.0), np.full(3, 5))
    with open(path, "a") as file:
        file.write("".join(f"{r:.6f},5,{0.01 * i:.2f}\n" for i, r in enumerate((7.0, 8.0))))
    monitor(tmp_path / "runs" / "b" / "e" / "0" / "0.monitor.csv", np.ones(5), np.full(5, 5))
    said = refused(tmp_path, str(tmp_path / "runs"))
    assert f"{path}: its wall time t goes back from 0.02 s to 0 s at episode 4" in said


@pytest.mark.slow("writes the report of two environments")
def test_aggregates_left_out_for_seed_counts_that_differ_between_environments_say_why(tmp_path: Path) -> None:
    """A and B on 5 seeds of E1 and 3 of E2, each with reference scores: rliable's matrix of seeds by environments
    needs one number of seeds a method; the reason said the stratified bootstrap needed it, which it does not."""
    import html

    rows = [(m, env, s, step, float(s + (m == "A"))) for m in ("A", "B") for env, seeds in (("E1", 5), ("E2", 3))
            for s in range(seeds) for step in (10, 20)]
    out = tmp_path / "out"
    result = invoke("compare", str(tidy(tmp_path / "runs.csv", rows)), "--scores", "E1=0:10", "--scores", "E2=0:10",
                    "--out", str(out), columns=300)
    assert result.exit_code == 0, result.output
    page = " ".join(html.unescape((out / "report.html").read_text()).split())
    assert ("Not pooled: no two methods ran every environment on one number of seeds. rliable's aggregates read each "
            "method's seeds by environments as one matrix, with the same seeds on every environment; seeds: E1: A 5, "
            "B 5; E2: A 3, B 3.") in page
    assert not (out / "tables" / "aggregates.csv").exists()


def rl_zoo_folder(root: Path) -> Path:
    """RL Zoo's own layout, logs/ALGO/ENV_ID/: a run's Monitor file and its evaluations in one directory. Monitor
    returns are 100 + the run for PPO and the run for A2C; evaluations 10 + the run and the run."""
    for algo, offset in (("ppo", 1), ("a2c", 0)):
        for run in (1, 2, 3):
            directory = root / algo / f"CartPole-v1_{run}"
            monitor(directory / "0.monitor.csv", np.full(20, 100.0 * offset + run), np.full(20, 10))
            np.savez(directory / "evaluations.npz", timesteps=np.array([50, 100, 150, 200]),
                     results=np.full((4, 2), 10.0 * offset + run))
    return root


@pytest.mark.slow("writes two reports")
def test_rl_zoos_own_folder_is_read_one_kind_of_file_at_a_time(tmp_path: Path) -> None:
    """Once refused as 'seed 1 again', with --group for a remedy that could not help. Each kind read alone gives its
    own means by hand: evaluations A2C 2 against PPO 12, Monitor episodes 2 against 102."""
    root, rule = rl_zoo_folder(tmp_path / "logs"), "{method}/{env}_{seed}/*"
    said = refused(tmp_path, str(root), "--group", rule)
    assert "one kind of file a directory with --files (RL Zoo keeps a run's Monitor files and evaluations" in said
    for kind, means in (("evaluations", [2.0, 12.0]), ("monitor", [2.0, 102.0])):
        out = tmp_path / kind
        result = invoke("compare", str(root), "--group", rule, "--files", kind, "--out", str(out), columns=300)
        assert result.exit_code == 0, result.output
        verdicts = pd.read_csv(out / "tables" / "verdicts.csv")
        assert verdicts[["A mean", "B mean"]].iloc[0].tolist() == pytest.approx(means)
        kinds = set(pd.read_csv(out / "tables" / "pairing.csv")["kind"])
        assert kinds == {"RL Zoo evaluations" if kind == "evaluations" else "Monitor episodes"}


def test_an_unknown_kind_of_file_is_one_line_naming_the_option(tmp_path: Path) -> None:
    said = refused(tmp_path, str(rl_zoo_folder(tmp_path / "logs")), "--files", "monitor,csv")
    assert "'--files'" in said
    assert "monitor, evaluations, tensorboard" in said
