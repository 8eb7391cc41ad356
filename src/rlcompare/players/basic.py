"""The players that need nothing but the rules: the protocol every player of a python-chess board keeps, a
uniformly random player and a one-ply material grabber.

Every player has ``name``, ``move(board)`` and ``close()`` (a no-op where nothing is held); ``with
contextlib.closing(player):`` closes one.
"""

from __future__ import annotations

from typing import Protocol

import chess
import numpy as np

from rlcompare.envs.chess.games import PIECE_VALUES


class ChessPlayer(Protocol):
    """Chooses a legal move on any board where one exists; ``close()`` frees what it holds (an engine)."""

    @property
    def name(self) -> str: ...

    def move(self, board: chess.Board) -> chess.Move: ...

    def close(self) -> None: ...


def sorted_moves(board: chess.Board) -> list[chess.Move]:
    """The legal moves by their UCI string, so that a draw among them does not hang on generation order."""
    return sorted(board.legal_moves, key=chess.Move.uci)


def captured_value(board: chess.Board, move: chess.Move) -> int:
    """What ``move`` takes, by :data:`PIECE_VALUES` (en passant takes a pawn); 0 for a quiet move."""
    if board.is_en_passant(move):
        return int(PIECE_VALUES[chess.PAWN - 1])
    piece = board.piece_at(move.to_square) if board.is_capture(move) else None
    return int(PIECE_VALUES[piece.piece_type - 1]) if piece else 0


class RandomPlayer:
    """Uniform over the legal moves, from its own generator."""

    def __init__(self, seed: int, name: str = "random") -> None:
        self._name = name
        self.rng = np.random.default_rng(seed)

    @property
    def name(self) -> str:
        return self._name

    def candidates(self, board: chess.Board) -> list[chess.Move]:
        """The moves it draws from: every legal one."""
        return sorted_moves(board)

    def move(self, board: chess.Board) -> chess.Move:
        moves = self.candidates(board)
        return moves[int(self.rng.integers(len(moves)))]

    def close(self) -> None:
        """Holds nothing."""


class MaterialPlayer(RandomPlayer):
    """One ply deep: takes the most valuable piece it can; ties, and positions with nothing to take, uniformly at
    random among the candidates."""

    def __init__(self, seed: int, name: str = "material") -> None:
        super().__init__(seed, name)

    def candidates(self, board: chess.Board) -> list[chess.Move]:
        """The legal moves that take the most."""
        moves = sorted_moves(board)
        values = [captured_value(board, move) for move in moves]
        top = max(values)
        return [move for move, value in zip(moves, values, strict=True) if value == top]
