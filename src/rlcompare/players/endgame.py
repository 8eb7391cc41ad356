"""The endgames on python-chess boards: a learnt agent's move on any board of its endgame, the defender's reply, and
whole games, which become PGN any chess program opens.

A learner with the board's symmetries knows one position of each class (:mod:`rlcompare.envs.chess.endgame`); on a
board it finds the symmetry that takes the board's position to its class's, chooses there, and maps the move back.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import chess
import numpy as np

from rlcompare.envs.chess import rules
from rlcompare.envs.chess.endgame import BEST, Endgame, board_position, make_endgame, symmetric_images
from rlcompare.envs.chess.endgames import ENDGAMES, MOVE_LIMIT, parse


@functools.cache
def square_maps() -> np.ndarray:
    """``(8, 64)``: where each symmetry of :func:`symmetric_images` takes each square (identity first)."""
    squares = np.arange(64, dtype=np.int64)
    return np.asarray(symmetric_images(squares) % 64)  # a position of king a1, piece a1 and this square


@dataclass
class ChessAgent:
    """The greedy policy of a learnt table on python-chess boards: ``move(board)`` plays White's move."""

    q: np.ndarray
    env: str
    seed: int = 0
    stage: str = "final"
    tables: Endgame = field(init=False)

    def __post_init__(self) -> None:
        self.tables = make_endgame(parse(self.env))

    def move(self, board: chess.Board) -> chess.Move:
        """White's greedy move in ``board`` (first maximum, as ``np.argmax``); a ``ValueError`` for a board that
        is not a legal position of this endgame with White to move."""
        index = board_position(parse(self.env).endgame, board)
        state = int(self.tables.state_of[index])
        played = int(self.tables.positions[state])
        symmetry = int(np.flatnonzero(symmetric_images(np.array([index]))[:, 0] == played)[0])
        move = rules.move_of(ENDGAMES[parse(self.env).endgame].piece, played, int(np.argmax(self.q[state])))
        back = np.argsort(square_maps()[symmetry])
        return chess.Move(int(back[move.from_square]), int(back[move.to_square]))


def defender_move(env: str, board: chess.Board, rng: np.random.Generator) -> chess.Move:
    """Black's reply on ``board`` as the endgame's defender plays it: one of the longest-resisting replies, a random
    legal one, or either by its share, each uniformly among its kind."""
    tables = make_endgame(parse(env))
    index = board_position(parse(env).endgame, board, white_to_move=False)
    replies = int(tables.replies[index])
    chosen = replies >> BEST & 0xFF
    if tables.random_share > 0 and (tables.random_share >= 1 or rng.random() < tables.random_share):
        chosen = replies & 0xFF
    steps = [k for k in range(8) if chosen >> k & 1]
    king = index % 64
    return chess.Move(king, king + int(tables.steps[steps[int(rng.integers(len(steps)))]]))


def play(agent: ChessAgent, start: chess.Board, rng: np.random.Generator, limit: int = MOVE_LIMIT
         ) -> list[chess.Move]:
    """A game from ``start`` (White to move): the agent's moves and the defender's replies, until mate, stalemate,
    the piece taken, or ``limit`` moves of White."""
    board, moves = start.copy(stack=False), []
    for _ in range(limit):
        for side in (chess.WHITE, chess.BLACK):
            move = agent.move(board) if side == chess.WHITE else defender_move(agent.env, board, rng)
            board.push(move)
            moves.append(move)
            if board.is_checkmate() or board.is_stalemate() or board.is_insufficient_material():
                return moves  # the episode's ends: repetitions do not end one
    return moves
