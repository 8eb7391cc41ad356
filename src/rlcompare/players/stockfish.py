"""Stockfish as a player, at the weak settings of the rating ladder, through python-chess's UCI client."""

from __future__ import annotations

import contextlib
import shutil
from collections.abc import Mapping
from dataclasses import dataclass

import chess
import chess.engine

STOCKFISH_DIRS: tuple[str, ...] = ("/usr/games",)
"""Where :func:`find_stockfish` looks after ``PATH`` (Debian installs Stockfish in /usr/games, off users' PATH)."""


class MissingEngine(FileNotFoundError):
    """A chess engine the caller asked for is not installed; the message says how to install it (a missing file:
    the command line reports it in one line, as any other)."""


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
LIMIT_1350 = StockfishRung("stockfish-limit1350-nodes5000", {"UCI_LimitStrength": True, "UCI_Elo": 1350},
                           chess.engine.Limit(nodes=5000))
"""Named by its settings, not by a rating: ``UCI_Elo`` is calibrated against CCRL at a time control, not at 5,000
nodes, so the ladder measures this rung as it measures every player. Stockfish 15.1's lowest ``UCI_Elo``: skill
level ((1350 - 1346.6) / 143.4) ** (1 / 0.806) ~ 0.01, which picks among the first iteration's best moves as skill 0
does, yet searches on, and the fuller hash table and histories seem to help: it scored 52 of 80 against
:data:`SKILL_0` (46 of 80 at 1000 nodes, 54 at 10 ms a move). A node limit, not a time limit, so that the work per
move does not hang on the machine or its load; 5000 nodes take about 5 ms."""


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
