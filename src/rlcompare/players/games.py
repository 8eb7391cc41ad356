"""Games between players on python-chess boards: one game, and pairs with the colours swapped. A game ends where
``board.outcome(claim_draw=True)`` says, or at a ply limit as a draw; its record holds the result and the PGN game.
"""

from __future__ import annotations

from dataclasses import dataclass

import chess
import chess.pgn

from rlcompare.players.basic import ChessPlayer


@dataclass(frozen=True)
class GameRecord:
    """A finished game: who played, ``result`` as PGN writes it (``1-0``, ``0-1``, ``1/2-1/2``), how it ended,
    and the PGN game."""

    white: str
    black: str
    result: str
    termination: str
    plies: int
    game: chess.pgn.Game

    @property
    def white_points(self) -> float:
        """1 for a win of White, 0.5 for a draw, 0 for a loss."""
        return {"1-0": 1.0, "0-1": 0.0}.get(self.result, 0.5)

    def points(self, name: str) -> float:
        """What the player named ``name`` scored."""
        if name not in (self.white, self.black):
            raise ValueError(f"{name!r} did not play in {self.white} - {self.black}")
        return self.white_points if name == self.white else 1.0 - self.white_points


def ending(outcome: chess.Outcome | None, max_plies: int | None) -> tuple[str, str]:
    """``(result, termination)`` of a game that stopped with ``outcome``, or at the ply limit where None."""
    if outcome is None:
        return "1/2-1/2", f"draw at the limit of {max_plies} plies"
    return outcome.result(), outcome.termination.name.lower().replace("_", " ")


def play_game(white: ChessPlayer, black: ChessPlayer, start: chess.Board | None = None,
              max_plies: int | None = None) -> GameRecord:
    """A game from ``start``'s position (the standard start where None; its earlier moves are not replayed), until
    ``board.outcome(claim_draw=True)`` (draws are claimed at once) or a draw after ``max_plies`` plies. Players
    see the game's own board, with its moves (copying it each ply would cost more than the game); a player that
    leaves it changed, or plays an illegal move, is a ValueError."""
    board = chess.Board() if start is None else start.copy(stack=False)
    players = {chess.WHITE: white, chess.BLACK: black}
    outcome = board.outcome(claim_draw=True)
    plies = 0
    while outcome is None and (max_plies is None or plies < max_plies):
        player, fen = players[board.turn], board.fen()
        move = player.move(board)
        if len(board.move_stack) != plies or board.fen() != fen:
            raise ValueError(f"{player.name} changed the board from {fen} to {board.fen()}")
        if not board.is_legal(move):
            raise ValueError(f"{player.name} played the illegal move {move.uci()} on {fen}")
        board.push(move)
        plies += 1
        outcome = board.outcome(claim_draw=True)
    result, termination = ending(outcome, max_plies)
    game = chess.pgn.Game.from_board(board)
    game.headers.update({"White": white.name, "Black": black.name, "Result": result, "Termination": termination})
    return GameRecord(white.name, black.name, result, termination, plies, game)


def play_pairs(a: ChessPlayer, b: ChessPlayer, pairs: int, start: chess.Board | None = None,
               max_plies: int | None = None) -> list[GameRecord]:
    """``2 * pairs`` games, colours swapped in each pair: ``a`` White, then ``b`` White."""
    return [play_game(*players, start=start, max_plies=max_plies)
            for _ in range(pairs) for players in ((a, b), (b, a))]
