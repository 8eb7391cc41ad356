"""The retrograde solution of KRK and KQK: the longest mates of the literature, Bellman's equations on every position,
optimal lines played out in python-chess, a brute-force search near mate, and the tablebase's Gaviota conventions."""

from __future__ import annotations

import chess
import chess.gaviota
import numpy as np
import pytest

from rlcompare.compiled import njit
from rlcompare.envs.chess import rules
from rlcompare.envs.chess.endgames import ENDGAMES, QUEEN, ROOK
from rlcompare.envs.chess.rules import N_POSITIONS
from rlcompare.envs.chess.solver import Tablebase, solve

LONGEST_MATE = {ROOK: 16, QUEEN: 10}
"""Moves to mate from the worst white-to-move position (Ströhlein 1970; Thompson 1986)."""


@njit(cache=True)
def _bellman_violations(piece: int, white: np.ndarray, black: np.ndarray) -> np.ndarray:
    """The positions whose depths break the equations of best play: white to move, ``1 + min`` over white's
    moves of the black depths that are won (-1 without one); black to move, 0 when checkmated, -1 when stalemated or
    able to capture the piece, else ``1 + max`` over its replies where every reply is won (-1 otherwise); -1 for
    an illegal position."""
    wrong = np.zeros(N_POSITIONS, dtype=np.bool_)
    replies = np.zeros(8, dtype=np.int64)
    for index in range(N_POSITIONS):
        expected = -1
        if rules.is_legal(piece, index, True):
            for action in range(rules.n_actions(piece)):
                after = rules.white_after(piece, index, action)
                if after >= 0 and black[after] >= 0 and (expected < 0 or black[after] + 1 < expected):
                    expected = black[after] + 1
        wrong[index] |= white[index] != expected
        expected = -1
        if rules.is_legal(piece, index, False):
            count = rules.black_replies(piece, index, replies)
            white_king, white_piece, _ = rules.decode(index)
            if count == 0:
                expected = 0 if rules.black_in_check(piece, index) else -1
            for i in range(count):
                after = rules.encode(white_king, white_piece, replies[i])
                if replies[i] == white_piece or white[after] < 0:
                    expected = -1
                    break
                expected = max(expected, white[after] + 1)
        wrong[index] |= black[index] != expected
    return np.flatnonzero(wrong)


@pytest.mark.parametrize("endgame", list(ENDGAMES))
def test_longest_mates_and_counts(endgame):
    """The longest mate with white to move is 16 moves (31 half-moves) in KRK, 10 (19) in KQK; black to move, one
    half-move more. Every legal white-to-move position is won; white's depths are odd, black's even; the illegal
    positions are -1."""
    piece = ENDGAMES[endgame].piece
    solution = solve(piece)
    assert solution is solve(piece)  # cached
    assert solution.white.dtype == solution.black.dtype == np.int16
    assert solution.white.shape == solution.black.shape == (N_POSITIONS,)
    assert solution.white.max() == 2 * LONGEST_MATE[piece] - 1
    assert solution.black.max() == 2 * LONGEST_MATE[piece]
    legal_white = rules.legal_moves_mask(piece).any(axis=1)
    np.testing.assert_array_equal(solution.white >= 0, legal_white)
    assert np.all(solution.white[legal_white] % 2 == 1)
    won_black = solution.black >= 0
    assert np.all(solution.black[won_black] % 2 == 0)
    assert 0 < won_black.sum() < N_POSITIONS
    assert np.array_equal(np.unique(solution.white[legal_white]), np.arange(1, solution.white.max() + 1, 2))
    assert np.array_equal(np.unique(solution.black[won_black]), np.arange(0, solution.black.max() + 1, 2))


@pytest.mark.parametrize("endgame", list(ENDGAMES))
def test_solution_satisfies_bellman_equations(endgame):
    """Every position's depth is what its moves' depths make it (the equations have one solution, so this proves
    the analysis, given the rules)."""
    piece = ENDGAMES[endgame].piece
    solution = solve(piece)
    wrong = _bellman_violations(piece, solution.white, solution.black)
    assert wrong.size == 0, f"{wrong.size} positions, the first {wrong[:5]}"


