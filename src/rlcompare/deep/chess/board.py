"""pgx's chess and python-chess in each other's terms: a move and its action, a board and its state.

pgx (``pgx.make("chess")``, pinned 2.6.0) keeps the board from the side to move's point of view: its 64 squares are
indexed ``file * 8 + rank``, where for Black to move rank r is shown as ``7 - r``, and the mover's pieces are
positive. An action is AlphaZero's ``from * 73 + plane``: planes 0-8 underpromote (``plane // 3``: rook, bishop,
knight), the others are queen-like and knight moves, and a pawn reaching the last rank by one of those becomes a
queen. A python-chess move is from White's point of view, in standard notation (castling is ``e1g1``).

:func:`state_of` replays a board's moves from its root through pgx's own (jitted) step, so that what pgx keeps of
the past (its last eight positions and its repetition hashes) is exactly what the same moves give in pgx. A root
other than the standard start is the state ``pgx.experimental.chess.from_fen`` makes (the same fields, tested
equal), with an empty history where ``from_fen`` leaves the standard start as the position before; it is built
here, in one jitted function, because ``from_fen`` compiles three programs at every call (0.8 s).
``tests/parity/test_pgx_chess.py`` checks these conversions and pgx's rules against python-chess;
``docs/chess-game.md`` lists where the rules differ.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import chess
import jax
import jax.numpy as jnp
import numpy as np
import pgx
from pgx._src.games import chess as rules
from pgx.chess import State
from pgx.experimental.chess import to_fen

from rlcompare.deep.chess.games import pgx_game

N_ACTIONS = 64 * 73
"""pgx's chess actions: 73 planes for each of the 64 squares a move can leave."""
UNDERPROMOTIONS = (chess.ROOK, chess.BISHOP, chess.KNIGHT)
"""The piece of each underpromotion plane, by ``plane // 3`` (planes 0-8)."""
PAWN = 1
LAST_RANK_BUT_ONE = 6
"""The rank (from the mover's side, 0-7) a pawn promotes from."""


def env() -> pgx.Env:
    """pgx's chess, one per process (:func:`rlcompare.deep.chess.games.pgx_game`)."""
    return pgx_game("chess")


@functools.cache
def _tables() -> tuple[np.ndarray, np.ndarray]:
    """pgx's ``FROM_PLANE`` (from, plane) -> to and ``TO_PLANE`` (from, to) -> plane (-1: none), as NumPy."""
    return np.asarray(rules.FROM_PLANE), np.asarray(rules.TO_PLANE)


@functools.cache
def _jitted_step() -> Callable[[State, jax.Array], State]:
    step: Callable[[State, jax.Array], State] = jax.jit(env().step)
    return step


def step(state: State, action: int) -> State:
    """pgx's ``env.step``, jitted once per process (the action as int32, so that it never compiles again), traced
    in JAX's 32-bit mode, which pgx is written for, whatever the caller's."""
    with jax.enable_x64(False):
        return _jitted_step()(state, jnp.int32(action))


def _square(index: int, white: bool) -> chess.Square:
    """python-chess's square of pgx's board index ``index`` for the side to move (``white``)."""
    file, rank = divmod(index, 8)
    return chess.square(file, rank if white else 7 - rank)


def _index(square: chess.Square, white: bool) -> int:
    """pgx's board index of ``square`` for the side to move (``white``)."""
    rank = chess.square_rank(square)
    return chess.square_file(square) * 8 + (rank if white else 7 - rank)


def _position(state: State) -> tuple[np.ndarray, bool]:
    """pgx's board (the mover's view) and whether White is to move."""
    return np.asarray(state._x.board), int(state._x.color) == 0


