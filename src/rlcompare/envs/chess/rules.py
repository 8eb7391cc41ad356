"""The rules of two chess endgames, king and rook against king (KRK) and king and queen against king (KQK), as
compiled functions: white's moves, black's replies, check and legality (FIDE Laws of Chess, articles 3 and 5).

A position, without the side to move, is three squares numbered as python-chess numbers them (a1 = 0, b1 = 1, ...,
h8 = 63): ``index = white_king * 4096 + white_piece * 64 + black_king``. White's actions are the king's eight
steps (:data:`KING_STEPS`), then the piece's slides, action ``8 + 7 * d + (distance - 1)`` along direction ``d`` of
:data:`ROOK_DIRECTIONS` or :data:`QUEEN_DIRECTIONS`. Black has only its king; a reply onto the piece's square
captures it, which leaves two bare kings, a draw (article 5.2.2, insufficient material). The lone king can never
give check, and no castling or en passant is possible, so a position is legal when its three squares differ, the
kings do not touch, and the side not to move is not in check (article 3.9). These endgames are the classic
subjects of retrograde analysis (Ströhlein 1970; Thompson 1986): :mod:`rlcompare.envs.chess.solver` solves them.
The conversions to and from python-chess's ``Board`` and ``Move`` are plain Python, at the end of the module. The
public functions are inlined into the kernels that call them, and also cached for the calls from Python.
"""

from __future__ import annotations

import chess
import numpy as np

from rlcompare.compiled import njit
from rlcompare.envs.chess.endgames import QUEEN, ROOK

PIECE_TYPES = {ROOK: chess.ROOK, QUEEN: chess.QUEEN}
"""python-chess's piece type of each endgame's white piece."""
N_SQUARES = 64
N_POSITIONS = N_SQUARES**3
KING_STEPS = ((-1, -1), (0, -1), (1, -1), (-1, 0), (1, 0), (-1, 1), (0, 1), (1, 1))
"""The king's steps as (file delta, rank delta): white's actions 0..7, and the order of black's replies."""
ROOK_DIRECTIONS = ((0, 1), (1, 0), (0, -1), (-1, 0))
"""North, east, south, west."""
QUEEN_DIRECTIONS = (*ROOK_DIRECTIONS, (1, 1), (1, -1), (-1, -1), (-1, 1))
"""The rook's directions, then north-east, south-east, south-west, north-west."""
DIRECTIONS = {ROOK: ROOK_DIRECTIONS, QUEEN: QUEEN_DIRECTIONS}
N_KING_STEPS = 8
MAX_DISTANCE = 7


@njit(inline="always", cache=True)
def encode(white_king: int, white_piece: int, black_king: int) -> int:
    """The index of the position with these three squares."""
    return white_king * 4096 + white_piece * 64 + black_king


@njit(inline="always", cache=True)
def decode(index: int) -> tuple[int, int, int]:
    """``(white_king, white_piece, black_king)``, the squares of the position ``index``."""
    return index // 4096, index // 64 % 64, index % 64


@njit(inline="always")
def n_directions(piece: int) -> int:
    """How many directions the piece slides along: 4 for the rook, 8 for the queen."""
    return 4 if piece == ROOK else 8


@njit(inline="always", cache=True)
def n_actions(piece: int) -> int:
    """White's actions: 8 king steps and 7 distances along each of the piece's directions (36 KRK, 64 KQK)."""
    return N_KING_STEPS + MAX_DISTANCE * n_directions(piece)


@njit(inline="always")
def on_board(file: int, rank: int) -> bool:
    """Whether ``(file, rank)`` is a square: both in 0..7."""
    return 0 <= file < 8 and 0 <= rank < 8


