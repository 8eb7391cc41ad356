"""Whole games of chess for the deep engine, as facts: which of pgx's games, its board, actions and planes, and its
ply cap (the games themselves are :mod:`rlcompare.deep.chess.games`, in JAX).

| name              | board | actions | planes | ply cap | rules                                                  |
|-------------------|-------|---------|--------|---------|--------------------------------------------------------|
| ``gardner_chess`` | 5 x 5 | 1,225   | 115    | 256     | Gardner's minichess (1969): no castling, no double step |
| ``chess``         | 8 x 8 | 4,672   | 119    | 512     | FIDE's, with the draws pgx ends at once (docs)          |

Each is pgx's game of the same name; ``docs/chess-game.md`` lists where pgx's rules depart from python-chess's.
"""

from __future__ import annotations

from typing import NamedTuple

HISTORY_PLANES = 14
"""pgx's planes for each of the eight positions it stacks: 6 of the mover's pieces, 6 of the opponent's, and 2 that
say whether the position was seen before."""


class BoardGame(NamedTuple):
    name: str
    pgx_id: str
    board_size: int
    n_actions: int
    planes: int
    """pgx's observation planes: 8 positions of 14 planes each, then the colour, counters and castling."""
    max_plies: int
    """Where pgx ends a game as a draw."""
    label: str

    @property
    def observation_shape(self) -> tuple[int, int, int]:
        """What the network sees: the current position's planes and the colour, counter and castling planes (the
        seven earlier positions left out: ``docs/chess-game.md``)."""
        return (self.board_size, self.board_size, self.planes - 7 * HISTORY_PLANES)


GAMES = {game.name: game for game in (
    BoardGame("gardner_chess", "gardner_chess", 5, 1225, 115, 256, "Gardner's minichess"),
    BoardGame("chess", "chess", 8, 4672, 119, 512, "chess"),
)}
PIECE_VALUES = (1.0, 3.0, 3.0, 5.0, 9.0, 0.0)
"""Pawn, knight, bishop, rook, queen, king: the textbook values the one-ply material player counts (a king is never
taken)."""
