"""The MinAtar study through the CLI at a tiny size: its run directories and report, resuming, bad input, and a
trained agent playing the reference game and Gymnasium's as it plays our port."""

from __future__ import annotations

import html
import warnings

import numpy as np
import pandas as pd
import pytest
from scipy import stats

jax = pytest.importorskip("jax")
pytest.importorskip("gymnax")
minatar_reference = pytest.importorskip("minatar")

from helpers import assert_loaded_not_trained, assert_same_runs, finished_runs, invoke, kill_when, start, study_fixture  # noqa: E402

from rlcompare import load_agent  # noqa: E402
from rlcompare.deep import float64  # noqa: E402
from rlcompare.deep.envs import jax_env  # noqa: E402
from rlcompare.deep.methods import DEEP_METHODS  # noqa: E402
from rlcompare.deep.rollout import evaluate  # noqa: E402
from rlcompare.formatting import number  # noqa: E402
from rlcompare.studies.deep.minatar import plan_of  # noqa: E402
from rlcompare.studies.paired_plan import random_returns  # noqa: E402
from rlcompare.studies.paper.claims import CLAIMS as PAPER_CLAIMS  # noqa: E402
from rlcompare.studies.registry import MinAtarOptions  # noqa: E402

TINY = ["reproduce", "minatar", "--allow-undecidable", "--seeds", "2", "--games", "breakout", "--steps", "40960",
        "--methods",
        "pqn_sarsa_lambda,pqn_q_lambda"]
EPISODES = 150


study = study_fixture("minatar", *TINY)


@pytest.mark.slow("trains and reports MinAtar studies")
def test_the_study_writes_its_runs_and_a_report(study):
    out, output = study
    assert sorted(p.name for p in out.iterdir() if p.is_dir()) == [
        "figures", "pqn_q_lambda-breakout", "pqn_sarsa_lambda-breakout", "tables", "videos"]
    summary = pd.read_csv(out / "tables" / "minatar_summary.csv")
    assert summary["env"].tolist() == ["MinAtar/Breakout-v0"] * 2
    assert summary["final at ε = 0.05, mean"].str.match(r"-?\d+\.\d\d \[").all()
    verdicts = pd.read_csv(out / "tables" / "minatar_verdicts.csv")
    assert verdicts["game"].tolist() == ["Breakout"]
    assert not (out / "tables" / "minatar_improvement.csv").exists()  # one game: nothing to pool
    assert "SARSA(λ) scores on Breakout" in " ".join(output.split())
    page = (out / "report.html").read_text()
    assert page.count("<img") == 2  # the paired differences, Breakout's curves (one game: no aggregates)
    assert page.index(">The answer</h2>") < page.index("paired-differences.png") < page.index('<nav')
    assert sorted(p.name for p in (out / "videos").iterdir()) == [
        "pqn_q_lambda-breakout.gif", "pqn_q_lambda-breakout.mp4", "pqn_sarsa_lambda-breakout.gif",
        "pqn_sarsa_lambda-breakout.mp4"]
    assert page.count("<video") == 2
    assert "a short budget" in page
    assert "sticky actions 0.1" in page
    said = " ".join(html.unescape(page).split())
    assert "Q(λ) here is Peng's (purejaxql's)" in said  # what the pair differs in
    assert "at λ = 0.65 it differs from SARSA(λ) only in the 0.35-weighted bootstrap" in said
    assert "a shorter budget decays them sooner" in said  # the schedules, rescaled, stated
    assert "Breakout 0.455 to 10" in said  # the game's scale: the random policy to the MinAtar paper's DQN
    # two seeds cannot pass the learning gate (the one-sided signed-rank test's smallest p is 1/4)
    assert verdicts["verdict"].tolist() == ["neither learnt at this budget"]


@pytest.mark.slow("trains and reports MinAtar studies")
def test_a_finished_study_is_loaded_not_trained_again(study):
    out, _ = study
    assert_loaded_not_trained(out, *TINY, runs=2)