@njit(inline="always")
def touching(a: int, b: int) -> bool:
    """Whether squares ``a`` and ``b`` are one king step apart or equal (a king on ``a`` attacks ``b``)."""
    return abs(a % 8 - b % 8) <= 1 and abs(a // 8 - b // 8) <= 1


@njit(inline="always")
def _sign(x: int) -> int:
    return 1 if x > 0 else -1 if x < 0 else 0


@njit(inline="always")
def slider_attacks(piece: int, origin: int, target: int, blocker: int) -> bool:
    """Whether the rook or queen on ``origin`` attacks ``target``, where ``blocker`` (a square, or -1) is the only
    square other than the two that may be occupied."""
    df, dr = target % 8 - origin % 8, target // 8 - origin // 8
    if df == 0 and dr == 0:
        return False
    if df != 0 and dr != 0 and (piece == ROOK or abs(df) != abs(dr)):
        return False
    step = _sign(df) + 8 * _sign(dr)
    square = origin + step
    while square != target:
        if square == blocker:
            return False
        square += step
    return True


@njit(inline="always", cache=True)
def black_in_check(piece: int, index: int) -> bool:
    """Whether the black king is attacked: by the rook or queen (only the white king can block it), or by the white
    king (which only an illegal position has)."""
    white_king, white_piece, black_king = decode(index)
    return touching(white_king, black_king) or slider_attacks(piece, white_piece, black_king, white_king)


@njit(inline="always", cache=True)
def is_legal(piece: int, index: int, white_to_move: bool) -> bool:
    """Three distinct squares, kings not touching, and, with white to move, black not in check (with black to move
    the white king cannot be in check: the black king would touch it)."""
    white_king, white_piece, black_king = decode(index)
    if white_piece in (white_king, black_king) or touching(white_king, black_king):
        return False
    return not white_to_move or not slider_attacks(piece, white_piece, black_king, white_king)


@njit(inline="always", cache=True)
def white_after(piece: int, index: int, action: int) -> int:
    """The position after white plays ``action`` in the legal white-to-move position ``index``, or -1 where the move
    is illegal: off the board, the king onto its own piece or next to the black king, the slide through or onto a
    king."""
    white_king, white_piece, black_king = decode(index)
    if action < N_KING_STEPS:
        df, dr = KING_STEPS[action]
        file, rank = white_king % 8 + df, white_king // 8 + dr
        to = file + 8 * rank
        if not on_board(file, rank) or to == white_piece or touching(to, black_king):
            return -1
        return encode(to, white_piece, black_king)
    direction, distance = divmod(action - N_KING_STEPS, MAX_DISTANCE)
    if direction >= n_directions(piece):
        return -1
    df, dr = QUEEN_DIRECTIONS[direction]
    file, rank = white_piece % 8, white_piece // 8
    for _ in range(distance + 1):
        file, rank = file + df, rank + dr
        square = file + 8 * rank
        if not on_board(file, rank) or square in (white_king, black_king):
            return -1
    return encode(white_king, file + 8 * rank, black_king)


@njit(inline="always", cache=True)
def black_replies(piece: int, index: int, out: np.ndarray) -> int:
    """With black to move in ``index``: the black king's legal destinations into ``out`` (int64, length >= 8), in
    :data:`KING_STEPS` order, and how many. A destination on the white piece's square captures it, legal where the
    white king does not defend it; the king's own square no longer blocks the piece's line behind it."""
    white_king, white_piece, black_king = decode(index)
    count = 0
    for step in range(N_KING_STEPS):
        df, dr = KING_STEPS[step]
        file, rank = black_king % 8 + df, black_king // 8 + dr
        to = file + 8 * rank
        if not on_board(file, rank) or touching(to, white_king):
            continue
        if to != white_piece and slider_attacks(piece, white_piece, to, white_king):
            continue
        out[count] = to
        count += 1
    return count


@njit(cache=True)
def legal_moves_mask(piece: int) -> np.ndarray:
    """``(N_POSITIONS, n_actions(piece))`` bool: True where the action is legal in the legal white-to-move position;
    a whole row False for an illegal position."""
    mask = np.zeros((N_POSITIONS, n_actions(piece)), dtype=np.bool_)
    for index in range(N_POSITIONS):
        if is_legal(piece, index, True):
            for action in range(mask.shape[1]):
                mask[index, action] = white_after(piece, index, action) >= 0
    return mask


def _piece_of(piece: int) -> chess.PieceType:
    if piece not in PIECE_TYPES:
        raise ValueError(f"piece {piece} is neither ROOK ({ROOK}) nor QUEEN ({QUEEN})")
    return PIECE_TYPES[piece]


def _squares_of(index: int) -> tuple[int, int, int]:
    if not 0 <= index < N_POSITIONS:
        raise ValueError(f"index {index} is not a position: 0 <= index < {N_POSITIONS}")
    return index // 4096, index // 64 % 64, index % 64


def material(board: chess.BaseBoard) -> str:
    """The board's material in python-chess's Gaviota notation, the strongest piece first: ``"KRvK"``."""
    return "v".join("".join(chess.piece_symbol(kind).upper() * chess.popcount(board.pieces_mask(kind, color))
                            for kind in reversed(chess.PIECE_TYPES))
                    for color in (chess.WHITE, chess.BLACK))


def board_of(piece: int, index: int, white_to_move: bool) -> chess.Board:
    """python-chess's board of the position (no castling rights, no en passant square, move 1), legal or not; a
    ``ValueError`` where two of its squares coincide."""
    kind = _piece_of(piece)
    white_king, white_piece, black_king = _squares_of(index)
    if len({white_king, white_piece, black_king}) < 3:
        raise ValueError(f"position {index} puts two pieces on one square: white king "
                         f"{chess.square_name(white_king)}, {chess.piece_name(kind)} {chess.square_name(white_piece)},"
                         f" black king {chess.square_name(black_king)}")
    board = chess.Board.empty()
    board.set_piece_at(white_king, chess.Piece(chess.KING, chess.WHITE))
    board.set_piece_at(white_piece, chess.Piece(kind, chess.WHITE))
    board.set_piece_at(black_king, chess.Piece(chess.KING, chess.BLACK))
    board.turn = chess.WHITE if white_to_move else chess.BLACK
    return board


def index_of(board: chess.Board) -> tuple[int, int, bool]:
    """``(piece, index, white_to_move)`` of a python-chess board of KRK or KQK, legal or not. A ``ValueError`` for
    any other material (the lone king must be black: mirror the board, ``board.mirror()``, for the other colour), or
    a board with castling rights."""
    found = material(board)
    kinds = {"KRvK": ROOK, "KQvK": QUEEN}
    if found not in kinds:
        raise ValueError(f"the board holds {found}; only KRvK and KQvK are allowed, white king and rook or queen "
                         f"against the lone black king (board.mirror() gives the other colours'): {board.fen()}")
    if board.clean_castling_rights():
        raise ValueError(f"the board has castling rights, which these endgames leave out: {board.fen()}")
    piece = kinds[found]
    white_king, black_king = board.king(chess.WHITE), board.king(chess.BLACK)
    assert white_king is not None  # the material says so
    assert black_king is not None
    white_piece = chess.SquareSet(board.pieces(PIECE_TYPES[piece], chess.WHITE)).pop()
    return piece, white_king * 4096 + white_piece * 64 + black_king, board.turn == chess.WHITE


def move_of(piece: int, index: int, action: int) -> chess.Move:
    """python-chess's move of white's ``action`` in the position ``index``; a ``ValueError`` where it is no action
    or is illegal there (white to move)."""
    _piece_of(piece)
    white_king, white_piece, _ = _squares_of(index)
    if not 0 <= action < n_actions(piece):
        raise ValueError(f"action {action} is not one of the {n_actions(piece)} actions of piece {piece}")
    after = white_after(piece, index, action) if is_legal(piece, index, True) else -1
    if after < 0:
        raise ValueError(f"action {action} is illegal with white to move in position {index}")
    if action < N_KING_STEPS:
        return chess.Move(white_king, after // 4096)
    return chess.Move(white_piece, after // 64 % 64)


def action_of(piece: int, index: int, move: chess.Move) -> int:
    """White's action playing ``move`` in the position ``index``; a ``ValueError`` where the move is not a king
    step or a slide of the piece, or is illegal there (white to move)."""
    _piece_of(piece)
    white_king, white_piece, _ = _squares_of(index)
    df = chess.square_file(move.to_square) - chess.square_file(move.from_square)
    dr = chess.square_rank(move.to_square) - chess.square_rank(move.from_square)
    action = -1
    if move.promotion is None and move.drop is None and (df, dr) != (0, 0):
        if move.from_square == white_king and (df, dr) in KING_STEPS:
            action = KING_STEPS.index((df, dr))
        elif move.from_square == white_piece and (df == 0 or dr == 0 or abs(df) == abs(dr)):
            direction = (int(np.sign(df)), int(np.sign(dr)))
            if direction in DIRECTIONS[piece]:
                distance = max(abs(df), abs(dr))
                action = N_KING_STEPS + MAX_DISTANCE * QUEEN_DIRECTIONS.index(direction) + distance - 1
    if action < 0:
        raise ValueError(f"{move.uci()} is neither a step of the white king nor a slide of the white piece "
                         f"in position {index}")
    if not is_legal(piece, index, True) or white_after(piece, index, action) < 0:
        raise ValueError(f"{move.uci()} is illegal with white to move in position {index}")
    return action
