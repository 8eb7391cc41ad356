"""KRK and KQK's compiled rules against python-chess: every position of both endgames with either side to move,
legality, the legal moves, checkmate, stalemate and the capture of the lone piece; and the conversions."""

from __future__ import annotations

import functools

import chess
import numpy as np
import pytest

from rlcompare.compiled import njit
from rlcompare.envs.chess import rules
from rlcompare.envs.chess.endgames import ENDGAMES, QUEEN, ROOK
from rlcompare.envs.chess.rules import N_POSITIONS

CHUNKS = 4
"""The exhaustive test's share of the positions per endgame, by the white king's rank (pytest-xdist spreads them)."""


@njit(cache=True)
def _rules_table(piece: int) -> tuple[np.ndarray, ...]:
    """Per position, from the module's own functions: legal with white / black to move, the white king's and the
    piece's destinations (bitboards), black's destinations, black in check, and how many of white's successors
    move anything but the piece the action names (0)."""
    legal = np.zeros((N_POSITIONS, 2), dtype=np.bool_)
    king_to = np.zeros(N_POSITIONS, dtype=np.uint64)
    piece_to = np.zeros(N_POSITIONS, dtype=np.uint64)
    black_to = np.zeros(N_POSITIONS, dtype=np.uint64)
    check = np.zeros(N_POSITIONS, dtype=np.bool_)
    replies = np.zeros(8, dtype=np.int64)
    strays = 0
    for index in range(N_POSITIONS):
        white_king, white_piece, black_king = rules.decode(index)
        legal[index, 0] = rules.is_legal(piece, index, True)
        legal[index, 1] = rules.is_legal(piece, index, False)
        check[index] = rules.black_in_check(piece, index)
        if legal[index, 0]:
            for action in range(rules.n_actions(piece)):
                after = rules.white_after(piece, index, action)
                if after < 0:
                    continue
                king, moved, black = rules.decode(after)
                if action < 8:
                    king_to[index] |= np.uint64(1) << np.uint64(king)
                    strays += moved != white_piece or black != black_king
                else:
                    piece_to[index] |= np.uint64(1) << np.uint64(moved)
                    strays += king != white_king or black != black_king
        if legal[index, 1]:
            for i in range(rules.black_replies(piece, index, replies)):
                black_to[index] |= np.uint64(1) << np.uint64(replies[i])
    return legal, king_to, piece_to, black_to, check, np.array([strays])


@functools.cache
def _tables(piece: int) -> tuple[tuple[np.ndarray, ...], np.ndarray]:
    """:func:`_rules_table` and the count of white's legal actions from ``legal_moves_mask``, once per process."""
    return _rules_table(piece), rules.legal_moves_mask(piece).sum(axis=1)


def _place(board: chess.Board, piece: int, white_king: int, white_piece: int, black_king: int) -> None:
    """Put the three pieces on the emptied ``board`` (cheaper than a new board)."""
    board.clear_board()
    board.set_piece_at(white_king, chess.Piece(chess.KING, chess.WHITE))
    board.set_piece_at(white_piece, chess.Piece(rules.PIECE_TYPES[piece], chess.WHITE))
    board.set_piece_at(black_king, chess.Piece(chess.KING, chess.BLACK))


def _destinations(board: chess.Board) -> dict[int, int]:
    """python-chess's legal moves, as a bitboard of their destinations by the square they leave."""
    masks: dict[int, int] = {}
    for move in board.generate_legal_moves():
        masks[move.from_square] = masks.get(move.from_square, 0) | chess.BB_SQUARES[move.to_square]
    return masks