@pytest.mark.parametrize(("arguments", "named"), [
    (["--games", "breakout,pong"], "--games"),
    (["--protocol", "atari"], "--protocol"),
    (["--budget", "huge"], "--budget"),
    (["--steps", "100"], "--steps"),
    (["--methods", "pqn_q_lambda,a2c"], "--methods"),
])
def test_bad_input_is_one_message_naming_the_option(tmp_path, arguments, named):
    result = invoke("reproduce", "minatar", "--allow-undecidable", "--seeds", "2", *arguments,
                                      "--out", str(tmp_path / "x"), columns=None)
    assert result.exit_code == 2
    assert named in result.output
    assert "Traceback" not in result.output
    assert not (tmp_path / "x").exists()


@pytest.mark.slow("plays 150 episodes of the reference game")
def test_the_random_policy_scores_as_the_reference_games_random_policy():
    ours = random_returns("MinAtar/Breakout-v0", EPISODES)
    reference = minatar_reference.Environment("breakout", sticky_action_prob=0.1)
    reference.seed(0)
    rng = np.random.default_rng(0)
    theirs = []
    for _ in range(EPISODES):
        reference.reset()
        score, done = 0.0, False
        while not done:
            reward, done = reference.act(int(rng.integers(6)))
            score += reward
        theirs.append(score)
    assert stats.mannwhitneyu(ours, theirs).pvalue > 1e-3


def play(agent, env_step, reset, episodes: int) -> np.ndarray:
    returns = []
    for k in range(episodes):
        observation, score, done = reset(k), 0.0, False
        while not done:
            observation, reward, done = env_step(agent.act(observation))
            score += reward
        returns.append(score)
    return np.asarray(returns)


@pytest.mark.slow("trains and reports MinAtar studies")
def test_a_trained_agent_plays_the_reference_game_and_gymnasiums_as_it_plays_our_port(study):
    import gymnasium as gym
    from minatar.gym import register_envs

    agent = load_agent(study[0] / "pqn_q_lambda-breakout", seed=1)
    port = jax_env("MinAtar/Breakout-v0")
    in_port = float64(lambda: np.asarray(jax.jit(
        lambda key: evaluate(port, agent._act, agent.params, key, EPISODES)[0])(jax.random.key(5))))()

    reference = minatar_reference.Environment("breakout", sticky_action_prob=0.1)
    reference.seed(7)

    def reference_step(action: int):
        reward, done = reference.act(action)
        return reference.state(), reward, done

    in_reference = play(agent, reference_step, lambda k: (reference.reset(), reference.state())[1], EPISODES)

    if "MinAtar/Breakout-v0" not in gym.registry:
        register_envs()
    with warnings.catch_warnings():  # v1 is the minimal action set, not a newer version of v0
        warnings.filterwarnings("ignore", ".*MinAtar/Breakout-v0 is out of date", DeprecationWarning)
        env = gym.make("MinAtar/Breakout-v0")

    def gymnasium_step(action: int):
        observation, reward, terminated, truncated, _ = env.step(action)
        return observation, reward, terminated or truncated

    in_gymnasium = play(agent, gymnasium_step, lambda k: env.reset(seed=100 + k)[0], EPISODES)
    assert in_port.std() > 0  # the agent's episodes differ: the comparison below could fail
    for played in (in_reference, in_gymnasium):
        assert stats.mannwhitneyu(in_port, played).pvalue > 1e-3
        assert abs(played.mean() - in_port.mean()) < 4 * np.hypot(played.std(), in_port.std()) / np.sqrt(EPISODES)


