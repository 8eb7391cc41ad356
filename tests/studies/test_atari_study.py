"""The Atari study through the CLI at a tiny size (a small network in Breakout's PQN preset): its run directories,
human-normalised tables and report, its agents loaded by load_agent playing Gymnasium's ALE/Breakout-v5, resuming,
and bad input."""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest

jax = pytest.importorskip("jax")
pytest.importorskip("ale_py")
pytest.importorskip("cv2")  # Gymnasium's AtariPreprocessing

from helpers import assert_loaded_not_trained, invoke, study_run  # noqa: E402

from rlcompare import load_agent  # noqa: E402
from rlcompare.deep import pqn  # noqa: E402
from rlcompare.deep.agent import DeepAgent  # noqa: E402
from rlcompare.envs.atari import games as atari  # noqa: E402
from rlcompare.envs.atari import scores as atari_scores  # noqa: E402
from rlcompare.experiment.engines import load_run  # noqa: E402
from rlcompare.studies.atari import plan as atari_plan  # noqa: E402
from rlcompare.studies.atari import play as atari_play  # noqa: E402
from rlcompare.studies.atari import random_policy  # noqa: E402
from rlcompare.studies.atari import study as atari_study  # noqa: E402
from rlcompare.studies.paired import final_returns  # noqa: E402

pytestmark = pytest.mark.slow("trains and reports an Atari study")
TINY = ["reproduce", "atari", "--allow-undecidable", "--seeds", "2"]
SMALL = dataclasses.replace(pqn.PRESETS["default"]["Breakout-Atari"], n_envs=4, n_steps=16, n_minibatches=2,
                            hidden=(32,))
"""Breakout's preset with a small network and batch, for the whole module: its runs are loaded with it too."""
RUNS = ["pqn_q_lambda-Breakout", "pqn_sarsa_lambda-Breakout"]


@pytest.fixture(scope="module", autouse=True)
def small_preset():
    with pytest.MonkeyPatch.context() as patch:
        patch.setitem(pqn.PRESETS["default"], "Breakout-Atari", SMALL)
        patch.setattr(atari_play, "STAGE_STEPS", 40)
        patch.setattr(random_policy, "EPISODES", 4)
        patch.setitem(atari_plan.BUDGETS, "smoke", atari_plan.Budget("breakout", 256, 1, 2, "seconds"))
        yield


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    out, output = study_run(tmp_path_factory.mktemp("atari"), *TINY, columns=300)
    return out, " ".join(output.split())


def test_the_study_writes_its_runs_and_a_human_normalised_report(study):
    out, output = study
    assert sorted(p.name for p in out.iterdir() if p.is_dir()) == ["figures", *RUNS, "tables", "videos"]
    summary = pd.read_csv(out / "tables" / "atari_summary.csv")
    assert summary["game"].tolist() == ["Breakout"] * 2
    breakout = atari_scores.GAMES["Breakout"]
    assert (summary["random"] == breakout.random).all()
    assert (summary["human"] == breakout.human).all()
    shown = summary.set_index("method")["human-normalised, mean"]
    for name, method in zip(RUNS, ("Q(λ), network", "SARSA(λ), network"), strict=True):
        finals = final_returns(load_run(out / name))
        normalised = (finals - 1.7) / (30.5 - 1.7)  # Mnih et al.'s Breakout: random 1.7, human 30.5
        assert shown[method].startswith(f"{normalised.mean():.3f} [")
        results = load_run(out / name)
        finished = results.episodes.groupby("seed").size().reindex(list(results.seeds), fill_value=0)
        machado = summary.set_index("method")["last 100 training episodes, mean"][method]
        assert summary.set_index("method")["training episodes, fewest a seed"][method] == finished.min()
        if finished.min() == 0:  # 32,768 steps over 128 game copies: no copy finished a game while training
            assert pd.isna(machado)  # 'n/a' in the table
        else:
            by_seed = results.episodes.groupby("seed")["return"].apply(lambda r: r.to_numpy()[-100:].mean())
            assert machado.startswith(f"{by_seed.mean():.1f}")
    verdicts = pd.read_csv(out / "tables" / "atari_verdicts.csv")
    assert verdicts["game"].tolist() == ["Breakout"]
    assert "final return at ε = 0.05 per episode" in output
    page = (out / "report.html").read_text()
    assert page.index(">The answer</h2>") < page.index("paired-differences.png")
    assert "Needs a method run on all five Atari-5 games" in page
    assert "Breakout-Atari: greedy return against frames (4 an agent step)" in page
    assert sorted(p.name for p in (out / "videos").iterdir()) == sorted(
        f"{run}.{kind}" for run in RUNS for kind in ("gif", "mp4"))


