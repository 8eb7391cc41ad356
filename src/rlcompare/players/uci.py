"""Any :class:`~rlcompare.players.basic.ChessPlayer` as a UCI engine, so that chess programs (a GUI, a
tournament manager, python-chess's own client) play against it.

:func:`serve` reads commands a line at a time and answers each, flushing after every answer. The player chooses
at once, so ``go`` answers ``bestmove`` at once, except ``go infinite`` and ``go ponder``, which hold the move
until ``stop`` or ``ponderhit`` as the protocol asks. A player that values its move (``evaluate(board) -> (move,
value)``, a network's action value) sends ``info depth 1 score cp ... pv ...`` before it (:func:`centipawns`).
Malformed input never ends the loop: it is answered with ``info string`` and the loop goes on.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, TextIO

import chess

from rlcompare.players.basic import ChessPlayer, sorted_moves

AUTHOR = "rlcompare"
COMMANDS = frozenset({"uci", "debug", "isready", "setoption", "register", "ucinewgame", "position", "go", "stop",
                      "ponderhit", "quit"})
"""The commands a GUI sends an engine; ``debug``, ``register`` and ``setoption`` are accepted and change nothing."""
GO_WORDS = frozenset({"searchmoves", "ponder", "wtime", "btime", "winc", "binc", "movestogo", "depth", "nodes", "mate",
                      "movetime", "infinite"})


def info(text: str) -> str:
    """An ``info string`` line, on one line whatever ``text`` holds."""
    return "info string " + " ".join(text.split())


def status_words(board: chess.Board) -> str:
    """What is wrong with an invalid position, in python-chess's words: ``no white king, too many kings``."""
    status = board.status()
    return ", ".join((flag.name or "").lower().replace("_", " ") for flag in chess.Status if flag & status)


def centipawns(value: float) -> int:
    """A network's action value (the mover's expected return: +1 won, 0 drawn, -1 lost) in centipawns, by Leela
    Chess Zero's former mapping ``111.714640912 * tan(1.5620688421 * q)``, the value clipped to [-1, 1] (NaN: 0):
    0 at 0, 111 at 0.5, 671 at 0.9, 12,800 at 1."""
    q = 0.0 if math.isnan(value) else min(1.0, max(-1.0, value))
    return round(111.714640912 * math.tan(1.5620688421 * q))


def score_line(move: chess.Move, value: float | None) -> list[str]:
    """The ``info`` line that gives ``engine.analyse`` a score and a principal variation (none where no value)."""
    return [] if value is None else [f"info depth 1 score cp {centipawns(value)} pv {move.uci()}"]


MAX_COUNTER = 2**31 - 1
"""The largest halfmove clock or move number a position may give: pgx keeps them in 32 bits."""


def parse_position(tokens: list[str]) -> tuple[chess.Board | None, list[str]]:
    """The board ``position`` names (``startpos`` or ``fen <FEN>``, then ``moves ...``), or None, and the problems
    met; moves are played up to the first that cannot be, as Stockfish does."""
    kind, rest = (tokens[0], tokens[1:]) if tokens else ("", [])
    end = rest.index("moves") if "moves" in rest else len(rest)
    setup, moves = rest[:end], rest[end + 1:]
    if kind == "startpos":
        board, problems = chess.Board(), [f"ignored {' '.join(setup)!r} after startpos"] if setup else []
    elif kind == "fen":
        try:
            board = chess.Board(" ".join(setup))
        except ValueError as error:
            return None, [f"bad FEN {' '.join(setup)!r}: {error}"]
        if not board.is_valid():
            return None, [f"invalid position {board.fen()!r}: {status_words(board)}"]
        if max(board.halfmove_clock, board.fullmove_number) > MAX_COUNTER:
            return None, [f"bad FEN {' '.join(setup)!r}: a move counter above {MAX_COUNTER:,}"]
        problems = []
    else:
        return None, [f"position needs startpos or fen, got {' '.join(tokens)!r}"]
    for text in moves:
        try:
            move = board.parse_uci(text)
            if not move:
                raise ValueError("a null move")
        except ValueError as error:
            return board, [*problems, f"move {text!r} not played ({error}); position stops before it"]
        board.push(move)
    return board, problems


class Deferred:
    """A player made on first use, so that an engine answers ``uci`` at once and loads (and compiles) its network
    when asked ``isready``, as the protocol means: a GUI waits for ``readyok``, not for ``uciok``. A player that
    cannot be made fails each move (:meth:`Session.best_move` answers with an ``info string``)."""

    def __init__(self, name: str, make: Callable[[], Any]) -> None:
        self.name = name
        self._make = make
        self._player: Any = None

    def ready(self) -> None:
        """Make the player, and play on :func:`warm_up_boards`, so that a network's every program is compiled
        before the first ``go``."""
        if self._player is None:
            self._player = self._make()
            for board in warm_up_boards():
                evaluate(self._player, board)

    def move(self, board: chess.Board) -> chess.Move:
        return self.evaluate(board)[0]

    def evaluate(self, board: chess.Board) -> tuple[chess.Move, float | None]:
        """The player's move and its value (None where the player gives none)."""
        self.ready()
        return evaluate(self._player, board)

    def close(self) -> None:
        if self._player is not None:
            self._player.close()