@pytest.mark.slow("trains and reports MinAtar studies")
def test_an_agent_of_gymnaxs_protocol_plays_gymnasiums_minimal_action_set_as_our_port(tmp_path):
    """``Breakout-MinAtar`` (gymnax's protocol: the minimal actions, no sticky actions) is Gymnasium's
    ``MinAtar/Breakout-v1`` with sticky actions off."""
    import gymnasium as gym
    from minatar.gym import register_envs

    from rlcompare.deep.config import DeepConfig
    from rlcompare.experiment.runner import run as deep_run

    deep_run(DeepConfig(algorithm="pqn_q_lambda", env="Breakout-MinAtar", seeds=(0,), vmap_width=1, eval_rounds=2,
                        eval_episodes=2, hyperparameters={"total_steps": 16 * 16 * 8, "n_envs": 16, "n_steps": 16,
                                                          "n_minibatches": 2, "hidden": (32,)}), out=tmp_path / "run")
    agent = load_agent(tmp_path / "run", seed=0)
    port = jax_env("Breakout-MinAtar")
    in_port = float64(lambda: np.asarray(jax.jit(
        lambda key: evaluate(port, agent._act, agent.params, key, EPISODES)[0])(jax.random.key(5))))()
    if "MinAtar/Breakout-v1" not in gym.registry:
        register_envs()
    env = gym.make("MinAtar/Breakout-v1", sticky_action_prob=0.0)
    assert env.action_space.n == port.n_actions == 3

    def gymnasium_step(action: int):
        observation, reward, terminated, truncated, _ = env.step(action)
        return observation, reward, terminated or truncated

    in_gymnasium = play(agent, gymnasium_step, lambda k: env.reset(seed=200 + k)[0], EPISODES)
    assert in_port.std() > 0
    assert stats.mannwhitneyu(in_port, in_gymnasium).pvalue > 1e-3
    assert abs(in_gymnasium.mean() - in_port.mean()) < 4 * np.hypot(in_gymnasium.std(), in_port.std()) / np.sqrt(
        EPISODES)


def test_every_method_trains_with_its_minatar_preset_when_asked():
    plan = plan_of(MinAtarOptions(seeds=3, games="seaquest", methods="all", budget="paper"))
    configs = plan.configs()
    assert sorted(configs) == sorted(f"{m}-seaquest" for m in DEEP_METHODS)
    dqn = configs["dqn-seaquest"].method_config()
    assert (dqn.buffer_size, dqn.batch_size, dqn.optimizer, dqn.total_steps) == (100_000, 32, "rmsprop", 5_000_000)
    assert configs["ppo-seaquest"].method_config().n_envs == 64
    assert {c.env for c in configs.values()} == {"MinAtar/Seaquest-v0"}


@pytest.mark.slow("trains and reports MinAtar studies")
def test_blocks_of_seeds_trained_as_tasks_equal_the_whole_trained_here(tmp_path, monkeypatch):
    import dataclasses

    from rlcompare.deep import pqn
    from rlcompare.experiment.backends import LocalBackend
    from rlcompare.studies.paired import reproduce
    from rlcompare.studies.seed_blocks import seed_blocks

    small = dataclasses.replace(pqn.PRESETS["default"]["MinAtar/Breakout-v0"], n_envs=4, n_steps=16, n_minibatches=2,
                                hidden=(32,))  # the tasks are threads of this process: they train the same preset
    monkeypatch.setitem(pqn.PRESETS["default"], "MinAtar/Breakout-v0", small)
    plan = plan_of(MinAtarOptions(seeds=2, games="breakout", steps=640, methods="pqn_q_lambda"))
    plan = dataclasses.replace(plan, vmap_width=1)  # two seeds: two blocks, each its own task
    assert [b.seeds for b in seed_blocks(plan.configs()["pqn_q_lambda-breakout"])] == [(0,), (1,)]
    whole = list(reproduce(tmp_path / "whole", "minatar", plan))
    tasks = list(reproduce(tmp_path / "tasks", "minatar", plan, backend=LocalBackend(2)))
    assert [(name, reused) for name, _, reused in tasks] == [("pqn_q_lambda-breakout", False)]
    assert tasks[0][1].meta["seeds"] == whole[0][1].meta["seeds"] == [0, 1]
    assert_same_runs(tmp_path / "tasks", tmp_path / "whole", ["pqn_q_lambda-breakout"])
    again = list(reproduce(tmp_path / "tasks", "minatar", plan, backend=LocalBackend(2)))
    assert [(name, reused) for name, _, reused in again] == [("pqn_q_lambda-breakout", True)]


