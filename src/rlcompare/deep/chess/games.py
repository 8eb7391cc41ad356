"""Chess and Gardner's 5 x 5 minichess for the deep engine: pgx's JAX games (pinned, 2.6.0) as two-player
environments.

Every step is taken by the side to move and rewarded from its side: +1 for the move that mates, 0 otherwise; the
game's own end (mate, stalemate, insufficient material, the fifty-move rule, threefold repetition, and pgx's cap of
256 plies for Gardner's game and 512 for chess, a draw) terminates the episode, so nothing is ever truncated. What
the network sees is the position from the mover's side (pgx's AlphaZero planes), reduced to the current position:
its 12 piece planes and 2 repetition planes, and the colour, move count, castling and no-progress planes, without
the seven earlier positions AlphaZero stacks (``docs/chess-game.md`` gives the reason and the cost).

``tests/parity/test_pgx_chess.py`` checks pgx's rules against python-chess; ``docs/chess-game.md`` lists where they
differ.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import jax
import jax.numpy as jnp
import numpy as np

from rlcompare.envs.chess.games import GAMES, HISTORY_PLANES, PIECE_VALUES, BoardGame

if TYPE_CHECKING:
    import pgx


@functools.cache
def _loaded() -> tuple[dict[str, pgx.Env], dict[str, np.ndarray]]:
    """pgx's games and, per game, the square each action's move ends on (-1 where the label names no move), made
    once per process where a game is first stepped, not where one is named: pgx builds its tables and constant
    arrays as it loads (seconds; a configuration's checks and a plan read only the game's sizes). Loaded outside any
    trace (a constant made while tracing would be the trace's) and in JAX's 32-bit default, as at an import."""
    with jax.ensure_compile_time_eval(), jax.enable_x64(False):
        import pgx
        from pgx._src import gardner_chess_utils as gardner_tables
        from pgx._src.games import chess as pgx_chess

        games = {pgx_id: pgx.make(pgx_id) for pgx_id in ("chess", "gardner_chess")}
    return games, {
        "chess": np.asarray(pgx_chess.FROM_PLANE, np.int32).reshape(-1),  # a label is from * 73 + plane
        "gardner_chess": np.asarray(gardner_tables.TO_MAP, np.int32).reshape(-1),  # from * 49 + plane
    }


def pgx_game(pgx_id: str) -> pgx.Env:
    return _loaded()[0][pgx_id]


def destinations(pgx_id: str) -> np.ndarray:
    """The square each action's move ends on in the game ``pgx_id`` (-1 where the label names no move)."""
    return _loaded()[1][pgx_id]


@dataclass(frozen=True)
class ChessGameEnv:
    """One of :data:`rlcompare.envs.chess.games.GAMES` as the deep engine steps it; hashable, static under jit."""

    game: BoardGame

    players = 2
    max_steps = None
    """The game's own end is the only one (its ply cap included)."""

    @property
    def name(self) -> str:
        return self.game.name

    @property
    def n_actions(self) -> int:
        return self.game.n_actions

    @property
    def observation_shape(self) -> tuple[int, ...]:
        return self.game.observation_shape

    def reset(self, key: jax.Array) -> Any:
        with jax.enable_x64(False):  # pgx is written for JAX's 32-bit default (the engine traces in 64-bit mode)
            return pgx_game(self.game.pgx_id).init(key)

    def step(self, state: Any, action: jax.Array, key: jax.Array | None = None
             ) -> tuple[Any, jax.Array, jax.Array, jax.Array]:
        """``(state, reward to the mover, terminated, truncated)``; the game is deterministic (``key`` unused)."""
        mover = state.current_player
        with jax.enable_x64(False):
            state = pgx_game(self.game.pgx_id).step(state, action.astype(jnp.int32))
        return state, state.rewards[mover], state.terminated, jnp.zeros((), bool)

    def observe(self, state: Any) -> jax.Array:
        planes = state.observation
        return jnp.concatenate([planes[..., :HISTORY_PLANES], planes[..., 8 * HISTORY_PLANES:]], axis=-1)

    def legal(self, state: Any) -> jax.Array:
        """``(n_actions,)`` bool: the moves the side to move may play."""
        mask: jax.Array = state.legal_action_mask
        return mask

    def colour(self, state: Any) -> jax.Array:
        """The side to move: 0 White, 1 Black."""
        side: jax.Array = state._x.color if self.game.pgx_id == "chess" else state._turn
        return side

    def captures(self, state: Any) -> jax.Array:
        """``(n_actions,)`` float32: the value of the opponent's piece on each move's destination square
        (:data:`rlcompare.envs.chess.games.PIECE_VALUES`; a pawn for en passant; 0 for a move that takes nothing)."""
        board = state._x.board if self.game.pgx_id == "chess" else state._board
        values = jnp.asarray((0.0, *PIECE_VALUES), jnp.float32)  # by pgx's piece code, 0 for an empty square
        to = jnp.asarray(destinations(self.game.pgx_id))
        taken = jnp.clip(-board[jnp.maximum(to, 0)], 0, 6)  # the opponent's pieces are negative
        if self.game.pgx_id == "chess":  # a pawn moving onto the en-passant square takes a pawn
            pawn_from = board[jnp.arange(self.n_actions) // 73] == 1
            taken = jnp.where(pawn_from & (to == state._x.en_passant) & (to >= 0), 1, taken)
        return jnp.where(to >= 0, values[taken], 0.0)


def chess_game_env(name: str) -> ChessGameEnv:
    """The deep engine's environment for a game of :data:`rlcompare.envs.chess.games.GAMES`."""
    return ChessGameEnv(GAMES[name])


def fen_of(game: ChessGameEnv, state: Any) -> str:
    """The position in Forsyth-Edwards notation: chess's, or for Gardner's game pgx's five-rank version of it."""
    if game.game.pgx_id == "chess":
        from pgx.experimental.chess import to_fen

        return str(to_fen(state))
    return str(state._to_fen())
