"""Chess endgames as environments: the learner plays White's king and rook (KRK) or queen (KQK) against a defender
that plays the lone black king, every move checked by the rules of :mod:`rlcompare.envs.chess.rules`.

| item        | what happens                                                                                    |
|-------------|-------------------------------------------------------------------------------------------------|
| state       | a White-to-move position, or its class under the board's 8 symmetries (an option)              |
| action      | White's move: a king step (8) or a slide of the piece (7 per direction); illegal ones masked   |
| defender    | ``optimal``: a reply that resists longest (the solver's depth to mate), ties drawn from the run's |
|             | stream; ``random``: a legal reply uniformly; ``mixed-P``: random with probability P, else optimal |
| start       | a won position drawn uniformly (``won``), one at least 3/4 of the longest mate away (``hard``), |
|             | or the position of a FEN (``starts=8/8/8/3k4/8/8/8/KR6 w - - 0 1``)                             |
| reward      | ``mate``: +1 at mate, nothing otherwise; ``moves``: the paper's -1 per move, a move that        |
|             | stalemates or lets the piece be taken costing -(limit + 1); no lost piece beats a game kept    |
| end         | mate (terminated, won); stalemate or the piece taken (terminated, a failure); the move limit,    |
|             | 50 moves, truncates                                                                               |

White's move is the rules' arithmetic on the state's position; the defender's reply is a table lookup, its legal and
its longest-resisting replies bits of one word per Black-to-move position (:func:`reply_table`). A table of White's
moves as well, (states x actions), was slower (KRK, Q-Learning, one core: 4.0 against 5.0 M moves/s): its rows miss
the cache, which the arithmetic does not.
``docs/chess.md`` says why each choice was made.
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import chess
import numpy as np

from rlcompare.compiled import njit
from rlcompare.envs.chess import rules
from rlcompare.envs.chess.endgames import ENDGAMES, HARD_SHARE, REWARDS, STARTS, Options
from rlcompare.envs.chess.solver import solve
from rlcompare.rng import next_below, next_double
from rlcompare.validation import ConfigError


class Endgame(NamedTuple):
    """What compiled code steps: an endgame's tables and its defender."""

    piece: int
    state_of: np.ndarray  # (positions,) int32: the state of each White-to-move position; -1 where illegal
    positions: np.ndarray  # (states - 1,) int64: the position each state plays from (its class's smallest)
    replies: np.ndarray  # (positions,) uint16: Black to move, bit k: its king's step k is legal; bit 8 + k: that step
    # resists longest (a capture of the piece first, then the largest depth to mate); with no legal step, bit 8: mate
    steps: np.ndarray  # (8,) int64: the change of square of each king step
    starts: np.ndarray  # (starts,) int64: the positions episodes start from, drawn uniformly
    random_share: float
    move: float  # the reward of a move that neither mates nor fails
    mate: float  # the reward of the mating move
    failure: float  # the reward of a move that stalemates or loses the piece

    @property
    def n_states(self) -> int:
        return int(self.positions.size) + 1


# --- the tables -------------------------------------------------------------------------------------------


@functools.cache
def make_endgame(options: Options) -> Endgame:
    """The tables of an endgame under ``options`` (read-only; cached)."""
    piece = ENDGAMES[options.endgame].piece
    solution = solve(piece)
    state_of, positions = states(piece, options.symmetries)
    won = np.flatnonzero(solution.white > 0)
    if options.starts == "hard":
        won = won[solution.white[won] >= HARD_SHARE * (2 * ENDGAMES[options.endgame].longest_mate - 1)]
    elif options.starts not in STARTS:
        won = np.array([fen_start(options)])
    steps = np.array([df + 8 * dr for df, dr in rules.KING_STEPS], dtype=np.int64)
    tables = Endgame(piece, state_of.astype(np.int32), positions, reply_table(piece, solution.white),
                     steps, won.astype(np.int64), options.random_share, *REWARDS[options.rewards])
    for array in tables:
        if isinstance(array, np.ndarray):
            array.flags.writeable = False
    return tables


def board_position(endgame: str, board: chess.Board, *, white_to_move: bool = True) -> int:
    """The position index of ``board`` in ``endgame``; a ``ValueError`` naming what is wrong where the board is not a
    legal position of that endgame with that side to move."""
    facts = ENDGAMES[endgame]
    piece, index, white = rules.index_of(board)
    if piece != facts.piece:
        raise ValueError(f"the board is not {facts.name} ({facts.title}): {board.fen()}")
    if white != white_to_move or not rules.is_legal(piece, index, white):
        side = "White" if white_to_move else "Black"
        raise ValueError(f"the board is not a legal {facts.name} position with {side} to move: {board.fen()}")
    return index


def fen_start(options: Options) -> int:
    """The position ``starts=FEN`` names; a :class:`ConfigError` naming what is wrong with it."""
    try:
        return board_position(options.endgame, chess.Board(options.starts))
    except ValueError as error:
        raise ConfigError("env", options.name, f"starts won, hard, or the FEN of a legal {options.endgame} position "
                          f"with White to move ({error})") from None


def symmetric_images(positions: np.ndarray) -> np.ndarray:
    """``(8, n)``: each position under the board's 8 symmetries (identity first): the file and rank flips and the
    reflection in the a1-h8 diagonal, which a board without pawns or castling keeps."""
    wk, wp, bk = positions // 4096, positions // 64 % 64, positions % 64
    images = []
    for flip_file in (False, True):
        for flip_rank in (False, True):
            for transpose in (False, True):
                moved = [_mapped(square, flip_file, flip_rank, transpose) for square in (wk, wp, bk)]
                images.append(moved[0] * 4096 + moved[1] * 64 + moved[2])
    return np.stack(images)


