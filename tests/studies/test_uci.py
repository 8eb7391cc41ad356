"""``rlcompare uci RUN_DIR``: a network trained at chess served as a UCI engine, played by python-chess's own engine
client through whole games against Stockfish; ``load_agent`` of such a run plays on python-chess boards; bad input is
one line."""

from __future__ import annotations

import shutil
import sys

import chess
import chess.engine
import pytest

pytest.importorskip("jax")
pytest.importorskip("pgx")

from helpers import invoke

from rlcompare import load_agent
from rlcompare.players.stockfish import SKILL_0, MissingEngine, StockfishPlayer, find_stockfish
from rlcompare.players.uci import centipawns


def stockfish_or_skip() -> str:
    try:
        return find_stockfish()
    except MissingEngine as error:
        pytest.skip(str(error))


@pytest.fixture(scope="module")
def chess_run(tmp_path_factory):
    """A network trained at chess for one short rollout (its play is nearly random; the protocol is what is
    tested)."""
    from rlcompare.deep.config import DeepConfig
    from rlcompare.experiment.runner import run as deep_run

    out = tmp_path_factory.mktemp("uci") / "run"
    deep_run(DeepConfig(algorithm="pqn_q_lambda", env="chess", seeds=(0,), vmap_width=1, eval_rounds=1,
                        eval_episodes=2, hyperparameters={"total_steps": 256, "n_envs": 16, "n_steps": 16,
                                                          "n_epochs": 1, "n_minibatches": 1}), out=out)
    return out


def warm_the_compilation_cache(run) -> None:
    """What any earlier start of ``rlcompare uci`` on this machine leaves: the engine's programs in JAX's persistent
    cache (a first start compiles them, 8-10 s on a busy two-core machine, near python-chess's 10 s). The command
    runs in this process (its programs are the same, and so are their keys in the cache), sparing a start of JAX."""
    result = invoke("uci", str(run), input="isready\nquit\n", columns=300)
    assert result.exit_code == 0, result.output
    assert result.output.splitlines()[-1] == "readyok"


@pytest.mark.slow("trains a network at chess and plays whole games through python-chess's UCI client")
def test_python_chess_plays_a_whole_game_against_stockfish_through_rlcompare_uci(chess_run):
    """python-chess's client with its default timeouts (10 s for uciok; 10 s plus the move's time for each play,
    the first of which waits for readyok): uci answered at once, the network ready well within the limit, the first
    go movetime 100 answered at once, and engine.analyse given a score and a principal variation."""
    import time

    stockfish_or_skip()
    warm_the_compilation_cache(chess_run)
    command = [sys.executable, "-m", "rlcompare.cli", "uci", str(chess_run)]
    started = time.perf_counter()
    engine = chess.engine.SimpleEngine.popen_uci(command)
    uci_seconds = time.perf_counter() - started
    opponent = StockfishPlayer(SKILL_0)
    try:
        started = time.perf_counter()
        engine.ping()  # isready: the network loaded and compiled
        ready_seconds = time.perf_counter() - started
        board = chess.Board()
        started = time.perf_counter()
        first = engine.play(board, chess.engine.Limit(time=0.1)).move
        first_seconds = time.perf_counter() - started
        print(f"uci answered {uci_seconds:.3f} s after start; readyok after {ready_seconds:.2f} s; first go movetime"
              f" 100 answered in {first_seconds:.3f} s")
        assert uci_seconds < 2.0
        assert first_seconds < 1.0
        assert engine.id["name"].startswith("rlcompare pqn_q_lambda-chess")
        assert first in board.legal_moves
        analysis = engine.analyse(board, chess.engine.Limit(time=0.1))
        move, value = load_agent(chess_run).evaluate(board)
        assert analysis["pv"] == [move] == [first]
        assert analysis["depth"] == 1
        assert analysis["score"].relative == chess.engine.Cp(centipawns(value))
        while board.outcome(claim_draw=True) is None and board.ply() < 200:
            if board.turn == chess.WHITE:
                move = engine.play(board, chess.engine.Limit(time=0.1)).move
                assert move in board.legal_moves
            else:
                move = opponent.move(board)
            board.push(move)
        assert board.ply() >= 2
        assert board.outcome(claim_draw=True) is not None or board.ply() == 200
    finally:  # Stockfish closed even where the engine's quit fails: its client's thread would hold pytest's exit
        try:
            engine.quit()
        finally:
            opponent.close()