def _sample(piece: int, white_to_move: bool, count: int, seed: int, most: int = 99) -> list[int]:
    """``count`` random positions won for white with this side to move, at most ``most`` half-moves from mate."""
    solution = solve(piece)
    depths = solution.white if white_to_move else solution.black
    candidates = np.flatnonzero((depths >= 0) & (depths <= most))
    return [int(i) for i in np.random.default_rng(seed).choice(candidates, size=count, replace=False)]


@pytest.mark.slow("plays 400 optimal lines out in python-chess")
@pytest.mark.parametrize("endgame", list(ENDGAMES))
def test_optimal_lines_mate_in_the_probed_depth(endgame):
    """From 200 won positions, half with each side to move, the tablebase's best play in python-chess mates in
    exactly the probed number of half-moves: white moves to a position probed ``-(d - 1)``, black picks any reply
    probed longest, and no reply of black's is better than ``d - 1``."""
    piece = ENDGAMES[endgame].piece
    tablebase = Tablebase()
    starts = [(i, True) for i in _sample(piece, True, 100, seed=1)] + [(i, False) for i in _sample(piece, False, 100,
                                                                                                    seed=2)]
    for index, white_to_move in starts:
        board = rules.board_of(piece, index, white_to_move)
        dtm = abs(tablebase.probe_dtm(board))
        assert tablebase.probe_wdl(board) == (1 if white_to_move else -1)
        for played in range(dtm):
            assert not board.is_game_over(), board.fen()
            left = dtm - played
            probes = {move: _probe_after(tablebase, board, move) for move in board.legal_moves}
            if board.turn == chess.WHITE:  # black then loses (WDL -1) in -DTM half-moves; the fastest is left - 1
                move = min((m for m in probes if probes[m][0] == -1), key=lambda m: -probes[m][1])
                assert -probes[move][1] == left - 1, board.fen()
            else:  # white then wins (WDL 1) after every reply, the longest in left - 1
                assert all(wdl == 1 for wdl, _ in probes.values()), board.fen()
                move = max(probes, key=lambda m: probes[m][1])
                assert probes[move][1] == left - 1, board.fen()
            board.push(move)
        assert board.is_checkmate(), board.fen()


def _probe_after(tablebase: Tablebase, board: chess.Board, move: chess.Move) -> tuple[int, int]:
    """``(WDL, DTM)`` after ``move``, for the side then to move (a capture of the piece leaves a draw)."""
    board.push(move)
    try:
        return tablebase.probe_wdl(board), tablebase.probe_dtm(board)
    finally:
        board.pop()


def _white_mates(board: chess.Board, plies: int) -> bool:
    """White to move mates within ``plies`` half-moves (odd), by python-chess's moves alone."""
    for move in board.legal_moves:
        if plies == 1 and not board.gives_check(move):
            continue
        board.push(move)
        mated = _black_mated(board, plies - 1)
        board.pop()
        if mated:
            return True
    return False


def _black_mated(board: chess.Board, plies: int) -> bool:
    """Black to move is mated within ``plies`` half-moves (even), whatever it plays."""
    if board.is_checkmate():
        return True
    moves = list(board.legal_moves)
    if plies == 0 or not moves:
        return False
    for move in moves:
        if board.is_capture(move):
            return False
        board.push(move)
        mated = _white_mates(board, plies - 1)
        board.pop()
        if not mated:
            return False
    return True


@pytest.mark.slow("searches a few hundred positions three half-moves deep in python-chess")
@pytest.mark.parametrize("endgame", list(ENDGAMES))
def test_agrees_with_brute_force_near_mate(endgame):
    """Minimax over python-chess's moves finds a mate within 1 or 3 half-moves (white to move) or 0 or 2 (black to
    move) exactly where the solution says, on 100 positions near mate and 100 anywhere for each side, and 50
    drawn ones with black to move."""
    piece = ENDGAMES[endgame].piece
    solution = solve(piece)
    for white_to_move, limits, depths in ((True, (1, 3), solution.white), (False, (0, 2), solution.black)):
        starts = _sample(piece, white_to_move, 100, seed=3, most=limits[-1] + 2) + _sample(piece, white_to_move,
                                                                                           100, seed=4)
        if not white_to_move:
            drawn = (int(i) for i in np.random.default_rng(5).permutation(np.flatnonzero(depths < 0)))
            starts += [i for i in drawn if rules.is_legal(piece, i, False)][:50]
        for index in starts:
            board = rules.board_of(piece, index, white_to_move)
            search = _white_mates if white_to_move else _black_mated
            found = next((plies for plies in limits if search(board, plies)), None)
            expected = int(depths[index]) if 0 <= depths[index] <= limits[-1] else None
            assert found == expected, board.fen()


