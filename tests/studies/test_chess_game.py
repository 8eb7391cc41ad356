"""The chess study through the CLI at a tiny size: its runs, the ladder's games kept beside them, the report with its
ratings, boards and records, resuming, and bad input."""

from __future__ import annotations

import dataclasses
import json
import shutil

import numpy as np
import pandas as pd
import pytest

pytest.importorskip("jax")
pytest.importorskip("pgx")

from helpers import assert_loaded_not_trained, invoke, study_fixture

from rlcompare.deep import pqn
from rlcompare.studies.chess import game_plan
from rlcompare.studies.chess import ladder as chess_ladder
from rlcompare.studies.chess.game import LADDER, load_ladder
from rlcompare.studies.chess.ladder import distinct_games
from rlcompare.studies.paired import load_runs

TINY = ["reproduce", "chess", "--allow-undecidable", "--seeds", "2", "--steps", "1280", "--pairs", "2"]
SMALL = dataclasses.replace(pqn.PRESETS["default"]["gardner_chess"], n_envs=8, n_steps=16, n_epochs=1,
                            n_minibatches=2, hidden=(32,))
"""Gardner's preset with a small network and batch, and 8 evaluation games a round, for the whole module: its runs are
loaded with them too (the study runs in this process; the preset's own size is the bench's and docs/chess-game.md's)."""


@pytest.fixture(scope="module", autouse=True)
def small_preset():
    with pytest.MonkeyPatch.context() as patch:
        patch.setitem(pqn.PRESETS["default"], "gardner_chess", SMALL)
        patch.setattr(game_plan, "EVAL_EPISODES", 8)
        yield


study = study_fixture("chess", *TINY)


@pytest.mark.slow("trains, rates and reports a chess study")
def test_the_study_writes_its_runs_the_ladder_and_a_report(study):
    out, output = study
    assert {"pqn_q_lambda-gardner_chess", "pqn_sarsa_lambda-gardner_chess", LADDER} <= {
        p.name for p in out.iterdir() if p.is_dir()}
    games = pd.read_parquet(out / LADDER / "gardner_chess" / "games.parquet")
    # random v material, then each of 2 methods x 2 seeds against random, material, and the other method (once)
    pairings = 1 + 2 * 2 * 2 + 2
    assert len(games) == pairings * 2 * 2
    assert set(games["score"]) <= {0.0, 0.5, 1.0}
    swapped = games.iloc[0:2]
    assert (swapped["white"].tolist(), swapped["black"].tolist()) == (["random", "material"], ["material", "random"])
    # each pair of games from its own opening, both colours; every pairing plays the same suite
    assert games["opening"].tolist() == [0, 0, 1, 1] * pairings
    assert (games["plies"] > chess_ladder.OPENING_PLIES).all()
    # two greedy networks play one game from one position: every duel's game differs from the others
    duels = games[(games["white_seed"] >= 0) & (games["black_seed"] >= 0)]
    assert len(duels) == 2 * 2 * 2
    assert distinct_games(duels) == len(duels)
    assert duels.groupby(["white", "white_seed"])["game"].nunique().tolist() == [2, 2, 2, 2]
    ladder = pd.read_csv(out / "tables" / "chess_ladder_gardner_chess.csv")
    assert set(ladder["player"]) == {"random", "material", "Q(λ)", "SARSA(λ)"}
    assert ladder.loc[ladder["player"] == "random", "rating (Elo)"].item() == "0 [0, 0]"  # the anchor, always
    learner = ladder[ladder["player"] == "Q(λ)"].iloc[0]
    assert learner["games"] == 12 * 2
    assert learner["distinct games"] == distinct_games(
        games[(games["white"] == "Q(λ)") | (games["black"] == "Q(λ)")])
    assert learner["per seed"].startswith("#0 ")
    assert ", #1 " in learner["per seed"]
    assert "95% intervals over seeds then games" in " ".join(output.split())
    assert "The ladder, strongest first" in " ".join(output.split())
    assert "With 2 seeds the learning gate cannot pass" in " ".join(output.split())
    page = (out / "report.html").read_text()
    assert "ladder-gardner_chess.png" in page
    records = sorted(p.name for p in (out / "games").iterdir())
    assert len(records) == 2 * 3  # each method's first seed at three stages
    first = (out / "games" / records[0]).read_text().splitlines()
    assert first[first.index("") + 1] == "rnbqk/ppppp/5/PPPPP/RNBQK w - - 0 1"  # Gardner's start, then each position


@pytest.mark.slow("trains, rates and reports a chess study")
def test_a_finished_study_is_loaded_and_its_ladder_kept(study):
    out, _ = study
    assert_loaded_not_trained(out, *TINY, "--no-videos", runs=2, kept=f"{LADDER}/gardner_chess/games.parquet")


@pytest.mark.slow("trains, rates and reports a chess study")
def test_a_ladder_of_other_runs_is_refused_naming_it(study, tmp_path):
    out, _ = study
    runs, _, _ = load_runs(out)
    marker = out / LADDER / "gardner_chess" / "ladder.json"
    saved = marker.read_text()
    try:
        data = json.loads(saved)
        data["runs"] = {name: "2020-01-01T00:00:00+00:00" for name in data["runs"]}
        marker.write_text(json.dumps(data))
        with pytest.raises(OSError, match=r"ladder\.json: the ladder was played from other runs"):
            load_ladder(out, "gardner_chess", runs)
    finally:
        marker.write_text(saved)