@pytest.mark.slow("trains a network at chess")
def test_load_agent_of_a_chess_run_moves_on_python_chess_boards(chess_run):
    agent = load_agent(chess_run)
    board = chess.Board("r1bqkbnr/pppp1ppp/2n5/4p3/4P3/5N2/PPPP1PPP/RNBQKB1R w KQkq - 2 3")
    for _ in range(2):  # White's move, then Black's, each from the side to move
        move = agent.move(board)
        assert move in board.legal_moves
        board.push(move)


ENDED_BY_PGX = {
    "fifty moves, not claimed": ("8/8/8/4k3/8/8/R7/4K3 w - - 100 80", ""),
    "a threefold repetition, not claimed": (chess.STARTING_FEN, "g1f3 g8f6 f3g1 f6g8 g1f3 g8f6 f3g1 f6g8 g1f3"),
    "pgx's 512-ply cap": (chess.STARTING_FEN, "512 random plies"),
}
"""Positions where pgx has ended the game by its own count and python-chess's rules go on: the agent once masked
with pgx's all-True mask and answered ``bestmove 0000`` or an illegal move, or raised at ply 513."""


def long_game() -> str:
    """512 plies of a seeded random game in which neither pgx's fifty-move count nor a threefold repetition comes
    (seed 50 is the first such of :class:`RandomPlayer`): pgx ends it at its 512-ply cap, python-chess goes on."""
    from rlcompare.players.basic import RandomPlayer

    board, player = chess.Board(), RandomPlayer(50)
    while board.ply() < 512:
        board.push(player.move(board))
    return " ".join(move.uci() for move in board.move_stack)


def ended_by_pgx(case: str) -> tuple[str, str, chess.Board]:
    """The FEN, the moves and the board of ``case``."""
    fen, moves = ENDED_BY_PGX[case]
    moves = long_game() if moves == "512 random plies" else moves
    board = chess.Board(fen)
    for move in moves.split():
        board.push_uci(move)
    return fen, moves, board


@pytest.mark.slow("trains a network at chess")
@pytest.mark.parametrize("case", list(ENDED_BY_PGX))
def test_the_network_moves_by_the_rules_where_pgx_has_ended_the_game(chess_run, case):
    from rlcompare.deep.chess.board import state_of

    fen, moves, board = ended_by_pgx(case)
    assert not board.is_game_over(claim_draw=False)
    assert bool(state_of(board).terminated)  # pgx's own replay has ended it, and its mask is all True
    assert bool(state_of(board).legal_action_mask.all())
    agent = load_agent(chess_run)
    move = agent.move(board)
    assert move in board.legal_moves
    for _ in range(6):  # and on, each ply from the board the last one left
        board.push(agent.move(board))
    assert len(board.move_stack) == len(moves.split()) + 6
    command = f"position fen {fen}" + (f" moves {moves}" if moves else "")
    result = invoke("uci", str(chess_run), input=f"{command}\ngo\nquit\n", columns=300)
    assert result.exit_code == 0, result.output
    best = [line for line in result.output.splitlines() if line.startswith("bestmove")]
    assert len(best) == 1
    assert chess.Move.from_uci(best[0].split()[1]) in ended_by_pgx(case)[2].legal_moves


AFTER_FIVEFOLD = "g1f3 g8f6 f3g1 f6g8 " * 4 + "e2e4"
"""The knights out and back four times (the start's fifth occurrence: python-chess's automatic fivefold end), then a
move a GUI may still send: the position after it is not over, but pgx's replay cannot pass the end."""


@pytest.mark.slow("trains a network at chess")
def test_the_network_moves_after_a_game_went_past_an_automatic_end(chess_run):
    from rlcompare.deep.chess.board import state_of

    board = chess.Board()
    for move in AFTER_FIVEFOLD.split():
        assert not board.is_game_over(claim_draw=False) or len(board.move_stack) == 16
        board.push_uci(move)
    assert not board.is_game_over(claim_draw=False)
    with pytest.raises(ValueError, match="the game has ended before the move e2e4"):
        state_of(board, rules_decide=True)
    assert load_agent(chess_run).move(board) in board.legal_moves
    result = invoke("uci", str(chess_run), input=f"position startpos moves {AFTER_FIVEFOLD}\ngo\nquit\n",
                    columns=300)
    assert result.exit_code == 0, result.output
    assert "info string" not in result.output
    assert chess.Move.from_uci(result.output.splitlines()[-1].split()[1]) in board.legal_moves


def tabular_run(run_dir, env: str):
    """A tabular run directory of ``env`` as ``rlcompare run`` leaves it, as far as ``uci`` reads one: its
    ``config.json`` (the configuration's own, written by the one writer of run directories) and ``meta.json``;
    ``uci`` refuses a run from its configuration alone, before anything is loaded or compiled."""
    from rlcompare.experiment import rundir
    from rlcompare.tabular.config import ExperimentConfig

    config = ExperimentConfig(env=env, episodes=5, seeds=(0,))
    return rundir.write_run(run_dir, config.to_dict(), {}, {})


