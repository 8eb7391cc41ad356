"""Players on python-chess boards and games between them, for a rating ladder: a uniformly random player, a
one-ply material grabber, and Stockfish at two weak settings through its UCI client.

Every player has ``name``, ``move(board)`` and ``close()`` (a no-op where nothing is held); ``with
contextlib.closing(player):`` closes one. A game ends where ``board.outcome(claim_draw=True)`` says, or at a ply
limit as a draw; its record holds the result and the PGN game.
"""

from __future__ import annotations

import contextlib
import shutil
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Protocol

import chess
import chess.engine
import chess.pgn
import numpy as np

from rlcompare.envs.chess_games import PIECE_VALUES

STOCKFISH_DIRS: tuple[str, ...] = ("/usr/games",)
"""Where :func:`find_stockfish` looks after ``PATH`` (Debian installs Stockfish in /usr/games, off users' PATH)."""


class ChessPlayer(Protocol):
    """Chooses a legal move on any board where one exists; ``close()`` frees what it holds (an engine)."""

    @property
    def name(self) -> str: ...

    def move(self, board: chess.Board) -> chess.Move: ...

    def close(self) -> None: ...


class MissingEngine(FileNotFoundError):
    """A chess engine the caller asked for is not installed; the message says how to install it (a missing file:
    the command line reports it in one line, as any other)."""


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


@dataclass(frozen=True)
class StockfishRung:
    """A Stockfish setting on the ladder: its UCI options and the limit of each search."""

    name: str
    options: Mapping[str, int | bool]
    limit: chess.engine.Limit


ENGINE_OPTIONS: Mapping[str, int] = {"Threads": 1, "Hash": 1}
"""Every rung: one thread (a search with a node or depth limit then repeats itself) and a 1 MB table, plenty for
searches this short."""
SKILL_0 = StockfishRung("stockfish-skill0-depth1", {"Skill Level": 0}, chess.engine.Limit(depth=1))
"""Stockfish's weakest skill, searching one ply (with MultiPV 4 behind the scenes)."""
ELO_1350 = StockfishRung("stockfish-elo1350", {"UCI_LimitStrength": True, "UCI_Elo": 1350},
                         chess.engine.Limit(nodes=5000))
"""Stockfish 15.1's lowest Elo: skill level ((1350 - 1346.6) / 143.4) ** (1 / 0.806) ~ 0.01, which picks among the
first iteration's best moves as skill 0 does, yet searches on, and the fuller hash table and histories seem to
help: it scored 52 of 80 against :data:`SKILL_0` (46 of 80 at 1000 nodes, 54 at 10 ms a move). A node limit, not
a time limit, so that the work per move does not hang on the machine or its load; 5000 nodes take about 5 ms."""


def find_stockfish() -> str:
    """The path of a Stockfish binary on ``PATH`` or in :data:`STOCKFISH_DIRS`; :class:`MissingEngine` if none."""
    found = shutil.which("stockfish")
    for folder in STOCKFISH_DIRS:
        found = found or shutil.which("stockfish", path=folder)
    if found is None:
        raise MissingEngine(f"Stockfish not found on PATH or in {', '.join(STOCKFISH_DIRS)}; "
                            "install Debian's package: apt-get install stockfish")
    return found


class StockfishPlayer:
    """Stockfish at one rung, in a process of its own until :meth:`close`.

    Below full strength it cannot be seeded: Stockfish 15.1 picks its weakened move with a PRNG seeded from the
    clock (``static PRNG rng(now())`` in ``Skill::pick_best``), so one position gets different moves in fresh
    processes and in one process alike. At full strength, one thread and a node limit, it repeats itself."""

    def __init__(self, rung: StockfishRung, path: str | None = None) -> None:
        self.rung = rung
        self.engine = chess.engine.SimpleEngine.popen_uci(path or find_stockfish())
        try:
            self.engine.configure({**ENGINE_OPTIONS, **rung.options})
        except BaseException:
            self.close()
            raise

    @property
    def name(self) -> str:
        return self.rung.name

    def move(self, board: chess.Board) -> chess.Move:
        played = self.engine.play(board, self.rung.limit)
        if played.move is None:
            raise chess.engine.EngineError(f"{self.name} gave no move on {board.fen()}")
        return played.move

    def close(self) -> None:
        """Ends the engine's process; again, or after the engine died, does nothing."""
        with contextlib.suppress(chess.engine.EngineTerminatedError):
            self.engine.quit()


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