@pytest.mark.slow("starting and stopping the cluster take about half a minute")
def test_the_study_on_a_ray_cluster_killed_and_resumed_equals_the_study_here(study, tmp_path):
    """The study's seed blocks as Ray tasks; its driver killed with SIGKILL once one run is written, then run
    again: the finished run is loaded, the other trained, and both equal the study trained here."""
    import subprocess
    import sys

    pytest.importorskip("ray")
    from ray_cluster import loopback_cluster

    here, _ = study
    out = tmp_path / "ray"
    with loopback_cluster() as (address, env, _, _):
        command = [sys.executable, "-m", "rlcompare.cli", *TINY, "--out", str(out), "--address", address,
                   "--no-videos"]
        kill_when(start(command, tmp_path / "killed.log", {**env, "COLUMNS": "200"}),
                  lambda: len(finished_runs(out)) >= 1, tmp_path / "killed.log")
        finished = finished_runs(out)
        done = subprocess.run(command, capture_output=True, text=True, env={**env, "COLUMNS": "200"}, timeout=500,
                              check=False)
    assert done.returncode == 0, done.stdout + done.stderr
    assert f"on Ray at {address}" in done.stdout
    assert len(finished) == 1
    assert done.stdout.count("loaded") == 1
    assert finished_runs(out) == finished_runs(here) == ["pqn_q_lambda-breakout", "pqn_sarsa_lambda-breakout"]
    assert_same_runs(out, here, finished_runs(here))


def _results_with_finals(method: str, env: str, finals: np.ndarray):
    from rlcompare.deep.config import DeepConfig
    from rlcompare.deep.results import DeepResults

    seeds = tuple(range(len(finals)))
    episodes = pd.DataFrame({"seed": seeds, "return": 0.0})
    evaluations = pd.DataFrame({"seed": seeds, "round": 0, "after_step": 100, "return": finals,
                                "length": 10, "terminated": True})
    return DeepResults(DeepConfig(algorithm=method, env=env, seeds=seeds), episodes, evaluations, {}, {})


def test_the_overall_verdict_pairs_each_seed_s_normalised_score_averaged_over_the_games():
    from rlcompare.studies.deep.minatar import MARGIN, MINATAR, OVERALL_MARGIN, by_game
    from rlcompare.studies.paired_report import across, answer, judged, verdict_table

    rng = np.random.default_rng(0)
    floors = {"MinAtar/Breakout-v0": 0.5, "MinAtar/Asterix-v0": 1.0}
    finals = {("pqn_sarsa_lambda", "MinAtar/Breakout-v0"): 10 + rng.normal(0, 0.5, 8),
              ("pqn_q_lambda", "MinAtar/Breakout-v0"): 6 + rng.normal(0, 0.5, 8),
              ("pqn_sarsa_lambda", "MinAtar/Asterix-v0"): 3 + rng.normal(0, 0.2, 8),
              ("pqn_q_lambda", "MinAtar/Asterix-v0"): 3 + rng.normal(0, 0.2, 8)}
    runs = {f"{m}-{e}": _results_with_finals(m, e, f) for (m, e), f in finals.items()}
    spread = across(runs, list(floors), floors, MINATAR.method_order, MINATAR.references)
    assert spread.envs == ["MinAtar/Breakout-v0", "MinAtar/Asterix-v0"]
    for method, values in spread.scores.items():  # the curves on the same scales: their last round is the final
        np.testing.assert_array_equal(spread.curves[method][..., -1], values)
    compared = judged(MINATAR, runs, {}, floors, spread)
    verdicts = verdict_table(MINATAR, compared)
    assert verdicts["game"].tolist() == ["Asterix", "Breakout", "overall (normalised)"]  # the games' order
    breakout_scale, asterix_scale = 10.0 - 0.5, 17.0 - 1.0  # random to the MinAtar paper's DQN at 5 M frames
    by_hand = np.mean([(finals[("pqn_sarsa_lambda", e)] - finals[("pqn_q_lambda", e)]) / scale
                       for e, scale in (("MinAtar/Breakout-v0", breakout_scale),
                                        ("MinAtar/Asterix-v0", asterix_scale))], axis=0).mean()
    assert verdicts["on - off (mean, 95% CI)"].iloc[2].startswith(f"{by_hand:.2f} [")
    assert by_hand > OVERALL_MARGIN
    p_values = verdicts["p (Holm)"].to_numpy()
    # every Breakout seed on one side: 2 / 2^8, the second smallest of the family's six p-values (three directions,
    # three equivalences; Asterix's equivalence within ±1 is the smallest), so Holm multiplies it by 5
    assert p_values[1] == pytest.approx(5 * 2 / 2**8)
    assert verdicts["verdict"].iloc[0] == f"equivalent (within ±{number(MARGIN * asterix_scale)})"  # ±1.6
    assert verdicts["p equivalent (Holm)"].iloc[0] < 0.05
    assert verdicts["verdict"].iloc[1].startswith("on-policy")
    assert verdicts["verdict"].iloc[2].startswith("on-policy")
    games, overall = answer(by_game(compared), 8)
    assert games.startswith("On-policy SARSA(λ) against off-policy Q(λ), final greedy return per episode, 8 paired "
                            "seeds: SARSA(λ) scores on Asterix ")
    assert "); on Breakout 4." in games
    assert games.endswith("; on-policy better).")
    assert overall.startswith(f"Over the games, in scores normalised between the random policy (0) and the best "
                              f"method here (1), SARSA(λ) scores {number(by_hand)} more (95% interval")
    assert answer(by_game(compared), 8, references={"Breakout": 10.0})[1].startswith(
        "Over the games, in scores normalised between the random policy (0) and the reference (1)")