def _mapped(square: np.ndarray, flip_file: bool, flip_rank: bool, transpose: bool) -> np.ndarray:
    file, rank = square % 8, square // 8
    if transpose:
        file, rank = rank, file
    return np.asarray((7 - rank if flip_rank else rank) * 8 + (7 - file if flip_file else file))


def states(piece: int, symmetries: bool) -> tuple[np.ndarray, np.ndarray]:
    """``(state_of, position_of)`` over legal White-to-move positions: with ``symmetries``, one state per class of
    positions the 8 symmetries map onto each other, played from its smallest position; else one per position."""
    positions = np.arange(rules.N_POSITIONS, dtype=np.int64)
    legal = legal_positions(piece, white_to_move=True)
    representative = symmetric_images(positions).min(axis=0) if symmetries else positions
    position_of = np.unique(representative[legal])
    state_of = np.full(rules.N_POSITIONS, -1, dtype=np.int64)
    state_of[legal] = np.searchsorted(position_of, representative[legal])
    return state_of, position_of


@functools.cache
def legal_positions(piece: int, white_to_move: bool) -> np.ndarray:
    """``(positions,)`` bool: the legal positions with this side to move."""
    return _legal_positions(piece, white_to_move)


@njit(cache=True)
def _legal_positions(piece: int, white_to_move: bool) -> np.ndarray:
    legal = np.zeros(rules.N_POSITIONS, np.bool_)
    for index in range(rules.N_POSITIONS):
        legal[index] = rules.is_legal(piece, index, white_to_move)
    return legal


DRAW = 1 << 14
"""A reply's depth to mate where it draws: longer than any mate."""
BEST = 8
"""Where :attr:`Endgame.replies` keeps the longest-resisting replies (and a mate, where no reply is legal)."""


@njit(cache=True)
def reply_table(piece: int, white_dtm: np.ndarray) -> np.ndarray:
    """:attr:`Endgame.replies` of every Black-to-move position (0 where illegal)."""
    table = np.zeros(rules.N_POSITIONS, np.uint16)
    destinations = np.empty(8, np.int64)
    for index in range(rules.N_POSITIONS):
        if not rules.is_legal(piece, index, False):
            continue
        count = rules.black_replies(piece, index, destinations)
        wk, wp, bk = rules.decode(index)
        legal, best, longest = 0, 0, -2
        for k in range(8):
            destination = _king_step(bk, k)
            if destination < 0 or destination not in destinations[:count]:
                continue
            legal |= 1 << k
            depth = DRAW if destination == wp else int(white_dtm[rules.encode(wk, wp, destination)])
            if depth < 0:
                depth = DRAW  # White cannot force mate from there
            if depth > longest:
                longest, best = depth, 1 << k
            elif depth == longest:
                best |= 1 << k
        if legal == 0 and rules.black_in_check(piece, index):
            best = 1
        table[index] = legal | best << BEST
    return table


@njit(inline="always")
def _king_step(square: int, k: int) -> int:
    """The square the king reaches by its step ``k`` (:data:`rules.KING_STEPS`), or -1 off the board."""
    file = square % 8 + rules.KING_STEPS[k][0]
    rank = square // 8 + rules.KING_STEPS[k][1]
    if file < 0 or file > 7 or rank < 0 or rank > 7:
        return -1
    return rank * 8 + file


def legal_moves(tables: Endgame) -> np.ndarray:
    """``(states, actions)`` bool: White's legal moves in each state (every action in the last, ended one)."""
    legal = _legal_moves(tables.piece, tables.positions)
    return np.vstack([legal, np.ones((1, legal.shape[1]), np.bool_)])


@njit(cache=True)
def _legal_moves(piece: int, positions: np.ndarray) -> np.ndarray:
    legal = np.empty((positions.size, rules.n_actions(piece)), np.bool_)
    for state in range(positions.size):
        for action in range(legal.shape[1]):
            legal[state, action] = rules.white_after(piece, positions[state], action) >= 0
    return legal


# --- stepping (the functions of a dynamics module: rlcompare.tabular.steps) ----------------------------------


@njit(inline="always")
def reset(env: Endgame, rng: np.ndarray) -> int:
    """The state of a start position drawn uniformly."""
    return int(np.int64(env.state_of[env.starts[next_below(rng, env.starts.size)]]))


@njit(inline="always")
def _pick(bits: int, rng: np.ndarray) -> int:
    """One of the set bits of ``bits`` (8 of them), uniformly: the only one without a draw."""
    count = 0
    for k in range(8):
        count += (bits >> k) & 1
    pick = 0 if count == 1 else next_below(rng, count)
    for k in range(8):
        if (bits >> k) & 1:
            if pick == 0:
                return k
            pick -= 1
    return -1


@njit(inline="always")
def step(env: Endgame, state: int, action: int, rng: np.ndarray) -> tuple[int, float, bool]:
    """White's ``action`` and the defender's reply: ``(next state, reward, terminated)``."""
    after = rules.white_after(env.piece, int(env.positions[state]), action)
    replies = int(np.int64(env.replies[after]))
    over = env.positions.size
    if replies & 0xFF == 0:  # mate, or stalemate
        return over, (env.mate if replies >> BEST else env.failure), True
    chosen = replies >> BEST & 0xFF
    if env.random_share > 0.0 and (env.random_share >= 1.0 or next_double(rng) < env.random_share):
        chosen = replies & 0xFF
    destination = (after & 63) + env.steps[_pick(chosen, rng)]
    if destination == after >> 6 & 63:  # the piece taken
        return over, env.failure, True
    return int(np.int64(env.state_of[after - (after & 63) + destination])), env.move, False


@njit(inline="always")
def observe(env: Endgame, state: int) -> tuple[int]:
    """The state's index, as a table environment's."""
    return (state,)
