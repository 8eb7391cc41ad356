"""Retrograde analysis of KRK and KQK (Thompson 1986, "Retrograde analysis of certain endgames", ICCA Journal 9(3);
the method is Ströhlein's, 1970): the depth to mate of every position, and a tablebase with python-chess's Gaviota
interface that reads it.

The analysis works backwards from the checkmates, a ply at a time. Black-to-move positions lost in ``k`` half-moves
give, by un-moving a white move, the white-to-move positions won in ``k + 1`` that are not known yet (white mates as
fast as it can: the first depth found is the least). Those give, by un-moving a black king step, black-to-move
positions, each of which counts down its replies not yet known to lose; the one whose last reply falls at this ply is
lost in ``k + 2`` (black resists as long as it can: its longest reply). A black position that can capture the
undefended piece is a draw (two bare kings), as is a stalemate, and so is every position the sweeps never reach.
Each position is visited once per predecessor, so a solve is a few million steps of compiled code.
"""

from __future__ import annotations

import functools
from types import TracebackType
from typing import NamedTuple

import chess
import chess.gaviota
import numpy as np

from rlcompare.compiled import njit
from rlcompare.envs.chess.endgames import QUEEN, ROOK
from rlcompare.envs.chess.rules import (
    KING_STEPS,
    MAX_DISTANCE,
    N_KING_STEPS,
    N_POSITIONS,
    QUEEN_DIRECTIONS,
    black_in_check,
    black_replies,
    decode,
    encode,
    index_of,
    is_legal,
    material,
    n_directions,
    on_board,
    touching,
)

UNKNOWN = -1
"""The depth of a position white cannot force mate from (a draw), or of an illegal one."""


class Solution(NamedTuple):
    """Half-moves to mate with best play, by position index (int16, read-only); -1 where black draws or the
    position is illegal."""

    white: np.ndarray  # white to move: half-moves until white mates (odd)
    black: np.ndarray  # black to move: half-moves until black is mated (even; 0 checkmated now)


@njit(inline="always")
def _can_capture(replies: np.ndarray, count: int, white_piece: int) -> bool:
    """Whether one of black's ``count`` replies captures the white piece."""
    for i in range(count):  # noqa: SIM110 -- numba compiles no generator expression
        if replies[i] == white_piece:
            return True
    return False


@njit(inline="always")
def _mark_white_predecessors(piece: int, index: int, depth: int, white: np.ndarray, won: np.ndarray,
                             n_won: int) -> int:
    """Each white-to-move position with a move to the black-to-move ``index`` that has no depth yet gets ``depth``
    and joins ``won`` (its first ``n_won`` entries used); the new count."""
    white_king, white_piece, black_king = decode(index)
    for step in range(N_KING_STEPS):  # the king came from one step back, a square it could stand on
        df, dr = KING_STEPS[step]
        file, rank = white_king % 8 - df, white_king // 8 - dr
        before = encode(file + 8 * rank, white_piece, black_king)
        if on_board(file, rank) and is_legal(piece, before, True) and white[before] == UNKNOWN:
            white[before] = depth
            won[n_won] = before
            n_won += 1
    for direction in range(n_directions(piece)):  # the piece slid in along a line of empty squares
        df, dr = QUEEN_DIRECTIONS[direction]
        file, rank = white_piece % 8, white_piece // 8
        for _ in range(MAX_DISTANCE):
            file, rank = file - df, rank - dr
            square = file + 8 * rank
            if not on_board(file, rank) or square in (white_king, black_king):
                break
            before = encode(white_king, square, black_king)
            if is_legal(piece, before, True) and white[before] == UNKNOWN:
                white[before] = depth
                won[n_won] = before
                n_won += 1
    return n_won


@njit(inline="always")
def _count_down_black_predecessors(piece: int, index: int, depth: int, black: np.ndarray, escapes: np.ndarray,
                                   lost: np.ndarray, n_lost: int) -> int:
    """For each black-to-move position with a king step to the white-to-move ``index`` (now known won), one reply
    fewer escapes; one left with none is lost in ``depth`` and joins ``lost``; the new count."""
    white_king, white_piece, black_king = decode(index)
    for step in range(N_KING_STEPS):
        df, dr = KING_STEPS[step]
        file, rank = black_king % 8 - df, black_king // 8 - dr
        square = file + 8 * rank
        if not on_board(file, rank) or square == white_piece or touching(square, white_king):
            continue
        before = encode(white_king, white_piece, square)
        if escapes[before] > 0:
            escapes[before] -= 1
            if escapes[before] == 0:
                black[before] = depth
                lost[n_lost] = before
                n_lost += 1
    return n_lost