def test_a_game_neither_method_learnt_has_no_verdict_and_stays_out_of_the_overall_row():
    from rlcompare.stats.compare import NEITHER_LEARNT
    from rlcompare.studies.deep.minatar import MARGIN, MINATAR, by_game
    from rlcompare.studies.paired_report import across, answer, judged, verdict_table

    rng = np.random.default_rng(1)
    floors = {"MinAtar/Breakout-v0": 0.5, "MinAtar/Asterix-v0": 0.5, "MinAtar/SpaceInvaders-v0": 3.0}
    finals = {("pqn_sarsa_lambda", "MinAtar/Breakout-v0"): 9 + rng.normal(0, 0.3, 8),
              ("pqn_q_lambda", "MinAtar/Breakout-v0"): 6 + rng.normal(0, 0.3, 8),
              ("pqn_sarsa_lambda", "MinAtar/Asterix-v0"): 0.8 + rng.normal(0, 0.1, 8),  # below 0.5 + 1.65
              ("pqn_q_lambda", "MinAtar/Asterix-v0"): 0.95 + rng.normal(0, 0.1, 8),
              ("pqn_sarsa_lambda", "MinAtar/SpaceInvaders-v0"): 40 + rng.normal(0, 2, 8),
              ("pqn_q_lambda", "MinAtar/SpaceInvaders-v0"): 3 + rng.normal(0, 0.3, 8)}  # random's: not learnt
    runs = {f"{m}-{e}": _results_with_finals(m, e, f) for (m, e), f in finals.items()}
    spread = across(runs, list(floors), floors, MINATAR.method_order, MINATAR.references)
    compared = judged(MINATAR, runs, {}, floors, spread)
    labels = {title: j.label for title, j in by_game(compared).items()}
    assert labels["Asterix"] == NEITHER_LEARNT
    assert labels["SpaceInvaders"] == "only on-policy learnt"
    assert "learnt" not in labels["Breakout"]  # both learnt: the comparison's own label (Holm over seven tests)
    # the overall row averages the two games learnt, not Asterix
    scales = {"MinAtar/Breakout-v0": 9.5, "MinAtar/SpaceInvaders-v0": 40.0}
    by_hand = np.mean([(finals[("pqn_sarsa_lambda", e)] - finals[("pqn_q_lambda", e)]) / scale
                       for e, scale in scales.items()], axis=0).mean()
    assert verdict_table(MINATAR, compared)["on - off (mean, 95% CI)"].iloc[-1].startswith(f"{by_hand:.2f} [")
    assert MINATAR.margin_of("MinAtar/SpaceInvaders-v0", 3.0) == pytest.approx(MARGIN * 40.0)
    games = answer(by_game(compared), 8, floors={"Asterix": 0.5}, references={"Asterix": 17.0})[0]
    assert "on Asterix neither has learnt at this budget (SARSA(λ) 0.8" in games
    assert "against the random policy's 0.5 and the reference's 17): no verdict" in games


# --- the same question on tables and on classic control, beside the study's own verdicts ---------------------

@pytest.fixture(scope="module")
def other_studies(tmp_path_factory):
    """The paper's tabular study and the deep study at a tiny size, each made by its own command (about 25 s)."""
    root = tmp_path_factory.mktemp("others")
    for arguments, name in ((["reproduce", "--allow-undecidable", "--seeds", "3", "--episodes", "30", "--no-videos"],
                             "paper"),
                            (["reproduce", "deep", "--allow-undecidable", "--seeds", "2", "--steps", "41000",
                              "--episodes", "50",
                              "--methods", "pqn_q_lambda,pqn_sarsa_lambda", "--envs", "CartPole-v1"], "deep")):
        result = invoke(*arguments, "--out", str(root / name), columns=None)
        assert result.exit_code == 0, result.output
    return root