@pytest.mark.slow("every position of KRK and KQK against python-chess")
@pytest.mark.parametrize("chunk", range(CHUNKS))
@pytest.mark.parametrize("endgame", list(ENDGAMES))
def test_every_position_equals_python_chess(endgame, chunk):
    """Each position whose white king stands on this chunk's ranks, with white and with black to move: legal exactly
    where ``board.is_valid()``; white's moves (king and piece) and black's replies equal ``board.legal_moves``;
    black in check, checkmated and stalemated exactly where python-chess says so; every capture of the piece leaves
    insufficient material."""
    piece = ENDGAMES[endgame].piece
    (legal, king_to, piece_to, black_to, check, strays), white_moves = _tables(piece)
    assert strays[0] == 0
    board = chess.Board.empty()
    wrong: list[str] = []
    start, stop = chunk * N_POSITIONS // CHUNKS, (chunk + 1) * N_POSITIONS // CHUNKS
    for index in range(start, stop):
        white_king, white_piece, black_king = rules.decode(index)
        if len({white_king, white_piece, black_king}) < 3:
            if legal[index].any() or white_moves[index]:
                wrong.append(f"{index}: two pieces on one square, yet legal")
            continue
        _place(board, piece, white_king, white_piece, black_king)
        board.turn = chess.WHITE
        if board.is_valid() != legal[index, 0]:
            wrong.append(f"{board.fen()}: legal {legal[index, 0]}")
        elif legal[index, 0]:
            moves = _destinations(board)
            king, slides = moves.pop(white_king, 0), moves.pop(white_piece, 0)
            if (king, slides, moves) != (int(king_to[index]), int(piece_to[index]), {}):
                wrong.append(f"{board.fen()}: white's moves")
            if chess.popcount(king) + chess.popcount(slides) != white_moves[index] or not king | slides:
                wrong.append(f"{board.fen()}: legal_moves_mask")
        elif white_moves[index]:
            wrong.append(f"{board.fen()}: legal_moves_mask of an illegal position")
        board.turn = chess.BLACK
        if board.is_valid() != legal[index, 1]:
            wrong.append(f"{board.fen()}: legal {legal[index, 1]}")
            continue
        if not legal[index, 1]:
            continue
        moves = _destinations(board)
        replies = moves.pop(black_king, 0)
        if (replies, moves) != (int(black_to[index]), {}) or board.is_check() != check[index]:
            wrong.append(f"{board.fen()}: black's replies or check")
        if not replies and (board.is_checkmate() != check[index] or board.is_stalemate() == check[index]):
            wrong.append(f"{board.fen()}: checkmate or stalemate")
        if replies & chess.BB_SQUARES[white_piece]:
            board.push(chess.Move(black_king, white_piece))
            if not board.is_insufficient_material():
                wrong.append(f"{board.fen()}: material after the capture")
            board.pop()
    assert not wrong, f"{len(wrong)} disagreements, the first: {wrong[:5]}"


def _random_positions(piece: int, count: int, seed: int) -> list[tuple[int, bool]]:
    """``count`` positions with three distinct squares and a side to move, legal or not."""
    generator = np.random.default_rng(seed)
    positions = []
    while len(positions) < count:
        squares = generator.choice(64, size=3, replace=False)
        positions.append((rules.encode(*(int(s) for s in squares)), bool(generator.integers(2))))
    return positions


@pytest.mark.parametrize("endgame", list(ENDGAMES))
def test_random_positions_equal_python_chess(endgame):
    """1,000 random boards per endgame through the conversions: legality, ``set(board.legal_moves)`` against
    ``move_of`` of the legal actions and black's replies, each move's ``action_of`` and successor, game ends."""
    piece = ENDGAMES[endgame].piece
    mask = rules.legal_moves_mask(piece)
    replies = np.zeros(8, dtype=np.int64)
    for index, white_to_move in _random_positions(piece, 1000, seed=piece):
        board = rules.board_of(piece, index, white_to_move)
        assert rules.index_of(board) == (piece, index, white_to_move)
        legal = rules.is_legal(piece, index, white_to_move)
        assert board.is_valid() == legal, board.fen()
        if not legal:
            assert not mask[index].any()
            continue
        _, white_piece, black_king = rules.decode(index)
        if white_to_move:
            actions = np.flatnonzero(mask[index])
            moves = {rules.move_of(piece, index, int(a)): int(a) for a in actions}
            assert set(board.legal_moves) == set(moves), board.fen()
            for move, action in moves.items():
                assert rules.action_of(piece, index, move) == action
                board.push(move)
                assert rules.index_of(board) == (piece, rules.white_after(piece, index, action), False)
                board.pop()
            continue
        count = rules.black_replies(piece, index, replies)
        assert set(board.legal_moves) == {chess.Move(black_king, int(to)) for to in replies[:count]}, board.fen()
        assert board.is_check() == rules.black_in_check(piece, index)
        assert board.is_checkmate() == (count == 0 and rules.black_in_check(piece, index))
        assert board.is_stalemate() == (count == 0 and not rules.black_in_check(piece, index))
        assert (white_piece in replies[:count]) == (chess.Move(black_king, white_piece) in board.legal_moves)