def test_the_agents_loaded_by_load_agent_play_gymnasiums_game(study):
    out, _ = study
    played = pd.read_csv(out / "tables" / "atari_gymnasium.csv")
    assert len(played) == 6
    assert set(played["stage"]) == {"early", "middle", "final"}
    assert (played["steps"] <= 40).all()
    assert (played["steps"] > 0).all()
    agent = load_agent(out / "pqn_q_lambda-Breakout", seed=1)
    assert isinstance(agent, DeepAgent)
    env = atari.gymnasium_env("Breakout-Atari")
    try:
        observation, _ = env.reset(seed=3)
        for _ in range(30):
            observation, *_ = env.step(int(np.random.default_rng(0).integers(18)))
        action = agent.act(observation)
        # the network's greedy action on the stack as the engine lays it out (frames last)
        q = agent._act(agent.params, np.moveaxis(observation, 0, -1)[None].astype(np.float32))
        assert action == int(q[0])
        assert 0 <= action < 18
    finally:
        env.close()
    again = atari_play.play_stages(out / "pqn_q_lambda-Breakout", load_run(out / "pqn_q_lambda-Breakout"), 0, 40)
    np.testing.assert_array_equal(again.returns[:, -1], played[(played["method"].str.startswith("Q"))
                                                               & (played["seed"] == 0)]["return"].to_numpy())


def test_the_curves_count_frames_four_to_an_agent_step(study):
    from rlcompare.studies.paired import eval_curves
    from rlcompare.studies.paired_report import curves_figure

    out, _ = study
    runs = {name: load_run(out / name) for name in RUNS}
    steps, _ = eval_curves(runs[RUNS[0]])
    axes = curves_figure(runs, "Breakout-Atari", "frames", 4).axes[0]
    assert axes.get_xlabel() == "frames"
    np.testing.assert_array_equal(axes.lines[0].get_xdata(), 4 * steps)


def _gymnasium_breakout(**make):
    """``ALE/Breakout-v5`` as a user of Gymnasium makes it, here on its minimal action set (Gymnasium's default),
    with the preprocessing of :func:`atari.gymnasium_env`."""
    import gymnasium as gym

    env = gym.make("ALE/Breakout-v5", frameskip=1, **make)
    env = gym.wrappers.AtariPreprocessing(env, noop_max=0, frame_skip=4, terminal_on_life_loss=False)
    return gym.wrappers.FrameStackObservation(env, 4, padding_type="zero")


def test_an_agent_given_gymnasiums_minimal_action_set_plays_the_best_of_its_actions(study):
    """Breakout's minimal set is no-op, fire, right, left: ALE's 0, 1, 3, 4. The agent's action is the index in
    that set of the best of the network's Q-values among those four (ties: the first), never an action the set
    lacks; its ε-greedy draws are uniform over the four."""
    from rlcompare.deep.agent import action_values

    out, _ = study
    run_dir = out / "pqn_q_lambda-Breakout"
    env = _gymnasium_breakout()
    try:
        agent = load_agent(run_dir, seed=1, env=env)
        assert agent.actions == (0, 1, 3, 4)
        q_values = action_values(load_run(run_dir))
        observation, _ = env.reset(seed=3)
        for step in range(40):
            q = np.asarray(q_values(agent.params, np.moveaxis(observation, 0, -1)[None].astype(np.float32)))[0]
            action = agent.act(observation)
            assert action == int(np.argmax(q[[0, 1, 3, 4]]))
            observation, *_ = env.step(action if step % 2 else 1)  # FIRE every other step: the game goes on
        crafted = np.zeros((1, 18), np.float32)
        crafted[0, [17, 3, 4]] = [9.0, 2.0, 2.0]  # the network's best (17) is not in the set; 3 and 4 tie
        agent._scores = lambda params, observations: crafted
        assert agent.act(observation) == 2  # ALE's 3, right: the first of the best of the set
        explorer = load_agent(run_dir, seed=1, epsilon=1.0, exploration_seed=0, env=env)
        assert set(explorer.act(observation) for _ in range(200)) == {0, 1, 2, 3}
        full = load_agent(run_dir, seed=1, env=atari.gymnasium_env("Breakout-Atari"))
        assert full.actions is None
    finally:
        env.close()


def test_an_environment_an_agent_cannot_read_is_one_line_naming_what_it_needs(study):
    import gymnasium as gym

    from rlcompare.validation import ConfigError

    out, _ = study
    env = gym.make("ALE/Breakout-v5")  # Gymnasium's default: 210 x 160 colour frames, 4 frames a step
    try:
        needs = r"env.*\(210, 160, 3\).*\(4, 84, 84\).*gymnasium_env\('Breakout-Atari'\)"
        with pytest.raises(ConfigError, match=needs):
            load_agent(out / "pqn_q_lambda-Breakout", seed=1, env=env)
    finally:
        env.close()
    cartpole = gym.make("CartPole-v1")
    with pytest.raises(ConfigError, match="ALE/<Game>-v5"):
        load_agent(out / "pqn_q_lambda-Breakout", seed=1, env=gym.wrappers.TransformObservation(
            cartpole, lambda o: np.zeros((4, 84, 84), np.uint8),
            gym.spaces.Box(0, 255, (4, 84, 84), np.uint8)))