def _copied(source, target):
    import shutil

    return shutil.copytree(source, target, ignore=shutil.ignore_patterns(".rlcompare.lock"))


def _verdicts(directory, name):
    return pd.read_csv(directory / "tables" / name, dtype=str, keep_default_na=False)


def _rows_of(table, study):
    return table[table["study"].str.startswith(study)]


@pytest.mark.slow("trains and reports MinAtar studies")
def test_the_report_sets_the_paper_and_deep_verdicts_beside_its_own(study, other_studies, tmp_path):
    from rlcompare.studies.deep import minatar as minatar_study
    from rlcompare.studies.deep.same_question import CAPTION

    out = _copied(study[0], tmp_path / "minatar")
    for name in ("paper", "deep"):
        _copied(other_studies / name, tmp_path / name)
    minatar_study.report(out, videos=False)
    table = pd.read_csv(out / "tables" / "minatar_same_question.csv", dtype=str, keep_default_na=False)
    assert table["study"].tolist()[0] == "minatar (this study)"  # its own rows first
    own, paper, deep = (_rows_of(table, s) for s in ("minatar", "paper", "deep"))
    assert own["verdict"].tolist() == _verdicts(out, "minatar_verdicts.csv")["verdict"].tolist() != []
    written = _verdicts(tmp_path / "paper", "verdicts.csv")
    assert len(written) == len(PAPER_CLAIMS)
    assert paper[["claim", "verdict"]].to_numpy().tolist() == written[["claim", "verdict"]].to_numpy().tolist()
    assert set(paper["environment"]) == {"MountainCar-v0"}
    written = _verdicts(tmp_path / "deep", "deep_verdicts.csv")
    assert len(written) == 3
    assert (deep[["environment", "metric", "estimate", "verdict"]].to_numpy().tolist()
            == written[["env", "metric", "on - off (mean, 95% CI)", "verdict"]].to_numpy().tolist())
    page = html.unescape((out / "report.html").read_text())
    assert page.index("Verdicts") < page.index(">The same question on tables and on classic control</h2>")
    assert CAPTION in page
    assert "corrects its own claims separately" in CAPTION
    paper_file = tmp_path / "paper" / "tables" / "verdicts.csv"
    assert (f"Beside this study: the paper study's {len(PAPER_CLAIMS)} verdicts ({paper_file}); "
            f"the deep study's 3 verdicts ({tmp_path / 'deep' / 'tables' / 'deep_verdicts.csv'}).") in page


@pytest.mark.slow("trains and reports MinAtar studies")
def test_without_the_other_studies_the_report_says_how_to_make_them(study):

    out, _ = study
    page = " ".join(html.unescape((out / "report.html").read_text()).split())
    parent = out.parent
    assert (f"Beside this study: the paper study is absent ('rlcompare reproduce --out {parent / 'paper'}' makes "
            f"it); the deep study is absent ('rlcompare reproduce deep --out {parent / 'deep'}' makes it).") in page
    table = pd.read_csv(out / "tables" / "minatar_same_question.csv")
    assert set(table["study"]) == {"minatar (this study)"}


def _no_marker(directory):
    (directory / ".rlcompare.json").unlink()


def _verdicts_unlisted(directory):
    import json

    marker = directory / ".rlcompare.json"
    data = json.loads(marker.read_text())
    data["outputs"].remove("tables/deep_verdicts.csv")
    marker.write_text(json.dumps(data))


TABLES = {"paper": "tables/verdicts.csv", "deep": "tables/deep_verdicts.csv"}