def _move(board: np.ndarray, white: bool, action: int) -> chess.Move:
    from_planes, _ = _tables()
    if not 0 <= action < N_ACTIONS:
        raise ValueError(f"action {action} is not one of pgx's chess actions (0-{N_ACTIONS - 1})")
    start, plane = divmod(action, 73)
    end = int(from_planes[start, plane])
    if end < 0:
        raise ValueError(f"action {action} leaves the board (from index {start}, plane {plane})")
    promotion: chess.PieceType | None = None
    if plane < 9:
        promotion = UNDERPROMOTIONS[plane // 3]
    elif board[start] == PAWN and start % 8 == LAST_RANK_BUT_ONE:
        promotion = chess.QUEEN
    return chess.Move(_square(start, white), _square(end, white), promotion)


def move_of(state: State, action: int) -> chess.Move:
    """The python-chess move of pgx's ``action`` for the side to move in ``state``, its promotion piece included
    (a queen where a pawn reaches the last rank by a plane other than an underpromotion's, as pgx promotes). Any
    action on the board decodes, legal or not; an action off the board is a ``ValueError``."""
    board, white = _position(state)
    return _move(board, white, action)


def action_of(state: State, move: chess.Move) -> int:
    """pgx's action for ``move`` (standard notation: castling ``e1g1``) by the side to move in ``state``; a queen
    promotion is the plain move's plane, as pgx queens by default. A move no action names (a null move, a
    drop, a square pair neither queen-like nor a knight's, an underpromotion not one rank forward) is a
    ``ValueError``; legality is not checked."""
    _, white = _position(state)
    from_planes, to_planes = _tables()
    start, end = _index(move.from_square, white), _index(move.to_square, white)
    if move.drop is not None or start == end:
        raise ValueError(f"no pgx action is the move {move.uci()}")
    if move.promotion in UNDERPROMOTIONS:
        piece = UNDERPROMOTIONS.index(move.promotion)
        for plane in range(3 * piece, 3 * piece + 3):
            if from_planes[start, plane] == end:
                return start * 73 + plane
        raise ValueError(f"no pgx action is the underpromotion {move.uci()}")
    plane = int(to_planes[start, end])
    if plane < 0:
        raise ValueError(f"no pgx action is the move {move.uci()}")
    return start * 73 + plane


def legal_actions(state: State) -> list[int]:
    """The actions legal by the rules in ``state``, ascending. pgx's own ``state.legal_action_mask`` is all True
    once a game has ended; this reads the rules' mask, which it keeps (a drawn position still has its moves, a
    mated one none)."""
    return [int(action) for action in np.flatnonzero(np.asarray(state._x.legal_action_mask))]


def legal_moves(state: State) -> set[str]:
    """The UCI strings of the moves legal by the rules in ``state`` (see :func:`legal_actions`)."""
    board, white = _position(state)
    return {_move(board, white, action).uci() for action in legal_actions(state)}


def fen_of(state: State) -> str:
    """The FEN of ``state`` by ``pgx.experimental.chess.to_fen``: its en-passant square follows every two-square
    pawn move, as ``board.fen(en_passant="fen")``, where python-chess's own FEN names it only when a capture there
    is legal."""
    fen: str = to_fen(state)
    return fen


def board_of(state: State) -> chess.Board:
    """A python-chess board of ``state``'s position (:func:`fen_of`), with no moves behind it."""
    return chess.Board(fen_of(state))


@functools.cache
def _start() -> State:
    return env().init(jax.random.PRNGKey(0))


@functools.cache
def _jitted_rooted() -> Callable[[Any, jax.Array], State]:
    game = rules.Game()

    def rooted(x: Any, order: jax.Array) -> State:
        x = x._replace(legal_action_mask=rules._legal_action_mask(x))
        x = x._replace(hash_history=jnp.zeros_like(x.hash_history).at[0].set(rules._zobrist_hash(x)),
                       board_history=jnp.zeros_like(x.board_history).at[0].set(x.board))
        terminated = game.is_terminal(x)
        state = State(_x=x, _player_order=order, current_player=order[x.color], terminated=terminated,
                      rewards=game.rewards(x)[order],
                      legal_action_mask=jnp.where(terminated, True, x.legal_action_mask))
        return state.replace(observation=env().observe(state))

    function: Callable[[Any, jax.Array], State] = jax.jit(rooted)
    return function


def _game_state(root: chess.Board) -> Any:
    """pgx's ``GameState`` of ``root``'s position, as ``pgx.experimental.chess.from_fen`` makes it from
    ``root.fen(en_passant="fen")``, its legal moves and history not yet filled in."""
    white = root.turn
    board = np.zeros(64, dtype=np.int32)
    for square, piece in root.piece_map().items():
        board[_index(square, white)] = piece.piece_type if piece.color == white else -piece.piece_type
    castling = [[root.has_queenside_castling_rights(side), root.has_kingside_castling_rights(side)]
                for side in (white, not white)]
    en_passant = -1 if root.ep_square is None else _index(root.ep_square, white)
    return rules.GameState(
        color=jnp.int32(0 if white else 1), board=jnp.asarray(board), castling_rights=jnp.asarray(castling),
        en_passant=jnp.int32(en_passant), halfmove_count=jnp.int32(root.halfmove_clock),
        fullmove_count=jnp.int32(root.fullmove_number))


def _root_state(root: chess.Board, order: jax.Array) -> State:
    """pgx's state of the position ``root`` with nothing before it, players in ``order`` (White's first)."""
    if root.fen(en_passant="fen") == chess.STARTING_FEN:
        state: Any = _start()
        return state.replace(_player_order=order, current_player=order[0])
    return _jitted_rooted()(_game_state(root), order)


def state_of(board: chess.Board, white_player: int = 0, *, rules_decide: bool = False) -> State:
    """pgx's state after ``board``'s moves, replayed from ``board.root()`` through pgx's jitted step: from the
    standard start by ``env.init``, from any other root as ``pgx.experimental.chess.from_fen`` makes it (its
    history empty); ``white_player`` (0 or 1) is pgx's player who plays White (``env.init`` draws it from its key,
    ``from_fen`` makes it 0). Plies count from the root, whatever its FEN's move number says: pgx ends a game at its
    512th. Where ``rules_decide`` (a player choosing a move), python-chess's rules decide: where pgx has ended a game
    by its own count (fifty moves or a threefold repetition, which python-chess leaves to a claim, or its 512-ply
    cap) and python-chess plays on, the state is rebuilt from the position itself (:func:`rerooted`); else the
    state is pgx's own, ended where pgx ends it. A board pgx cannot hold (Chess960, a variant), a move pgx holds
    illegal, or a move after the game has ended is a ``ValueError``."""
    if board.chess960 or type(board).uci_variant != chess.Board.uci_variant:
        raise ValueError(f"pgx plays standard chess only, not {type(board).uci_variant} (chess960={board.chess960})")
    if white_player not in (0, 1):
        raise ValueError(f"white_player is 0 or 1, not {white_player}")
    order = jnp.int32([white_player, 1 - white_player])
    replay = board.root()
    with jax.enable_x64(False):
        state = _root_state(replay, order)
    for ply, move in enumerate(board.move_stack):
        ended = bool(jax.device_get(state.terminated))
        if ended and rules_decide and not replay.is_game_over():
            state, ended = rerooted(replay, order), False
        if ended or replay.is_game_over():
            raise ValueError(f"the game has ended before the move {move.uci()} (ply {ply + 1} from the root)")
        action = action_of(state, move)
        if not bool(jax.device_get(state._x.legal_action_mask)[action]):
            raise ValueError(f"pgx holds the move {move.uci()} illegal (ply {ply + 1} from the root)")
        state = step(state, action)
        replay.push(move)
    if rules_decide and bool(jax.device_get(state.terminated)) and not replay.is_game_over():
        state = rerooted(replay, order)
    return state


def rerooted(board: chess.Board, order: jax.Array) -> State:
    """pgx's state of ``board``'s position with nothing before it, its halfmove clock kept below pgx's fifty-move
    end (the rules' moves are the same at any clock): where pgx has ended a game python-chess plays on."""
    root = chess.Board(board.fen())
    root.halfmove_clock = min(root.halfmove_clock, 99)
    with jax.enable_x64(False):
        return _root_state(root, order)


def player_state(board: chess.Board) -> State:
    """pgx's state for a player choosing a move on ``board`` (White pgx's player 0): :func:`state_of` with
    python-chess's rules deciding; where the moves cannot be replayed in pgx (a move after an automatic end of
    python-chess's, such as a fivefold repetition, which a GUI may still send; a move pgx does not list), the
    position alone (:func:`rerooted`). A board pgx cannot hold (Chess960, a variant) is a ``ValueError``."""
    try:
        return state_of(board, rules_decide=True)
    except ValueError:
        if board.chess960 or type(board).uci_variant != chess.Board.uci_variant:
            raise
        return rerooted(board, jnp.int32([0, 1]))