def test_the_random_policy_is_measured_under_the_protocol_once_and_read_back_after(study, monkeypatch):
    """Breakout's 4 random episodes, played in the study's emulator, stand in its table beside the published random
    score and the margin; a report made again reads them back instead of playing them, and a table changed by hand
    is played again, not read."""
    out, _ = study
    episodes = pd.read_csv(out / random_policy.TABLE)
    assert episodes["game"].tolist() == ["Breakout"] * 4
    returns = episodes["return"].to_numpy()
    assert (returns >= 0).all()  # Breakout's points: never lost,
    assert (returns == np.round(returns)).all()  # and whole
    table = pd.read_csv(out / "tables" / "atari_random.csv").iloc[0]
    assert table["random here, mean"].startswith(f"{returns.mean():.1f} [")
    assert table["one episode's sd"] == round(float(np.std(returns, ddof=1)), 2)
    assert table["margin"] == round(0.1 * (30.5 - 1.7), 2)  # a tenth of Mnih et al.'s random-to-human range
    assert table["published random"] == 1.7

    def played(*_):
        raise AssertionError("played again")

    monkeypatch.setattr(random_policy, "random_returns", played)
    assert random_policy.random_episodes(out, ["Breakout"], 4).equals(episodes)
    table_file = out / random_policy.TABLE
    table_file.write_text(table_file.read_text().replace("Breakout,0,", "Breakout,0,9", 1))
    with pytest.raises(AssertionError, match="played again"):
        random_policy.random_episodes(out, ["Breakout"], 4)


def test_a_finished_study_is_loaded_not_trained_again(study):
    out, _ = study
    assert_loaded_not_trained(out, *TINY, "--no-videos", runs=2)


@pytest.mark.parametrize(("arguments", "named"), [
    (["--games", "Breakout,Tetris"], "--games"),
    (["--games", "atari6"], "--games"),
    (["--budget", "1m"], "--budget"),
    (["--methods", "pqn_q_lambda,a2c"], "--methods"),
    (["--budget", "100k", "--methods", "dqn"], "--steps"),  # learning_starts 100,000: not one gradient step
])
def test_bad_input_is_one_message_naming_the_option(tmp_path, arguments, named):
    result = invoke(*TINY, *arguments, "--out", str(tmp_path / "x"), columns=300)
    assert result.exit_code == 2
    assert named in result.output
    assert "Traceback" not in result.output
    assert not (tmp_path / "x").exists()


def test_a_missing_rom_is_one_message_naming_the_game(tmp_path, monkeypatch):
    from ale_py import roms

    monkeypatch.setattr(roms, "get_rom_path", lambda rom: None if rom == "pong" else "here")
    result = invoke(*TINY, "--games", "breakout-pong", "--out", str(tmp_path / "x"), columns=300)
    assert result.exit_code == 2
    assert "'Pong'" in result.output
    assert "ROM" in result.output
    assert "--games" in result.output
    assert not (tmp_path / "x").exists()


def test_an_atari_game_given_to_the_tabular_engine_is_one_message(tmp_path):
    result = invoke("run", "--env", "Breakout-Atari", "--algorithm", "q_learning", "--seeds", "1", "--episodes", "2",
                    "--out", str(tmp_path / "x"), columns=300)
    assert result.exit_code == 2
    assert "deep engine" in result.output
    assert "Traceback" not in result.output
    assert not (tmp_path / "x").exists()