def evaluate(player: Any, board: chess.Board) -> tuple[chess.Move, float | None]:
    """``player``'s move on ``board`` and its value: ``player.evaluate``'s where it has one, else None."""
    if hasattr(player, "evaluate"):
        move, value = player.evaluate(board)
        return move, value
    chosen: chess.Move = player.move(board)
    return chosen, None


KNIGHTS_OUT_AND_BACK = ("g1f3", "g8f6", "f3g1", "f6g8")


def warm_up_boards() -> list[chess.Board]:
    """Boards that take a network player through each of its compiled paths: the start, a move played on from it,
    a FEN's position with a move after it, and a game pgx has ended by its own count (a threefold repetition)."""
    after_e4 = chess.Board()
    after_e4.push_uci("e2e4")
    from_fen = chess.Board("rnbqkbnr/pppppppp/8/8/4P3/8/PPPP1PPP/RNBQKBNR b KQkq - 0 1")
    from_fen.push_uci("e7e5")
    repeated = chess.Board()
    for move in [*KNIGHTS_OUT_AND_BACK, *KNIGHTS_OUT_AND_BACK, "g1f3"]:
        repeated.push_uci(move)
    return [chess.Board(), after_e4, from_fen, repeated]


@dataclass
class Session:
    """One engine's state between commands: the player, its name, the position, and a move held by ``go
    infinite`` or ``go ponder``; ``done`` once ``quit`` came."""

    player: ChessPlayer
    name: str
    board: chess.Board | None = field(default_factory=chess.Board)
    held: str | None = None
    done: bool = False

    def handle(self, line: str) -> list[str]:
        """The lines that answer ``line``. Unknown tokens before a command are skipped,
        as the protocol says (``joho debug on`` is ``debug on``), and said to be."""
        tokens = line.split()
        start = next((index for index, token in enumerate(tokens) if token in COMMANDS), None)
        if start is None:
            return [info(f"unknown command {line.strip()!r}")] if tokens else []
        skipped = [info(f"unknown tokens {' '.join(tokens[:start])!r} skipped")] if start else []
        return skipped + self.command(tokens[start], tokens[start + 1:])

    def command(self, word: str, arguments: list[str]) -> list[str]:
        """The answer to one known command."""
        if word == "uci":
            return [f"id name {self.name}", f"id author {AUTHOR}", "uciok"]
        if word == "isready":
            try:
                getattr(self.player, "ready", lambda: None)()
            except Exception as error:  # the moves will say so too; readyok keeps the GUI's protocol going
                return [info(f"{self.name} could not be made ready: {error!r}"), "readyok"]
            return ["readyok"]
        if word == "ucinewgame":
            self.board, self.held = chess.Board(), None
            return []
        if word == "position":  # a position that cannot be set leaves none: the next go answers 0000, not stale
            self.board, problems = parse_position(arguments)
            if self.board is None:
                problems.append("no position until the next one that can be set")
            return [info(problem) for problem in problems]
        if word == "go":  # a move still held is dropped: the GUI has moved on without it
            answer = self.best_move(search_moves(arguments))
            holding = "infinite" in arguments or "ponder" in arguments
            self.held = answer[-1] if holding else None
            return answer[:-1] if holding else answer
        if word in ("stop", "ponderhit"):
            held, self.held = self.held, None
            return [held] if held else []
        self.done = word == "quit"  # debug, register and setoption change nothing
        return []

    def best_move(self, searched: list[str]) -> list[str]:
        """``bestmove`` of the player on the current board (``0000`` where there is no legal move, or where the
        player fails or plays an illegal move, with an ``info string`` saying so). Where ``go searchmoves`` named
        legal moves and the player chose another, the first of them."""
        if self.board is None:
            return [info("no position: the last could not be set"), "bestmove 0000"]
        allowed = [move for move in sorted_moves(self.board) if move.uci() in searched]
        if not any(self.board.legal_moves):
            return ["bestmove 0000"]
        try:
            move, value = evaluate(self.player, self.board.copy())
        except Exception as error:
            return [info(f"{self.name} failed: {error!r}"), "bestmove 0000"]
        if not isinstance(move, chess.Move) or not self.board.is_legal(move):
            return [info(f"{self.name} chose the illegal move {move}"), "bestmove 0000"]
        if allowed and move not in allowed:
            return [info(f"{self.name} chose {move.uci()}, outside searchmoves"), f"bestmove {allowed[0].uci()}"]
        return [*score_line(move, value), f"bestmove {move.uci()}"]


def search_moves(arguments: list[str]) -> list[str]:
    """The moves after ``searchmoves`` in ``go``'s arguments, up to the next keyword."""
    if "searchmoves" not in arguments:
        return []
    after = arguments[arguments.index("searchmoves") + 1:]
    return list(itertools.takewhile(lambda token: token not in GO_WORDS, after))


def serve(player: ChessPlayer, stdin: TextIO, stdout: TextIO, name: str | None = None) -> None:
    """Answer UCI commands from ``stdin`` on ``stdout`` with ``player``'s moves until ``quit`` or the end of the
    input. ``name`` is what ``id name`` says (the player's name where None)."""
    session = Session(player, name or player.name)
    for line in iter(stdin.readline, ""):
        answers = session.handle(line)
        if answers:
            stdout.write("".join(answer + "\n" for answer in answers))
            stdout.flush()
        if session.done:
            return