@njit(cache=True)
def retrograde(piece: int) -> tuple[np.ndarray, np.ndarray]:
    """``(white, black)``: the depths of :class:`Solution`, computed by retrograde sweeps."""
    white = np.full(N_POSITIONS, UNKNOWN, dtype=np.int16)
    black = np.full(N_POSITIONS, UNKNOWN, dtype=np.int16)
    escapes = np.full(N_POSITIONS, -1, dtype=np.int8)  # black to move: replies not known to lose; -1 never lost
    lost, next_lost = np.empty(N_POSITIONS, dtype=np.int64), np.empty(N_POSITIONS, dtype=np.int64)
    won = np.empty(N_POSITIONS, dtype=np.int64)
    replies = np.empty(N_KING_STEPS, dtype=np.int64)
    n_lost = 0
    for index in range(N_POSITIONS):
        if not is_legal(piece, index, False):
            continue
        count = black_replies(piece, index, replies)
        if count == 0 and black_in_check(piece, index):  # checkmate
            black[index] = 0
            lost[n_lost] = index
            n_lost += 1
        elif count > 0 and not _can_capture(replies, count, index // 64 % 64):  # stalemate and capture: drawn
            escapes[index] = count
    depth = 0
    while n_lost > 0:
        n_won = 0
        for i in range(n_lost):
            n_won = _mark_white_predecessors(piece, lost[i], depth + 1, white, won, n_won)
        n_lost = 0
        for i in range(n_won):
            n_lost = _count_down_black_predecessors(piece, won[i], depth + 2, black, escapes, next_lost, n_lost)
        lost, next_lost = next_lost, lost
        depth += 2
    return white, black


@functools.cache
def solve(piece: int) -> Solution:
    """The depth to mate of every position of KRK (``ROOK``) or KQK (``QUEEN``), computed once per process."""
    if piece not in (ROOK, QUEEN):
        raise ValueError(f"piece {piece} is neither ROOK ({ROOK}) nor QUEEN ({QUEEN})")
    white, black = retrograde(piece)
    white.flags.writeable = black.flags.writeable = False
    return Solution(white, black)


class Tablebase:
    """KRK, KQK and K v K with the interface of python-chess's Gaviota tablebases (``chess.gaviota``,
    ``PythonTablebase``, python-chess 1.11), its conventions copied from there:

    - ``probe_dtm``: half-moves to mate with best play, positive where the side to move mates, negative where it is
      mated, 0 for a draw *and for a checkmated position* (the docstring of ``PythonTablebase.probe_dtm``: "or 0 in
      drawn or checkmated positions"; its example: white to move and mated in 10 half-moves gives -10).
    - ``probe_wdl``: 1 where the side to move wins, -1 where it loses, 0 for a draw; a checkmated side loses, -1
      (``probe_wdl`` reads the DTM and asks ``board.is_checkmate()`` where it is 0).
    - Two bare kings are a draw, 0, before any table is looked for (``probe_dtm``: ``board.occupied ==
      board.kings``).
    - Any other material raises :class:`chess.gaviota.MissingTableError` (a ``KeyError``), as a missing table does;
      a board with castling rights or more than 5 pieces raises ``KeyError`` first, as Gaviota does.
    - A table serves either colour: a lone white king against king and rook or queen is probed as the board with the
      colours swapped and mirrored, as Gaviota probes "reversed" tables (``_setup_tablebase``).
    - ``get_dtm`` and ``get_wdl`` give ``default`` for any ``KeyError``.

    Gaviota's own tables hold no illegal positions; this one raises ``KeyError`` for one (the side not to move in
    check, or the kings touching).
    """

    def probe_dtm(self, board: chess.Board) -> int:
        """Half-moves to mate, signed for the side to move (see the class); ``KeyError`` where there is none."""
        if board.castling_rights:
            raise KeyError(f"gaviota tables do not contain positions with castling rights: {board.fen()}")
        if chess.popcount(board.occupied) > 5:
            raise KeyError(f"gaviota tables support up to 5 pieces, not {chess.popcount(board.occupied)}: "
                           f"{board.fen()}")
        if board.occupied == board.kings:
            return 0
        if material(board) in ("KvKR", "KvKQ"):
            board = board.mirror()
        if material(board) not in ("KRvK", "KQvK"):
            raise chess.gaviota.MissingTableError(f"no table available for: {material(board)} (this tablebase "
                                                  "holds KRvK, KQvK and KvK)")
        piece, index, white_to_move = index_of(board)
        if not is_legal(piece, index, white_to_move):
            raise KeyError(f"illegal position: {board.fen()}")
        solution = solve(piece)
        if white_to_move:
            return max(int(solution.white[index]), 0)
        return -max(int(solution.black[index]), 0)

    def probe_wdl(self, board: chess.Board) -> int:
        """1 where the side to move wins, 0 a draw, -1 where it loses (checkmated included)."""
        dtm = self.probe_dtm(board)
        if dtm == 0:
            return -1 if board.is_checkmate() else 0
        return 1 if dtm > 0 else -1

    def get_dtm(self, board: chess.Board, default: int | None = None) -> int | None:
        """:meth:`probe_dtm`, or ``default`` where it raises ``KeyError``."""
        try:
            return self.probe_dtm(board)
        except KeyError:
            return default

    def get_wdl(self, board: chess.Board, default: int | None = None) -> int | None:
        """:meth:`probe_wdl`, or ``default`` where it raises ``KeyError``."""
        try:
            return self.probe_wdl(board)
        except KeyError:
            return default

    def close(self) -> None:
        """Nothing to release (the solutions stay cached for the process); for Gaviota's interface."""

    def __enter__(self) -> Tablebase:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc_value: BaseException | None,
                 traceback: TracebackType | None) -> None:
        self.close()
