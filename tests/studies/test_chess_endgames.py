"""The chess endgames as environments and as a study: every step equals python-chess's game, the defender plays as
the solver says, no episode ends better by losing the piece, the board's symmetries keep the game, a learnt agent
plays python-chess boards, and the study answers from a fresh directory, resumes, and refuses bad input."""

from __future__ import annotations

import shutil
from pathlib import Path

import chess
import numpy as np
import pytest
from helpers import invoke

from rlcompare.envs.chess import endgame as chess_endgame
from rlcompare.envs.chess import rules as chess_rules
from rlcompare.envs.chess.endgames import ENDGAMES, MOVE_LIMIT, REWARDS, parse
from rlcompare.envs.chess.solver import Tablebase, solve
from rlcompare.rng import stream_state
from rlcompare.tabular.config import ExperimentConfig
from rlcompare.validation import ConfigError


@pytest.mark.slow("builds the endgame's tables (a second or two per endgame)")
@pytest.mark.parametrize("endgame", list(ENDGAMES))
@pytest.mark.parametrize("defender", ["optimal", "random"])
def test_every_step_is_python_chess_s_move_and_a_reply_the_defender_may_play(endgame: str, defender: str) -> None:
    name = f"{endgame}:defender={defender},symmetries=off"
    tables = chess_endgame.make_endgame(parse(name))
    piece, positions = ENDGAMES[endgame].piece, tables.positions
    tablebase, rng, moves = Tablebase(), stream_state(7), chess_endgame.legal_moves(tables)
    for state in np.random.default_rng(3).choice(len(positions), 300, replace=False):
        board = chess_rules.board_of(piece, int(positions[state]), True)
        legal = np.flatnonzero(moves[state])
        assert {chess_rules.move_of(piece, int(positions[state]), int(a)) for a in legal} == set(board.legal_moves)
        action = int(legal[len(legal) // 2])
        board.push(chess_rules.move_of(piece, int(positions[state]), action))
        replies = list(board.legal_moves)
        next_state, reward, terminated = chess_endgame.step(tables, int(state), action, rng)
        if board.is_checkmate():
            assert (reward, terminated) == (tables.mate, True)
            continue
        if board.is_stalemate():
            assert (reward, terminated) == (tables.failure, True)
            continue
        depths = {move: _depth_after(tablebase, board, move) for move in replies}
        chosen = [move for move in replies if _reached(board, move, piece, positions, next_state, terminated)]
        assert len(chosen) == 1
        if defender == "optimal":  # a capture draws (inf); else the longest mate
            assert depths[chosen[0]] == max(depths.values())
        assert terminated == (chosen[0].to_square == board.pieces(chess_rules.PIECE_TYPES[piece], chess.WHITE).pop())
        assert reward == (tables.failure if terminated else tables.move)


def _depth_after(tablebase: Tablebase, board: chess.Board, move: chess.Move) -> float:
    board = board.copy()
    board.push(move)
    return float("inf") if board.is_insufficient_material() else tablebase.probe_dtm(board)


def _reached(board: chess.Board, move: chess.Move, piece: int, positions: np.ndarray, state: int, ended: bool
             ) -> bool:
    after = board.copy()
    after.push(move)
    if after.is_insufficient_material():
        return ended
    return not ended and chess_rules.index_of(after)[1] == positions[state]


@pytest.mark.slow("builds the endgame's tables")
@pytest.mark.parametrize("endgame", list(ENDGAMES))
def test_the_solver_s_moves_mate_in_the_optimum_against_the_optimal_defender(endgame: str) -> None:
    tables = chess_endgame.make_endgame(parse(endgame))
    solution = solve(ENDGAMES[endgame].piece)
    rng = stream_state(11)
    for start in np.random.default_rng(5).choice(tables.starts, 100, replace=False):
        state, moves = int(tables.state_of[start]), 0
        optimum = (int(solution.white[start]) + 1) // 2
        while True:
            after = np.array([chess_rules.white_after(tables.piece, int(tables.positions[state]), action)
                              for action in range(chess_rules.n_actions(tables.piece))])
            depth = np.where(after >= 0, solution.black[np.maximum(after, 0)], 10**4)
            state, reward, terminated = chess_endgame.step(tables, state, int(np.argmin(np.where(depth < 0, 10**4,
                                                                                                 depth))), rng)
            moves += 1
            if terminated:
                break
        assert (reward, moves) == (tables.mate, optimum)


def test_the_symmetries_give_every_image_of_a_position_one_state() -> None:
    tables = chess_endgame.make_endgame(parse("KRK"))
    legal = np.flatnonzero(tables.state_of >= 0)[::997]
    images = chess_endgame.symmetric_images(legal)
    assert (tables.state_of[images] == tables.state_of[legal]).all()
    assert len(np.unique(tables.state_of[tables.state_of >= 0])) < len(tables.starts) / 7.5  # about an eighth


@pytest.mark.slow("makes an endgame's tables")
@pytest.mark.parametrize("endgame", list(ENDGAMES))
def test_an_endgame_is_checked_without_its_tables_whose_sizes_its_facts_give(endgame: str) -> None:
    """A configuration's checks and a plan read an endgame's sizes from its facts, the tables made where first read
    (a second of solving): the facts' counts of states, with and without the symmetries, and of actions are the
    tables'."""
    facts = ENDGAMES[endgame]
    for symmetries in (True, False):
        assert chess_endgame.states(facts.piece, symmetries)[1].size + 1 == facts.n_states(symmetries)
    assert facts.n_actions == chess_rules.n_actions(facts.piece)
    made = chess_endgame.make_endgame.cache_info().misses
    config = ExperimentConfig(env=f"{endgame}:starts=hard,symmetries=off,rewards=moves", algorithm="sarsa")
    env = config.environment
    assert chess_endgame.make_endgame.cache_info().misses == made  # checked, and nothing made
    assert (env.n_states, env.n_actions) == (facts.n_states(False), facts.n_actions)
    assert env.legal_moves.shape == (env.dynamics.n_states, facts.n_actions) == (env.n_states, env.n_actions)
    assert chess_endgame.make_endgame.cache_info().misses == made + 1
    assert env.dynamics is chess_endgame.make_endgame(parse(env.name))


@pytest.mark.parametrize("rewards", list(REWARDS))
def test_no_episode_ends_better_by_losing_the_piece(rewards: str) -> None:
    from rlcompare.studies.measures import solved
    from rlcompare.tabular.train import train

    config = ExperimentConfig(env=f"KRK:defender=random,rewards={rewards}", algorithm="random", episodes=400,
                              seeds=(0,), eval_every=0, stages=(("final", 1.0),))
    records = train(config).records
    returns, won = records.returns[0], solved(config.environment.success, records.returns, records.lengths,
                                              records.terminated, MOVE_LIMIT)[0]
    failed = records.terminated[0] & ~won
    assert failed.sum() > 50
    assert (~failed).sum() > 5
    assert returns[failed].max() < returns[~failed & won].min(initial=np.inf)
    assert returns[failed].max() <= returns[~records.terminated[0]].min(initial=np.inf)
    move, mate, failure = REWARDS[rewards]
    assert failure < mate
    assert (failure < -MOVE_LIMIT * abs(move) or (move == 0 and failure == 0 < mate))


def test_a_bad_endgame_name_is_one_message_naming_the_field() -> None:
    for name, allowed in (("KBK", "KRK, KQK"), ("KRK:defender=smart", "optimal, random or mixed-P"),
                          ("KRK:starts=easy", "won, hard or a FEN"), ("KRK:colour=black", "KEY defender"),
                          ("KRK:starts=hard,starts=won", "each once")):  # once trained with the last value
        with pytest.raises(ConfigError, match=allowed) as caught:
            ExperimentConfig(env=name)
        assert "env" in str(caught.value).split(":")[0]
    with pytest.raises(ConfigError, match="value method"):
        ExperimentConfig(env="KRK", algorithm="reinforce")
    for fen, reason in (("8/8/8/3k4/8/8/8/KQ6 w - - 0 1", "not KRK"), ("8/8/8/3k4/8/8/8/K2R4 w - - 0 1", "legal KRK"),
                        ("8/8/8/3k4/8/8/8/KR6 b - - 0 1", "White to move"), ("8/8/x w - - 0 1", "FEN")):
        with pytest.raises(ConfigError, match=reason):
            ExperimentConfig(env=f"KRK:starts={fen}")


def test_a_fen_start_is_where_every_episode_starts(tmp_path: Path) -> None:
    fen = "8/8/8/3k4/8/8/8/KR6 w - - 0 1"
    config = ExperimentConfig(env=f"KRK:starts={fen}", episodes=5, seeds=(0,), eval_every=0)
    tables = config.environment.dynamics
    assert tables.starts.tolist() == [chess_rules.index_of(chess.Board(fen))[1]]
    result = invoke("run", "--env", "KRK:starts=8/8/8/3k4/8/8/8/KQ6 w - - 0 1", "--out", str(tmp_path / "x"))
    assert result.exit_code == 2, result.output
    assert "env" in result.output
    assert "not KRK" in result.output
    assert not (tmp_path / "x").exists()


@pytest.mark.slow("trains and reports a small study, twice")
def test_the_study_answers_resumes_and_its_agent_plays_python_chess_boards(tmp_path: Path) -> None:
    import rlcompare

    out = tmp_path / "chess"
    args = ["reproduce", "chess-endgames", "--allow-undecidable", "--seeds", "3", "--episodes", "400", "--endgames",
            "KQK",
            "--defenders", "random", "--no-videos", "--out", str(out)]
    first = invoke(*args)
    assert first.exit_code == 0, first.output
    assert "On-policy or off-policy in chess endgames?" in first.output
    verdicts = (out / "tables" / "verdicts.csv").read_text()
    assert verdicts.count("\n") == 1 + 2 * 5  # two schedules x five measures
    again = invoke(*args)
    assert again.exit_code == 0
    assert again.output.count("loaded (already complete)") == 6  # four configurations and the order ablation
    assert (out / "tables" / "verdicts.csv").read_text() == verdicts
    shutil.rmtree(out / "KQK-random-sarsa-constant")  # a study with a run gone is not reported as whole
    missing = invoke("report", str(out), "--no-videos", columns=300)
    assert missing.exit_code == 2, missing.output
    assert "KQK-random-sarsa-constant: the study trained this run (members.json)" in " ".join(missing.output.split())
    assert "Traceback" not in missing.output
    agent = rlcompare.load_agent(out / "KQK-random-q_learning-decay", seed=1)
    board = chess.Board("8/8/8/3k4/8/8/8/KQ6 w - - 0 1")
    assert agent.move(board) in board.legal_moves
    with pytest.raises(ValueError, match="not KQK"):
        agent.move(chess.Board("8/8/8/3k4/8/8/8/KR6 w - - 0 1"))
    with pytest.raises(ValueError, match="only KRvK and KQvK"):
        agent.move(chess.Board())


def test_bad_study_options_are_refused_before_anything_is_written(tmp_path: Path) -> None:
    for option, value, allowed in (("--endgames", "KBK", "KRK, KQK"), ("--defenders", "smart", "optimal, random"),
                                   ("--algorithms", "reinforce", "q_learning")):
        result = invoke("reproduce", "chess-endgames", "--allow-undecidable", option, value, "--out",
                        str(tmp_path / "x"))
        assert result.exit_code == 2, result.output
        assert allowed in result.output
        assert "Traceback" not in result.output
        assert not (tmp_path / "x").exists()


@pytest.mark.slow("compiles the plain kernel and the engine's loop")
def test_the_benchmark_s_plain_kernel_learns_what_the_engine_learns() -> None:
    from rlcompare.bench.chess import plain_seconds
    from rlcompare.bench.harness import bench_config
    from rlcompare.tabular.train import train

    config = bench_config("q_learning", 3, 400, env="KRK:defender=random")
    moves, _, returns = plain_seconds(config)
    engine = train(config).records
    assert moves == engine.lengths.sum()
    np.testing.assert_array_equal(returns, engine.returns)
    assert 0 < returns.mean() < 1  # some games mated (+1), some not


def test_the_answer_says_when_the_seeds_are_too_few_for_the_family() -> None:
    import pandas as pd

    from rlcompare.studies.chess.endgames_report import answer

    frame = pd.DataFrame({"measure": ["mate rate", "excess moves"] * 10, "better": ["not resolved"] * 20})
    assert "this design cannot decide; with 11 seeds it can" in answer(frame, 10)  # 2 / 2^10 > 0.05 / 40
    assert "cannot decide" not in answer(frame, 11)  # 2 / 2^11 < 0.05 / 40
    assert "not resolved in 10" in answer(frame, 30)


def test_a_chunk_is_longer_where_a_run_s_table_outgrows_the_cache() -> None:
    from rlcompare.tabular.train import CHUNK_EPISODES, chunk_episodes

    assert chunk_episodes(20 * 20 * 3 * 8) == CHUNK_EPISODES  # the paper's table
    assert chunk_episodes(21_960 * 36 * 8) == 7 * CHUNK_EPISODES  # KRK's: 6.3 MB
    assert chunk_episodes(0) == CHUNK_EPISODES