def test_py_func_equals_compiled():
    """The Python source of the rules gives what the compiled functions give, on 120 random positions."""
    replies, python_replies = np.zeros(8, dtype=np.int64), np.zeros(8, dtype=np.int64)
    for piece in (ROOK, QUEEN):
        for index, white_to_move in _random_positions(piece, 60, seed=10 + piece):
            assert rules.decode.py_func(index) == rules.decode(index)
            assert rules.encode.py_func(*rules.decode(index)) == index
            assert rules.is_legal.py_func(piece, index, white_to_move) == rules.is_legal(piece, index, white_to_move)
            assert rules.black_in_check.py_func(piece, index) == rules.black_in_check(piece, index)
            count = rules.black_replies(piece, index, replies)
            assert rules.black_replies.py_func(piece, index, python_replies) == count
            np.testing.assert_array_equal(python_replies[:count], replies[:count])
            if rules.is_legal(piece, index, True):
                for action in range(rules.n_actions(piece)):
                    expected = rules.white_after(piece, index, action)
                    assert rules.white_after.py_func(piece, index, action) == expected


def test_action_numbering():
    """The convention: 8 king steps, then 7 distances per direction: action ``8 + 7 * d + distance - 1``."""
    assert (rules.n_actions(ROOK), rules.n_actions(QUEEN)) == (36, 64)
    index = rules.encode(chess.A1, chess.D4, chess.H6)
    assert rules.move_of(QUEEN, index, 4) == chess.Move(chess.A1, chess.B1)  # the king east
    assert rules.move_of(QUEEN, index, 8) == chess.Move(chess.D4, chess.D5)  # north, 1 square
    assert rules.move_of(QUEEN, index, 8 + 7 + 2) == chess.Move(chess.D4, chess.G4)  # east, 3 squares
    assert rules.move_of(QUEEN, index, 8 + 7 * 4 + 3) == chess.Move(chess.D4, chess.H8)  # north-east, 4 squares
    assert rules.move_of(QUEEN, index, 8 + 7 * 7 + 2) == chess.Move(chess.D4, chess.A7)  # north-west, 3 squares
    assert rules.white_after(QUEEN, index, 8 + 7 * 7 + 3) == -1  # north-west, 4 squares: off the board
    assert rules.white_after(QUEEN, index, 8 + 7 * 6 + 2) == -1  # south-west, 3 squares: onto the white king
    assert rules.white_after(QUEEN, index, 8 + 7 * 6 + 1) == rules.encode(chess.A1, chess.B2, chess.H6)
    blocked = rules.encode(chess.E5, chess.D4, chess.G7)  # the white king shields the black one
    assert rules.white_after(QUEEN, blocked, 8 + 7 * 4 + 2) == -1  # north-east, 3 squares: through e5 onto g7
    west_3 = rules.encode(chess.E5, chess.A4, chess.G7)
    assert rules.white_after(ROOK, blocked, 8 + 7 * 3 + 2) == west_3  # the rook west, 3 squares


def test_conversions_refuse_other_boards():
    """``index_of`` names the material it refuses and what it allows; other misuse says what is wrong."""
    for fen in ("4k3/8/8/8/8/8/8/2B1K3 w - - 0 1", "4k3/8/8/8/8/8/8/R3K2R w - - 0 1", "4k2r/8/8/8/8/8/8/4K3 w - - 0 1",
                "4k3/8/8/8/8/8/8/4K3 w - - 0 1", "4k3/8/8/8/8/8/4r3/R3K3 w - - 0 1"):
        with pytest.raises(ValueError, match="only KRvK and KQvK are allowed"):
            rules.index_of(chess.Board(fen))
    with pytest.raises(ValueError, match="castling rights"):
        rules.index_of(chess.Board("4k3/8/8/8/8/8/8/4K2R w K - 0 1"))
    assert rules.index_of(chess.Board("4k3/8/8/8/8/8/8/4K2R w - - 0 1")) == (
        ROOK, rules.encode(chess.E1, chess.H1, chess.E8), True)
    with pytest.raises(ValueError, match="two pieces on one square"):
        rules.board_of(ROOK, rules.encode(3, 3, 40), True)
    index = rules.encode(chess.E1, chess.E2, chess.E8)
    with pytest.raises(ValueError, match="illegal"):
        rules.move_of(ROOK, index, 8 + 7 * 2)  # the rook south, onto its own king
    with pytest.raises(ValueError, match="not one of the 36 actions"):
        rules.move_of(ROOK, index, 36)
    with pytest.raises(ValueError, match="neither a step"):
        rules.action_of(ROOK, index, chess.Move(chess.E2, chess.F3))  # a rook moves no diagonal
    with pytest.raises(ValueError, match="illegal"):
        rules.action_of(ROOK, index, chess.Move(chess.E1, chess.E2))  # the king onto its own rook