@pytest.mark.slow("trains, rates and reports a chess study")
@pytest.mark.parametrize("damage", ["rewritten", "truncated", "run removed"])
def test_a_study_whose_own_files_changed_or_whose_run_is_gone_is_reported_as_such(study, tmp_path, damage):
    """The ladder's games rewritten as a valid file in which Q(λ) wins every game, or cut short; or a run directory
    removed: the report names it, exits 2, and shows no ladder rated from what is there."""
    out = tmp_path / "study"
    shutil.copytree(study[0], out)
    games_file = out / LADDER / "gardner_chess" / "games.parquet"
    if damage == "rewritten":
        games = pd.read_parquet(games_file)
        games["score"] = np.where(games["white"] == "Q(λ)", 1.0, np.where(games["black"] == "Q(λ)", 0.0,
                                                                          games["score"]))
        games.to_parquet(games_file, index=False)
    elif damage == "truncated":
        games_file.write_bytes(games_file.read_bytes()[:100])
    else:
        shutil.rmtree(out / "pqn_q_lambda-gardner_chess")
    result = invoke("report", str(out), "--no-videos", columns=300)
    said = " ".join(result.output.split())
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    assert "The ladder, strongest first" not in said
    if damage == "run removed":
        assert "pqn_q_lambda-gardner_chess: the study trained this run (members.json)" in said
    else:
        assert "games.parquet: does not belong to this study" in said
        again = invoke(*TINY, "--no-videos", "--out", str(out), columns=300)  # the same command plays it again
        assert again.exit_code == 0, again.output
        assert "The ladder, strongest first" in " ".join(again.output.split())
        pd.testing.assert_frame_equal(pd.read_parquet(games_file), pd.read_parquet(
            study[0] / LADDER / "gardner_chess" / "games.parquet"))


@pytest.mark.parametrize(("arguments", "named"), [
    (["--game", "shogi"], "--game"),
    (["--budget", "tpu"], "--budget"),
    (["--methods", "dqn"], "--methods"),
])
def test_bad_options_are_one_line_naming_the_option(arguments, named, tmp_path):
    result = invoke("reproduce", "chess", "--allow-undecidable", *arguments, "--out", str(tmp_path / "out"),
                    columns=None)
    assert result.exit_code == 2
    assert named in result.output
    assert "Traceback" not in result.output
    assert not (tmp_path / "out").exists()


@pytest.mark.slow("trains, rates and reports a chess study")
def test_uci_refuses_a_network_of_gardners_game_in_one_line(study):
    out, _ = study
    result = invoke("uci", str(out / "pqn_q_lambda-gardner_chess"), columns=300)
    assert result.exit_code != 0
    said = " ".join(result.output.split())
    assert "holds a run of gardner_chess; allowed: a run of a network trained at chess" in said
    assert "Traceback" not in result.output


@pytest.mark.slow("imports the deep engine in the command")
def test_a_missing_stockfish_is_one_line_saying_how_to_install_it(tmp_path, monkeypatch):
    from rlcompare.players import stockfish

    monkeypatch.setattr(stockfish, "STOCKFISH_DIRS", ())
    monkeypatch.setenv("PATH", str(tmp_path))
    result = invoke("reproduce", "chess", "--allow-undecidable", "--game", "chess", "--out", str(tmp_path / "out"),
                    columns=300)
    assert result.exit_code != 0
    assert "apt-get install stockfish" in " ".join(result.output.split())
    assert "Traceback" not in result.output
    assert not any((tmp_path / "out").glob("pqn_*"))  # refused before anything trained


@pytest.mark.slow("compiles pgx's Gardner game")
def test_the_opening_suite_is_seeded_and_each_opening_a_different_position():
    from rlcompare.deep.chess.games import chess_game_env

    game = chess_game_env("gardner_chess")
    suite = chess_ladder.openings(game, 32)
    assert suite.moves.shape == (32, chess_ladder.OPENING_PLIES)
    seen = np.asarray(suite.states.observation)  # pgx's planes: the position and its history
    assert len({position.tobytes() for position in seen}) == 32
    assert not np.asarray(suite.states.terminated).any()
    assert np.array_equal(chess_ladder.openings(game, 32).moves, suite.moves)  # seeded
    paired = np.asarray(suite.paired().observation)
    assert np.array_equal(paired[::2], seen)
    assert np.array_equal(paired[1::2], seen)


def test_openings_leave_out_repeated_positions_and_ended_games_and_too_few_are_refused(monkeypatch):
    """The suite's selection on drawn candidates made by hand: 6 candidates, positions a, b, a, c, d, b, the one at d
    ended by its plies: a, b, c are kept in the order drawn, and 4 openings are refused naming what was found."""
    positions = np.array([[0], [1], [0], [2], [3], [1]])
    drawn = ({"id": np.arange(6)}, np.arange(6)[:, None] * np.ones((1, 4), int), np.array([0, 0, 0, 0, 1, 0], bool),
             positions)
    monkeypatch.setattr(chess_ladder, "opening_candidates", lambda game, candidates, plies: lambda key: drawn)
    suite = chess_ladder.openings(None, 3)
    assert suite.states["id"].tolist() == [0, 1, 3]
    assert suite.moves[:, 0].tolist() == [0, 1, 3]
    with pytest.raises(ValueError, match="only 3 distinct positions after 4 random plies among 256 drawn; 4 pairs"):
        chess_ladder.openings(None, 4)


def test_the_ratings_are_anchored_at_the_random_player_always():
    from rlcompare.studies.chess.game import ANCHOR

    assert ANCHOR == ("random", 0.0)