def test_the_atari5_table_estimates_each_seeds_median_from_its_five_games():
    from types import SimpleNamespace

    rng = np.random.default_rng(2)
    finals = {t: g.random + rng.uniform(-0.2, 1.5, size=3) * (g.human - g.random) for t, g in atari_scores.GAMES.items()
              if t in atari_scores.ATARI_5}

    def run(method: str, game: str):
        evaluations = pd.DataFrame({"seed": np.repeat([0, 1, 2], 2), "round": [0, 1] * 3,
                                    "after_step": [10, 20] * 3, "return": np.ravel([[0.0, f] for f in finals[game]])})
        return SimpleNamespace(config=SimpleNamespace(algorithm=method, env=f"{game}-Atari"), seeds=(0, 1, 2),
                               evaluations=evaluations)

    runs = {f"{m}-{g}": run(m, g) for m in ("pqn_q_lambda", "pqn_sarsa_lambda") for g in atari_scores.ATARI_5}
    del runs["pqn_sarsa_lambda-Qbert"]  # SARSA(λ) missed a game: no estimate for it
    table = atari_study.atari5_table(runs)
    normalised = {t: atari_scores.human_normalised(t, f) for t, f in finals.items()}
    of_the_means = atari_scores.atari5_median({t: float(np.mean(v)) for t, v in normalised.items()})
    mean_of_each_seeds = float(np.mean(atari_scores.atari5_median(normalised)))
    assert round(of_the_means, 3) != round(mean_of_each_seeds, 3)  # the author's order, not the other
    assert table["method"].tolist() == ["Q(λ), network"]
    assert table.iloc[0, 1].startswith(f"{of_the_means:.3f} [")
    assert atari_study.atari5_table({k: v for k, v in runs.items() if "Qbert" not in k}) is None


def test_machados_measure_is_each_seeds_mean_of_its_last_hundred_training_episodes():
    """Seed 0 finished 150 episodes returning 0, 1, ..., 149: its last 100 average 99.5; seed 1 finished 30 of
    return 1: all of them, 1.0; seed 2 none: NaN."""
    from types import SimpleNamespace

    episodes = pd.DataFrame({"seed": [0] * 150 + [1] * 30, "return": [*map(float, range(150)), *[1.0] * 30]})
    results = SimpleNamespace(seeds=(0, 1, 2), episodes=episodes)
    found = atari_study.last_training_episodes(results)
    np.testing.assert_array_equal(found[:2], [99.5, 1.0])
    assert np.isnan(found[2])


def test_the_overall_row_is_each_seeds_interquartile_mean_which_one_games_scale_cannot_own():
    """Five games both methods play alike (human-normalised 1.0, noise 0.01), but on DoubleDunk, whose random-to-human
    range is 2.2 points, SARSA(λ) scores 8 human ranges more on every seed. The mean over the games calls SARSA(λ)
    better by 1.6; each seed's interquartile mean (the middle three of its five games) sees no difference."""
    from rlcompare.deep.config import DeepConfig
    from rlcompare.deep.results import DeepResults
    from rlcompare.studies.paired_plan import OVERALL
    from rlcompare.studies.paired_report import across, judged, verdict_table

    rng = np.random.default_rng(5)
    seeds = tuple(range(10))  # every seed one way: 2 / 2^10, below Holm's 0.05 / 12 for the first of twelve tests
    normalised = {(method, title): 1.0 + rng.normal(0, 0.01, len(seeds))
                  for method in ("pqn_sarsa_lambda", "pqn_q_lambda") for title in atari_scores.ATARI_5}
    normalised["pqn_sarsa_lambda", "DoubleDunk"] += 8.0

    def results(method: str, title: str) -> DeepResults:
        game = atari_scores.GAMES[title]
        finals = game.random + normalised[method, title] * (game.human - game.random)
        evaluations = pd.DataFrame({"seed": seeds, "round": 0, "after_step": 100, "return": finals, "length": 10,
                                    "terminated": True})
        config = DeepConfig(algorithm=method, env=f"{title}-Atari", seeds=seeds, vmap_width=1)
        return DeepResults(config, pd.DataFrame({"seed": seeds, "return": 0.0}), evaluations, {}, {})

    runs = {f"{m}-{t}": results(m, t) for m, t in normalised}
    envs = [f"{t}-Atari" for t in atari_scores.ATARI_5]
    floors = {f"{t}-Atari": atari_scores.GAMES[t].random for t in atari_scores.ATARI_5}
    spread = across(runs, envs, floors, atari_study.ATARI.method_order, atari_study.ATARI.references)

    def overall(study) -> pd.Series:
        table = verdict_table(study, judged(study, runs, {}, floors, spread))
        return table[table["game"] == OVERALL].iloc[0]

    on, off = (np.stack([normalised[m, t] for t in atari_scores.ATARI_5]) for m in ("pqn_sarsa_lambda", "pqn_q_lambda"))
    middle_three = (np.sort(on, axis=0)[1:4].mean(axis=0) - np.sort(off, axis=0)[1:4].mean(axis=0)).mean()
    robust = overall(atari_study.ATARI)
    assert robust["on - off (mean, 95% CI)"].startswith(f"{middle_three:.2f} [")
    assert abs(middle_three) < 0.01
    assert not robust["verdict"].startswith("on-policy")
    by_mean = overall(dataclasses.replace(atari_study.ATARI, overall_statistic="mean"))
    assert by_mean["on - off (mean, 95% CI)"].startswith(f"{(on - off).mean():.2f} [")  # 1.60
    assert by_mean["verdict"].startswith("on-policy")