@pytest.mark.parametrize(
    ("fen", "dtm", "wdl"),
    [
        ("k7/8/1K6/8/8/8/8/7R w - - 0 1", 1, 1),  # Rh8# (or Ra1#)
        ("k7/8/1K6/8/8/8/7R/8 b - - 0 1", -2, -1),  # Kb8, Rh8#
        ("k7/8/1K6/8/8/8/7R/8 w - - 0 1", 1, 1),  # Rh8#
        ("R6k/8/6K1/8/8/8/8/8 b - - 0 1", 0, -1),  # checkmated: DTM 0, yet a loss
        ("k7/8/K7/8/8/8/8/1R6 b - - 0 1", 0, 0),  # stalemate
        ("k7/2Q5/1K6/8/8/8/8/8 b - - 0 1", 0, 0),  # stalemate
        ("k7/1R6/8/8/8/8/8/7K b - - 0 1", 0, 0),  # Kxb7, two bare kings
        ("k7/1Q6/8/8/8/8/8/7K b - - 0 1", 0, 0),  # Kxb7
        ("8/8/8/8/8/8/8/K2kr3 w - - 0 1", -10, -1),  # python-chess's own example, colours reversed: black mates
        ("4k3/8/8/8/8/8/8/4K3 w - - 0 1", 0, 0),  # K v K
        ("4k3/8/8/8/8/8/8/4K3 b - - 0 1", 0, 0),
    ],
)
def test_tablebase_conventions(fen, dtm, wdl):
    """python-chess's Gaviota signs on hand-checked positions: half-moves, positive where the side to move mates,
    0 for draws and for a checkmated position (whose WDL is -1)."""
    board = chess.Board(fen)
    tablebase = Tablebase()
    assert tablebase.probe_dtm(board) == tablebase.get_dtm(board) == dtm
    assert tablebase.probe_wdl(board) == tablebase.get_wdl(board) == wdl
    assert tablebase.probe_dtm(board.mirror()) == dtm  # either colour has the piece
    assert board.fen() == fen  # probing leaves the board as it was


def test_tablebase_refuses_other_boards():
    """Another material raises ``MissingTableError`` (a ``KeyError``); castling rights and illegal positions raise
    ``KeyError``; ``get_dtm`` and ``get_wdl`` give the default instead."""
    with Tablebase() as tablebase:
        for fen in ("4k3/8/8/8/8/8/8/2B1K3 w - - 0 1", "4k3/8/8/8/8/8/4r3/R3K3 w - - 0 1",
                    "4k3/8/8/8/8/8/4P3/4K3 w - - 0 1", "4k3/8/8/8/8/8/8/R3K2R w - - 0 1"):
            board = chess.Board(fen)
            with pytest.raises(chess.gaviota.MissingTableError, match="no table available for: K"):
                tablebase.probe_dtm(board)
            with pytest.raises(chess.gaviota.MissingTableError):
                tablebase.probe_wdl(board)
            assert tablebase.get_dtm(board) is None
            assert tablebase.get_wdl(board, 7) == 7
        for fen in ("4k3/8/8/8/8/8/8/4K2R w K - 0 1", "4k3/8/8/8/4Q3/8/8/4K3 w - - 0 1",
                    "8/8/8/8/8/3k4/3K4/7R b - - 0 1", "rnbqkbnr/8/8/8/8/8/8/4K3 w - - 0 1"):
            board = chess.Board(fen)
            with pytest.raises(KeyError):
                tablebase.probe_dtm(board)
            assert tablebase.get_dtm(board, -99) == -99


def test_retrograde_dtypes_and_cache():
    """The solution's arrays are read-only int16 (shared by every caller of the cache); only ROOK and QUEEN are
    solved."""
    solution = solve(QUEEN)
    assert not solution.white.flags.writeable
    assert not solution.black.flags.writeable
    with pytest.raises(ValueError, match="neither ROOK"):
        solve(2)