@pytest.mark.slow("trains and reports MinAtar studies")
@pytest.mark.parametrize(("name", "made_from", "change", "said"), [
    ("paper", "deep", None, "is not the paper study's (it holds the deep study): not read"),
    ("deep", "paper", None, "is not the deep study's (it holds the paper study): not read"),
    ("paper", "paper", _no_marker, "is not the paper study's (rlcompare wrote no marker there): not read"),
    ("deep", "deep", _verdicts_unlisted, "has no verdict table rlcompare wrote"),
])
def test_a_directory_that_is_not_the_study_s_is_not_read(other_studies, tmp_path, name, made_from, change, said):
    from rlcompare.studies.deep.same_question import COLUMNS, beside

    other = "deep" if name == "paper" else "paper"
    _copied(other_studies / other, tmp_path / other)
    directory = _copied(other_studies / made_from, tmp_path / name)
    # the study's own verdicts, well formed, where its reader looks: a reader that did not check would list them
    (directory / TABLES[name]).write_bytes((other_studies / name / TABLES[name]).read_bytes())
    if change is not None:
        change(directory)
    found = beside(tmp_path / "minatar", pd.DataFrame(columns=COLUMNS))
    assert _rows_of(found.table, name).empty
    assert len(_rows_of(found.table, other)) == len(pd.read_csv(other_studies / other / TABLES[other])) > 0
    assert said in found.sentence
    assert str(directory) in found.sentence
    assert found.malformed == []


@pytest.mark.slow("trains and reports MinAtar studies")
@pytest.mark.parametrize("content", [b"\x00\xff\xfe\"unterminated\n", b"env,engine\nCartPole-v1,network\n",
                                     b"env,engine,metric,\"on - off (mean, 95% CI)\",p (Holm),verdict\n"
                                     b"CartPole-v1,network,final greedy return,\"1.0 [0.0, 2.0]\",0.5,\n"],
                         ids=["not a table", "columns missing", "a row without a verdict"])
def test_a_malformed_verdict_file_is_one_line_naming_it_not_a_crash(other_studies, tmp_path, content):
    from rlcompare.studies.deep.same_question import COLUMNS, beside

    for name in ("paper", "deep"):
        _copied(other_studies / name, tmp_path / name)
    path = tmp_path / "deep" / "tables" / "deep_verdicts.csv"
    path.write_bytes(content)
    found = beside(tmp_path / "minatar", pd.DataFrame(columns=COLUMNS))
    assert _rows_of(found.table, "deep").empty
    assert len(_rows_of(found.table, "paper")) == len(PAPER_CLAIMS)
    assert len(found.malformed) == 1
    assert found.malformed[0].startswith(f"{path}: malformed (")
    assert "the deep study's verdict file could not be read" in found.sentence


@pytest.mark.slow("trains and reports MinAtar studies")
def test_an_empty_verdict_table_is_read_as_no_rows(other_studies, tmp_path):
    """A deep study run without the pair writes a table with no rows: read as none, not as malformed."""
    from rlcompare.studies.deep.same_question import COLUMNS, beside

    _copied(other_studies / "deep", tmp_path / "deep")
    (tmp_path / "deep" / "tables" / "deep_verdicts.csv").write_text(pd.DataFrame([]).to_csv(index=False))
    found = beside(tmp_path / "minatar", pd.DataFrame(columns=COLUMNS))
    assert found.table.empty
    assert found.malformed == []
    assert f"the deep study's 0 verdicts ({tmp_path / 'deep' / 'tables' / 'deep_verdicts.csv'})" in found.sentence


@pytest.mark.slow("trains and reports MinAtar studies")
def test_the_other_studies_can_be_named_where_they_are(other_studies, tmp_path):
    from rlcompare.studies.deep import minatar as minatar_study
    from rlcompare.studies.deep.same_question import COLUMNS, beside

    found = beside(tmp_path / "minatar", pd.DataFrame(columns=COLUMNS),
                   {"paper": other_studies / "paper", "deep": str(other_studies / "deep")})
    assert (len(_rows_of(found.table, "paper")), len(_rows_of(found.table, "deep"))) == (len(PAPER_CLAIMS), 3)
    alone = beside(tmp_path / "minatar", pd.DataFrame(columns=COLUMNS), {"deep": other_studies / "deep"})
    assert (len(_rows_of(alone.table, "paper")), len(_rows_of(alone.table, "deep"))) == (0, 3)
    with pytest.raises(ValueError, match="beside: got 'cartpole'; allowed: paper, deep"):
        minatar_study.report(tmp_path / "minatar", beside={"cartpole": other_studies / "paper"})