@pytest.mark.slow("trains a network at chess")
def test_uci_refuses_a_run_that_is_not_chess_in_one_line(tmp_path, chess_run):
    result = invoke("uci", str(tmp_path / "missing"), columns=300)
    assert result.exit_code == 2
    assert "is not a directory" in result.output
    assert "Traceback" not in result.output
    shutil.copytree(chess_run, tmp_path / "copy")
    result = invoke("uci", str(tmp_path / "copy"), "--stage", "late", columns=300)
    assert result.exit_code == 2
    assert "late" in result.output
    assert "Traceback" not in result.output
    result = invoke("uci", str(tmp_path / "copy"), "--seed", "5", columns=300)  # once named --stage
    assert result.exit_code == 2
    assert "'--seed'" in result.output
    assert "got 5; allowed: one of the run's seeds" in result.output
    mountain_car = tabular_run(tmp_path / "mountain_car", "MountainCar-v0")
    result = invoke("uci", str(mountain_car), columns=300)  # once an AttributeError
    assert result.exit_code == 2
    assert "holds a run of MountainCar-v0; allowed: a run of a network trained at chess" in result.output
    assert "Traceback" not in result.output
    endgame = tabular_run(tmp_path / "krk", "KRK:defender=random")
    result = invoke("uci", str(endgame), columns=300)  # once 'ChessAgent' object has no attribute 'name'
    assert result.exit_code == 2
    assert "a table learnt in the KRK endgame, which plays White's moves in that endgame only" in result.output
    assert "Traceback" not in result.output


@pytest.mark.slow("trains a network at chess")
def test_a_game_drawn_by_an_automatic_rule_is_answered_with_a_legal_move_as_stockfish_answers(chess_run):
    """K v K with the halfmove clock at 200 (drawn twice over: dead position, 75 moves): once an internal ValueError
    as the info line. Stockfish answers such a position with a move, and so does the engine: any legal one."""
    fen = "8/8/8/4k3/8/8/8/4K3 w - - 200 150"
    result = invoke("uci", str(chess_run), input=f"position fen {fen}\ngo\nquit\n", columns=300)
    assert result.exit_code == 0, result.output
    assert "Error" not in result.output
    assert result.output.splitlines()[-1].split()[0] == "bestmove"
    assert chess.Move.from_uci(result.output.splitlines()[-1].split()[1]) in chess.Board(fen).legal_moves


@pytest.mark.slow("trains a network at chess and plays it against Stockfish")
def test_the_ladder_plays_stockfish_in_pairs_and_rates_from_its_anchor(chess_run):
    """Each network against both rungs in colour-swapped pairs from one opening, the rungs tied to the rest by the
    random and material players' games and each other's; the ratings anchored at random = 0, the rungs measured."""
    from rlcompare.experiment.engines import load_run
    from rlcompare.stats.seeded_ratings import seeded_ratings, seeded_scores
    from rlcompare.studies.chess.game import ANCHOR, ladder_table
    from rlcompare.studies.chess.ladder import OPENING_PLIES, Learner, games_of, stockfish_games

    stockfish_or_skip()
    results = load_run(chess_run)
    games, records = stockfish_games(results.config.environment, [Learner("Q(λ)", results)], pairs=1)
    assert len(games) == len(records) == 2 * (1 + 2 + 2)
    assert games.iloc[0:2][["white", "black"]].values.tolist() == [
        ["stockfish-skill0-depth1", "stockfish-limit1350-nodes5000"],
        ["stockfish-limit1350-nodes5000", "stockfish-skill0-depth1"]]
    assert set(games["opening"]) == {0}
    assert all(record.game.headers["FEN"] == records[0].game.headers["FEN"] for record in records)
    assert (games["plies"] == [OPENING_PLIES + record.plies for record in records]).all()
    network = games[(games["white"] == "Q(λ)") | (games["black"] == "Q(λ)")]
    assert len(network) == 4
    assert set(network["white_seed"].where(network["white"] == "Q(λ)", network["black_seed"])) == {0}
    assert all(record.game.headers["Result"] in ("1-0", "0-1", "1/2-1/2") for record in records)
    table = ladder_table(games, seeded_ratings(games_of(games), *ANCHOR, seed=0),
                         seeded_scores(games_of(games), "random", seed=0))
    assert table.loc[table["player"] == "random", "rating (Elo)"].item() == "0 [0, 0]"
    assert table["player"].iloc[0].startswith("stockfish")  # strongest first
