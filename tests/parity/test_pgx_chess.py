"""pgx's chess (and Gardner's 5 x 5 minichess) against python-chess, and the conversions of
:mod:`rlcompare.deep.chess.board`.

pgx's legal moves are counted by perft (from the start and from four classic positions, with a vmapped step over
(position, legal action) pairs) and compared move for move on every position of seeded random games; its game
ends and rewards are compared on those games and on a position built for each kind of ending. Where pgx departs
from python-chess, a test here pins the departure (``docs/chess-game.md`` lists them): python-chess's
``outcome(claim_draw=True)`` claims a threefold repetition or the fifty-move rule one ply before the position that
ends the game in pgx; pgx's repetition hash holds the en-passant square after every two-square pawn move; the
first occurrence of the standard start is never counted (pgx's hard-coded hash of it is one JAX no longer draws);
pgx ends a game at its 512th ply; pgx keeps at most 200 moves before its check filter. Gardner's game has no
python-chess of its own: its positions are set on the a1-e5 corner of python-chess's board, where every line
between two squares of the corner stays in it, so that python-chess's moves onto the corner, less the two-square
pawn steps and with a white pawn reaching the fifth rank promoting, are Gardner's.
"""

from __future__ import annotations

import collections
import functools
from dataclasses import dataclass
from typing import Any

import chess
import numpy as np
import pytest

jax = pytest.importorskip("jax")
pytest.importorskip("pgx")

import jax.numpy as jnp  # noqa: E402
import pgx  # noqa: E402
import pgx.gardner_chess as gardner  # noqa: E402
from pgx._src import gardner_chess_utils  # noqa: E402
from pgx._src.games import chess as pgx_rules  # noqa: E402
from pgx.chess import State  # noqa: E402
from pgx.experimental.chess import from_fen  # noqa: E402

from rlcompare.deep.chess import board as cb  # noqa: E402

BATCH = 64
"""States per call of the vmapped step: the random games, and the chunks of perft's (position, action) pairs."""
N_GAMES = BATCH
SEED = 7
PERFT = {
    "start": (chess.STARTING_FEN, (20, 400, 8_902, 197_281)),
    "kiwipete": ("r3k2r/p1ppqpb1/bn2pnp1/3PN3/1p2P3/2N2Q1p/PPPBBPPP/R3K2R w KQkq - 0 1", (48, 2_039, 97_862)),
    "position 3": ("8/2p5/3p4/KP5r/1R3p1k/8/4P1P1/8 w - - 0 1", (14, 191, 2_812, 43_238)),
    "position 4": ("r3k2r/Pppp1ppp/1b3nbN/nP6/BBP1P3/q4N2/Pp1P2PP/R2Q1RK1 w kq - 0 1", (6, 264, 9_467)),
    "position 5": ("rnbq1k1r/pp1Pbppp/2p5/8/2B5/8/PPP1NnPP/RNBQK2R w KQ - 1 8", (44, 1_486, 62_379)),
}
"""Perft counts per depth, as published (chessprogramming.org, "Perft Results"): castling, en passant (with the
pin along the rank in position 3), promotions and underpromotions, checks and pins."""
STEPS = "replays moves through pgx's jitted step, compiled in seconds once per process"
ROOT = "builds a root from a FEN in pgx (a jitted program compiled in seconds once per process) and steps from it"
GARDNER = "plays Gardner's minichess through its jitted step, compiled in seconds once per process"


def _host_state(board: np.ndarray, white: bool) -> State:
    """A pgx state holding only the board and the side to move, host-side: what :func:`cb.move_of` and
    :func:`cb.action_of` read."""
    return State(_x=pgx_rules.GameState(board=board, color=np.int32(0 if white else 1)))


def _push_all(board: chess.Board, moves: str) -> chess.Board:
    for uci in moves.split():
        board.push_uci(uci)
    return board


def _played(moves: str, fen: str = chess.STARTING_FEN) -> chess.Board:
    return _push_all(chess.Board(fen), moves)


# --- Perft ---

@functools.cache
def _batch_step() -> Any:
    """pgx's ``env.step``, vmapped over :data:`BATCH` states and jitted, once per process."""
    return jax.jit(jax.vmap(cb.env().step))


def _pgx_perft(root: State, depth: int) -> list[int]:
    """The moves by pgx's rules at each depth 1..``depth`` from ``root``: each level's (position, legal action) pairs
    stepped in chunks of :data:`BATCH`; the last count is the sum of the legal moves of the positions at
    ``depth - 1`` (kept only as counts)."""
    level = jax.tree.map(lambda leaf: leaf[None], root)
    counts = [int(np.asarray(level._x.legal_action_mask).sum())]
    for depth_now in range(2, depth + 1):
        rows, actions = np.nonzero(np.asarray(level._x.legal_action_mask))
        parts, count = [], 0
        for start in range(0, len(rows), BATCH):
            n = len(rows[start:start + BATCH])
            pad = BATCH - n
            chunk_rows = np.concatenate([rows[start:start + n], np.repeat(rows[start], pad)])
            chunk_actions = np.concatenate([actions[start:start + n], np.repeat(actions[start], pad)])
            stepped = _batch_step()(jax.tree.map(lambda leaf, r=chunk_rows: leaf[r], level),
                                    jnp.asarray(chunk_actions, dtype=jnp.int32))
            masks, terminated = jax.device_get((stepped._x.legal_action_mask[:n], stepped.terminated[:n]))
            assert not (terminated & masks.any(axis=1)).any(), "a position ended by a draw rule: perft would stop"
            count += int(masks.sum())
            if depth_now < depth:
                parts.append(jax.tree.map(lambda leaf, n=n: leaf[:n], stepped))
        counts.append(count)
        if depth_now < depth:
            level = jax.tree.map(lambda *leaves: jnp.concatenate(leaves), *parts)
    return counts


def _python_chess_perft(board: chess.Board, depth: int) -> list[int]:
    counts = [0] * depth

    def walk(level: int) -> None:
        moves = list(board.legal_moves)
        counts[level] += len(moves)
        if level + 1 < depth:
            for move in moves:
                board.push(move)
                walk(level + 1)
                board.pop()

    walk(0)
    return counts


@pytest.mark.slow("pgx's step on 9,322 positions, vmapped (compiles once), and python-chess's perft")
def test_perft_from_the_start():
    """20, 400, 8,902 and 197,281 moves at depths 1-4, in pgx from ``env.init`` and in python-chess."""
    expected = list(PERFT["start"][1])
    assert _python_chess_perft(chess.Board(), 4) == expected
    assert _pgx_perft(cb.state_of(chess.Board()), 4) == expected


@pytest.mark.slow("pgx's step on 6,500 positions and python-chess's perft")
@pytest.mark.parametrize("name", [name for name in PERFT if name != "start"])
def test_perft_from_classic_positions(name):
    """The published counts, in pgx (the root by :func:`cb.state_of`) and in python-chess."""
    fen, expected = PERFT[name]
    assert _python_chess_perft(chess.Board(fen), len(expected)) == list(expected)
    assert _pgx_perft(cb.state_of(chess.Board(fen)), len(expected)) == list(expected)


# --- Seeded random games ---

@dataclass
class Ply:
    """pgx's view of one position of a random game, host-side."""

    board: np.ndarray
    white: bool
    legal: np.ndarray
    """The actions legal by the rules (pgx's ``_x.legal_action_mask``, which a draw leaves as it is)."""
    terminated: bool
    rewards: np.ndarray
    current_player: int
    action: int = -1
    """The action played from here (-1 at the end)."""


@dataclass
class Game:
    order: tuple[int, int]
    """pgx's players of White and Black (``_player_order``), as ``env.init`` drew them."""
    plies: list[Ply]

    def board(self) -> chess.Board:
        """python-chess's board at the game's end."""
        board = chess.Board()
        for ply in self.plies[:-1]:
            board.push(cb.move_of(_host_state(ply.board, ply.white), ply.action))
        return board


@functools.cache
def _chess_games() -> tuple[list[Game], State]:
    """:data:`N_GAMES` games of uniformly random legal moves, played together by the vmapped step from
    ``env.init`` (each game's players drawn by its key) until each ends, and pgx's batched state at the end."""
    generator = np.random.default_rng(SEED)
    state = jax.jit(jax.vmap(cb.env().init))(jax.random.split(jax.random.PRNGKey(SEED), N_GAMES))
    orders = np.asarray(state._player_order)
    games = [Game(order=(int(orders[i, 0]), int(orders[i, 1])), plies=[]) for i in range(N_GAMES)]
    live = np.ones(N_GAMES, dtype=bool)
    while live.any():
        board, color, mask, terminated, rewards, current = jax.device_get((
            state._x.board, state._x.color, state._x.legal_action_mask, state.terminated, state.rewards,
            state.current_player))
        actions = np.zeros(N_GAMES, dtype=np.int32)
        for i in np.flatnonzero(live):
            legal = np.flatnonzero(mask[i]).astype(np.int16)
            ply = Ply(board[i].astype(np.int8), bool(color[i] == 0), legal, bool(terminated[i]), rewards[i],
                      int(current[i]))
            games[i].plies.append(ply)
            if terminated[i]:
                live[i] = False
                continue
            ply.action = actions[i] = int(generator.choice(legal))
        state = _batch_step()(state, jnp.asarray(actions))
    return games, state


@pytest.mark.slow("plays 64 random games in pgx (compiles the vmapped step) and converts every legal move")
def test_random_games_legal_moves_equal_python_chess():
    """On every position of the games, ended ones included, the moves legal by pgx's rules are python-chess's
    ``board.legal_moves``, through :func:`cb.move_of`; and ``action_of(move_of(a)) == a`` for each."""
    games, _ = _chess_games()
    positions = 0
    for game in games:
        board = chess.Board()
        for ply in game.plies:
            state = _host_state(ply.board, ply.white)
            moves = {int(action): cb.move_of(state, int(action)) for action in ply.legal}
            assert set(moves.values()) == set(board.legal_moves), board.fen()
            for action, move in moves.items():
                assert cb.action_of(state, move) == action
            if ply.action >= 0:
                board.push(moves[ply.action])
            positions += 1
    assert positions > 15_000


def _pgx_key(board: chess.Board) -> str:
    """The position as pgx's repetition hash tells positions apart: placement, side to move, castling rights and
    the en-passant square after every two-square pawn move (python-chess's ``ep_square``, legal capture or not)."""
    return board.epd(en_passant="fen")


def _claim_departure(board: chess.Board, pgx_count: int, terminated: bool) -> str | None:
    """Why python-chess's ``outcome(claim_draw=True)`` and pgx's ``terminated`` differ on ``board`` (None where
    they agree); ``pgx_count`` is the number of times pgx's hash has seen the position."""
    outcome = board.outcome(claim_draw=True)
    if (outcome is not None) == terminated:
        return None
    if terminated:
        return "pgx's ply cap" if board.ply() == pgx_rules.MAX_TERMINATION_STEPS else "unexplained end in pgx"
    assert outcome is not None
    if outcome.termination == chess.Termination.FIFTY_MOVES and board.halfmove_clock == 99:
        return "fifty-move claim a ply early"
    if outcome.termination == chess.Termination.THREEFOLD_REPETITION:
        if not board.is_repetition(3):
            return "threefold claim a ply early"
        if board.epd() == chess.Board().epd() and pgx_count == 2:
            return "the start's first occurrence"
        return "en passant in pgx's hash"
    return f"unexplained claim of {outcome.termination.name}"


@pytest.mark.slow("plays 64 random games in pgx and asks python-chess for a claimable draw at every position")
def test_random_games_end_as_python_chess():
    """pgx ends a game exactly where the rules as pgx has them say so (no legal move, insufficient material,
    100 half-moves without a capture or a pawn move, a third occurrence as pgx's hash tells positions apart (the
    start's first occurrence not counted), the 512th ply); the mated side's player gets -1 and the other +1, every
    other end 0 each; and where python-chess's ``outcome(claim_draw=True)`` differs, it is one of the departures
    pinned below."""
    games, _ = _chess_games()
    ends: collections.Counter[str] = collections.Counter()
    departures: collections.Counter[str] = collections.Counter()
    for game in games:
        board = chess.Board()
        seen: collections.Counter[str] = collections.Counter()  # the start's first occurrence: not counted
        for ply in game.plies:
            key = _pgx_key(board)
            if board.ply():
                seen[key] += 1
            expected = (not ply.legal.size or board.is_insufficient_material() or board.halfmove_clock >= 100
                        or seen[key] >= 3 or board.ply() >= pgx_rules.MAX_TERMINATION_STEPS)
            assert ply.terminated == expected, (board.fen(), board.ply())
            assert ply.current_player == game.order[0 if ply.white else 1]
            departure = _claim_departure(board, seen[key], ply.terminated)
            if departure is not None:
                departures[departure] += 1
            if ply.terminated:
                outcome = board.outcome(claim_draw=True)
                if board.is_checkmate():
                    assert ply.rewards[ply.current_player] == -1
                    assert ply.rewards[1 - ply.current_player] == 1
                else:
                    assert (ply.rewards == 0).all()
                ends[outcome.termination.name if outcome else "pgx's ply cap"] += 1
                assert board.ply() <= pgx_rules.MAX_TERMINATION_STEPS
                break
            board.push(cb.move_of(_host_state(ply.board, ply.white), ply.action))
    assert sum(ends.values()) == N_GAMES
    assert set(departures) <= {"fifty-move claim a ply early", "threefold claim a ply early", "pgx's ply cap",
                               "en passant in pgx's hash", "the start's first occurrence"}, departures
    assert {"CHECKMATE", "STALEMATE", "INSUFFICIENT_MATERIAL", "FIFTY_MOVES", "THREEFOLD_REPETITION",
            "pgx's ply cap"} <= set(ends), ends
    assert {"fifty-move claim a ply early", "threefold claim a ply early", "pgx's ply cap"} <= set(departures)
    assert departures["pgx's ply cap"] == ends["pgx's ply cap"]


@pytest.mark.slow("replays four random games through the jitted step")
def test_state_of_equals_pgx_state_after_the_same_moves():
    """:func:`cb.state_of` of the games' last boards (the longest, and a mate) is pgx's own state after the same
    moves from ``env.init``: board, history of boards and hashes, counters, legal mask, observation, players."""
    games, final = _chess_games()
    longest = sorted(range(N_GAMES), key=lambda i: -len(games[i].plies))[:3]
    mated = next(i for i, game in enumerate(games) if game.plies[-1].terminated and not game.plies[-1].legal.size
                 and game.board().is_check())
    for i in [*longest, mated]:
        game = games[i]
        board = game.board()
        state = cb.state_of(board, white_player=game.order[0])
        theirs = jax.tree.map(lambda leaf, i=i: leaf[i], final)
        for name in ("current_player", "terminated", "truncated", "legal_action_mask", "observation", "_step_count",
                     "_player_order"):
            np.testing.assert_array_equal(getattr(state, name), getattr(theirs, name), err_msg=name)
        for name, leaf in state._x._asdict().items():
            np.testing.assert_array_equal(leaf, getattr(theirs._x, name), err_msg=name)
        np.testing.assert_array_equal(state.rewards, game.plies[-1].rewards)  # stepping an ended game zeroes them
        assert cb.fen_of(state) == board.fen(en_passant="fen")
        assert cb.legal_moves(state) == {move.uci() for move in board.legal_moves}


# --- Conversions ---

def test_every_action_round_trips():
    """Every action on the board, for either side, from a pawn on its seventh rank or any other piece:
    ``action_of(move_of(a)) == a``, and the promotion piece is pgx's (underpromotion planes, else a queen for a pawn
    stepping onto the last rank)."""
    from_planes = np.asarray(pgx_rules.FROM_PLANE)
    for white in (True, False):
        for pawn in (True, False):
            board = np.zeros(64, dtype=np.int8)
            board[np.arange(64) % 8 == 6] = 1 if pawn else 2
            state = _host_state(board, white)
            for action in range(cb.N_ACTIONS):
                start, plane = divmod(action, 73)
                if from_planes[start, plane] < 0:
                    with pytest.raises(ValueError, match="leaves the board"):
                        cb.move_of(state, action)
                    continue
                move = cb.move_of(state, action)
                assert cb.action_of(state, move) == action
                if plane < 9:
                    assert move.promotion == cb.UNDERPROMOTIONS[plane // 3]
                else:
                    assert (move.promotion == chess.QUEEN) == (pawn and start % 8 == 6)
    state = _host_state(np.asarray(pgx_rules.INIT_BOARD), True)
    assert cb.move_of(state, 89) == chess.Move.from_uci("a2a3")
    assert cb.move_of(state, 90) == chess.Move.from_uci("a2a4")
    with pytest.raises(ValueError, match="no pgx action"):
        cb.action_of(state, chess.Move.null())
    with pytest.raises(ValueError, match="no pgx action"):
        cb.action_of(state, chess.Move.from_uci("a1c4"))
    with pytest.raises(ValueError, match="not one of pgx's chess actions"):
        cb.move_of(state, cb.N_ACTIONS)


@pytest.mark.slow(ROOT)
def test_castling_and_promotions_convert():
    """White castles short and Black long (the king's two-square move), a pawn underpromotes and one queens by
    capturing: each move is its action's, and the position pgx reaches is python-chess's."""
    board = chess.Board("r3k3/P7/8/8/8/8/1p6/R3K2R w KQq - 0 1")
    for uci in ("e1g1", "e8c8", "a7a8n", "b2a1q"):
        state = cb.state_of(board)
        move = chess.Move.from_uci(uci)
        assert uci in cb.legal_moves(state)
        assert cb.move_of(state, cb.action_of(state, move)) == move
        board.push(move)
        assert cb.fen_of(cb.state_of(board)) == board.fen(en_passant="fen")
    assert board.board_fen() == "N1kr4/8/8/8/8/8/8/q4RK1"


@pytest.mark.slow("pgx's from_fen compiles three programs at every call")
@pytest.mark.parametrize("fen", ["r3k2r/p1ppqpb1/bn2pnp1/3PN3/1p2P3/2N2Q1p/PPPBBPPP/R3K2R w KQkq - 0 1",
                                 "rnbqkbnr/ppp1pppp/8/8/3pP3/8/PPPP1PPP/RNBQKBNR b Kq e3 0 3"])
def test_a_fen_root_is_from_fens_state_with_an_empty_history(fen):
    """From a root other than the start, :func:`cb.state_of` is ``from_fen``'s state (board, side, castling,
    en passant, counters, legal mask, hash, the current position's and the counters' planes), except that
    ``from_fen`` leaves the standard start in its history as the position before (pinned here) and
    :func:`cb.state_of` leaves it empty."""
    ours, theirs = cb.state_of(chess.Board(fen)), from_fen(fen)
    for name, leaf in ours._x._asdict().items():
        if name in ("hash_history", "board_history"):
            np.testing.assert_array_equal(leaf[0], getattr(theirs._x, name)[0], err_msg=name)
            assert not np.asarray(leaf[1:]).any()
        else:
            np.testing.assert_array_equal(leaf, getattr(theirs._x, name), err_msg=name)
    np.testing.assert_array_equal(theirs._x.board_history[1], pgx_rules.INIT_BOARD)
    np.testing.assert_array_equal(theirs._x.hash_history[1], pgx_rules.INIT_ZOBRIST_HASH)
    np.testing.assert_array_equal(ours.observation[..., :14], theirs.observation[..., :14])
    np.testing.assert_array_equal(ours.observation[..., 112:], theirs.observation[..., 112:])
    for name in ("current_player", "terminated", "rewards", "legal_action_mask", "_player_order"):
        np.testing.assert_array_equal(getattr(ours, name), getattr(theirs, name), err_msg=name)
    assert cb.fen_of(ours) == fen


def test_state_of_refuses_other_games():
    with pytest.raises(ValueError, match="standard chess only"):
        cb.state_of(chess.Board(chess960=True))
    with pytest.raises(ValueError, match="white_player"):
        cb.state_of(chess.Board(), white_player=2)


@pytest.mark.slow(STEPS)
def test_state_of_refuses_moves_pgx_cannot_play():
    board = chess.Board()
    board.push(chess.Move.from_uci("e2e5"))  # python-chess's push takes any move
    with pytest.raises(ValueError, match="illegal"):
        cb.state_of(board)
    board = _played("f2f3 e7e5 g2g4 d8h4")
    board.push(chess.Move.from_uci("e1f2"))
    with pytest.raises(ValueError, match="has ended"):
        cb.state_of(board)


# --- Game ends on built positions ---

@pytest.mark.slow(STEPS)
@pytest.mark.parametrize("white_player", [0, 1])
@pytest.mark.parametrize(("moves", "winner"), [("f2f3 e7e5 g2g4 d8h4", chess.BLACK),
                                                ("e2e4 e7e5 f1c4 b8c6 d1h5 g8f6 h5f7", chess.WHITE)])
def test_checkmate_rewards_the_mover_and_punishes_the_mated(moves, winner, white_player):
    """Fool's mate and scholar's mate, with either player as White: the mated side's player gets -1, the mover's
    +1, and the game has ended with no legal move."""
    board = _played(moves)
    state = cb.state_of(board, white_player=white_player)
    assert board.outcome(claim_draw=True).winner == winner
    winner_player = white_player if winner == chess.WHITE else 1 - white_player
    assert bool(state.terminated)
    assert not cb.legal_moves(state)
    assert int(state.current_player) == 1 - winner_player
    assert state.rewards.tolist() == [1.0 if player == winner_player else -1.0 for player in (0, 1)]


@pytest.mark.slow(STEPS)
def test_stalemate_is_a_draw():
    """Loyd's ten-move stalemate: ended, no legal move, no check, 0 each."""
    board = _played("e2e3 a7a5 d1h5 a8a6 h5a5 h7h5 h2h4 a6h6 a5c7 f7f6 c7d7 e8f7 d7b7 d8d3 b7b8 d3h7 b8c8 f7g6 c8e6")
    state = cb.state_of(board)
    assert board.is_stalemate()
    assert bool(state.terminated)
    assert not cb.legal_moves(state)
    assert state.rewards.tolist() == [0.0, 0.0]


def _after_a_capture(white: str, black: str) -> chess.Board:
    """White's king takes a black rook on e2; left: White's king and ``white`` ({square: piece letter}),
    Black's king on h8 and ``black``."""
    board = chess.Board(None)
    pieces = {"e1": "K", "e2": "r", "h8": "k", **dict(item.split("=") for item in white.split()),
              **dict(item.split("=") for item in black.split())}
    for square, letter in pieces.items():
        board.set_piece_at(chess.parse_square(square), chess.Piece.from_symbol(letter))
    board.push_uci("e1e2")
    return board


@pytest.mark.slow(ROOT)
@pytest.mark.parametrize(("white", "black", "insufficient"), [
    ("", "", True),  # K v K
    ("c1=B", "", True),  # KB v K
    ("b1=N", "", True),  # KN v K
    ("c1=B", "f8=b", True),  # bishops on dark squares both
    ("c1=B a3=B", "", True),  # two bishops on dark squares
    ("c1=B", "c8=b", False),  # bishops on squares of two colours
    ("c1=B f1=B", "", False),  # the bishop pair
    ("b1=N", "b8=n", False),  # KN v KN: a mate can be helped
    ("c1=B", "b8=n", False),  # KB v KN
    ("b1=N g1=N", "", False),  # KNN v K
    ("b1=N", "d8=q", False),  # KN v KQ
    ("a2=P", "", False),
])
def test_insufficient_material_is_python_chess_s(white, black, insufficient):
    """pgx's insufficient material (OpenSpiel's condition: K v K, a lone knight or bishop, bishops all on one
    colour) ends the game exactly where python-chess's ``is_insufficient_material`` holds."""
    board = _after_a_capture(white, black)
    state = cb.state_of(board)
    assert board.is_insufficient_material() == insufficient
    assert bool(state.terminated) == insufficient
    assert (board.outcome(claim_draw=True) is not None) == insufficient
    assert state.rewards.tolist() == [0.0, 0.0]


@pytest.mark.slow(ROOT)
def test_fifty_move_rule_ends_at_the_hundredth_half_move_and_python_chess_claims_a_ply_earlier():
    """At 99 half-moves without a capture or a pawn move pgx plays on, where ``outcome(claim_draw=True)`` already
    claims (the mover may announce a move that makes 100); at 100 both end it. A mate on the 100th half-move is a
    mate in both, and pgx rewards it."""
    board = chess.Board("7k/8/8/8/8/8/8/R3K3 w - - 98 80")
    board.push_uci("a1a2")
    assert board.halfmove_clock == 99
    assert board.outcome(claim_draw=True).termination == chess.Termination.FIFTY_MOVES
    assert not bool(cb.state_of(board).terminated)
    board.push_uci("h8g8")
    state = cb.state_of(board)
    assert bool(state.terminated)
    assert state.rewards.tolist() == [0.0, 0.0]
    assert board.outcome(claim_draw=True).termination == chess.Termination.FIFTY_MOVES
    mate = _played("h1h8", "k7/8/1K6/8/8/8/8/7R w - - 99 80")
    state = cb.state_of(mate, white_player=1)
    assert mate.halfmove_clock == 100
    assert mate.outcome(claim_draw=True).termination == chess.Termination.CHECKMATE
    assert bool(state.terminated)
    assert state.rewards.tolist() == [-1.0, 1.0]


KNIGHTS_OUT_AND_BACK = "g1f3 g8f6 f3g1 f6g8"


@pytest.mark.slow(STEPS)
def test_threefold_repetition_ends_at_the_third_occurrence_and_python_chess_claims_a_ply_earlier():
    """After 1. e3 e6, the knights out and back twice: the position's third occurrence (ply 10) ends the game in
    both; at ply 9 python-chess already claims (the move about to repeat it), pgx plays on."""
    opening = "e2e3 e7e6 "
    board = _played(opening + KNIGHTS_OUT_AND_BACK + " g1f3 g8f6 f3g1")
    assert board.outcome(claim_draw=True).termination == chess.Termination.THREEFOLD_REPETITION
    assert not board.is_repetition(3)
    assert not bool(cb.state_of(board).terminated)
    board.push_uci("f6g8")
    state = cb.state_of(board)
    assert board.is_repetition(3)
    assert bool(state.terminated)
    assert state.rewards.tolist() == [0.0, 0.0]


@pytest.mark.slow(STEPS)
def test_the_start_s_first_occurrence_is_not_counted():
    """pgx's first hash, of the start, is a constant (``INIT_ZOBRIST_HASH``) computed with JAX's former random
    bits: since JAX 0.5 (``jax_threefry_partitionable`` on) the start hashes otherwise, so its first occurrence
    matches nothing: the start's third occurrence ends nothing in pgx."""
    assert jax.config.jax_threefry_partitionable
    start = np.asarray(jax.jit(pgx_rules._zobrist_hash)(pgx_rules.GameState()))
    assert (start != np.asarray(pgx_rules.INIT_ZOBRIST_HASH)).all()
    board = _played(f"{KNIGHTS_OUT_AND_BACK} {KNIGHTS_OUT_AND_BACK}")
    assert board.is_repetition(3)
    assert board.outcome(claim_draw=True) is not None
    assert not bool(cb.state_of(board).terminated)
    board.push_uci("g1f3")  # the position after 1. Nf3, its third occurrence, ends it
    assert board.is_repetition(3)
    assert bool(cb.state_of(board).terminated)


@pytest.mark.slow(ROOT)
def test_en_passant_square_counts_in_pgx_repetitions_even_without_a_legal_capture():
    """After 1. e4 pgx's hash holds e3 although no black pawn can take there; python-chess counts the position
    as the same one without it (as FIDE does). With the knights out and back twice, python-chess's third
    occurrence of that position (ply 9) ends nothing in pgx. Where the capture is legal, both tell the positions
    apart and agree."""
    board = _played("e2e4 g8f6 g1f3 f6g8 f3g1 g8f6 g1f3 f6g8 f3g1")
    assert board.is_repetition(3)
    state = cb.state_of(board)
    assert not bool(state.terminated)
    board.push_uci("g8f6")  # the position after 1... Nf6, its third occurrence, ends it in both
    assert board.is_repetition(3)
    assert bool(cb.state_of(board).terminated)
    fen = "4k3/8/8/8/3p4/8/4P3/4K1N1 w - - 0 1"
    assert _played("e2e4", fen).has_legal_en_passant()
    legal_capture = _played("e2e4 e8d8 g1f3 d8e8 f3g1 e8d8 g1f3 d8e8 f3g1", fen)
    assert not legal_capture.is_repetition(3)
    assert not bool(cb.state_of(legal_capture).terminated)


@pytest.mark.slow(STEPS)
def test_pgx_ends_a_game_at_its_512th_ply():
    """pgx terminates (not truncates) a game at its 512th ply, as a draw; python-chess plays on."""
    board = _played("e2e4 e7e5")
    state = cb.state_of(board)
    state = state.replace(_x=state._x._replace(step_count=jnp.int32(pgx_rules.MAX_TERMINATION_STEPS - 1)))
    state = cb.step(state, cb.action_of(state, chess.Move.from_uci("g1f3")))
    board.push_uci("g1f3")
    assert bool(state.terminated)
    assert not bool(state.truncated)
    assert state.rewards.tolist() == [0.0, 0.0]
    assert board.outcome(claim_draw=True) is None
    assert cb.legal_moves(state) == {m.uci() for m in board.legal_moves}


@pytest.mark.slow(ROOT)
@pytest.mark.parametrize(("fen", "moves"), [
    ("8/8/8/4k3/8/8/R7/4K3 w - - 100 80", ""),  # fifty moves: python-chess leaves the draw to a claim
    (chess.STARTING_FEN, "g1f3 g8f6 f3g1 f6g8 g1f3 g8f6 f3g1 f6g8 g1f3"),  # a threefold repetition: the same
])
def test_a_game_pgx_ended_and_the_rules_go_on_with_is_rebuilt_with_the_rules_moves(fen, moves):
    board = _played(moves, fen) if moves else chess.Board(fen)
    assert bool(cb.state_of(board).terminated)  # pgx's own replay ends it
    state = cb.state_of(board, rules_decide=True)
    assert not bool(state.terminated)
    assert cb.legal_moves(state) == {m.uci() for m in board.legal_moves}
    assert cb.fen_of(state).split()[:4] == board.fen(en_passant="fen").split()[:4]


@pytest.mark.slow(ROOT)
def test_pgx_keeps_at_most_200_moves_before_its_check_filter():
    """A position with 218 legal moves: pgx lists 200 of them (its pseudo-legal moves are cut at 200), all
    legal."""
    board = chess.Board("R6R/3Q4/1Q4Q1/4Q3/2Q4Q/Q4Q2/pp1Q4/kBNN1KB1 w - - 0 1")
    moves = cb.legal_moves(cb.state_of(board))
    assert board.legal_moves.count() == 218
    assert len(moves) == 200
    assert moves <= {move.uci() for move in board.legal_moves}


@pytest.mark.slow(STEPS)
def test_pgx_fen_names_every_en_passant_square():
    """pgx's FEN (and hash) names the square a pawn passed over whatever can take there; python-chess's FEN only
    where a capture is legal (``en_passant="fen"`` gives pgx's)."""
    board = _played("e2e4")
    state = cb.state_of(board)
    assert cb.fen_of(state) == board.fen(en_passant="fen") != board.fen()
    assert cb.board_of(state).ep_square == chess.E3


# --- Gardner's 5 x 5 minichess ---

GARDNER_START = "8/8/8/rnbqk3/ppppp3/8/PPPPP3/RNBQK3 w - - 0 1"
"""Gardner's start, ``rnbqk/ppppp/5/PPPPP/RNBQK``, on python-chess's a1-e5."""
CORNER = chess.SquareSet(chess.BB_FILE_A | chess.BB_FILE_B | chess.BB_FILE_C | chess.BB_FILE_D | chess.BB_FILE_E) \
    & chess.SquareSet(chess.BB_RANK_1 | chess.BB_RANK_2 | chess.BB_RANK_3 | chess.BB_RANK_4 | chess.BB_RANK_5)
PROMOTIONS = (chess.QUEEN, chess.ROOK, chess.BISHOP, chess.KNIGHT)


@functools.cache
def _gardner() -> tuple[Any, Any, Any]:
    env = pgx.make("gardner_chess")
    return env, jax.jit(env.init), jax.jit(env.step)


def _gardner_square(index: int, white: bool) -> chess.Square:
    file, rank = divmod(index, 5)
    return chess.square(file, rank if white else 4 - rank)


def _gardner_move(board: np.ndarray, white: bool, action: int) -> chess.Move:
    """python-chess's move (on the a1-e5 corner) of Gardner's ``action``: ``from * 49 + plane``, planes 0-8
    underpromotions, a pawn onto the last rank by another plane a queen."""
    start, plane = divmod(action, 49)
    end = int(np.asarray(gardner_chess_utils.TO_MAP)[start, plane])
    assert end >= 0
    promotion = cb.UNDERPROMOTIONS[plane // 3] if plane < 9 else (
        chess.QUEEN if board[start] == 1 and start % 5 == 3 else None)
    return chess.Move(_gardner_square(start, white), _gardner_square(end, white), promotion)


def _gardner_moves(state: Any) -> dict[str, int]:
    board, turn, mask = jax.device_get((state._board, state._turn, state.legal_action_mask))
    return {_gardner_move(board, turn == 0, int(a)).uci(): int(a) for a in np.flatnonzero(mask)}


def _corner_moves(board: chess.Board) -> set[str]:
    """Gardner's legal moves by python-chess: its moves onto the corner, without two-square pawn steps, a white
    pawn onto the fifth rank promoting (Black's promote on the first rank already)."""
    moves = set()
    for move in board.legal_moves:
        if move.to_square not in CORNER:
            continue
        pawn = board.piece_type_at(move.from_square) == chess.PAWN
        if pawn and abs(chess.square_rank(move.to_square) - chess.square_rank(move.from_square)) == 2:
            continue
        if pawn and board.turn == chess.WHITE and chess.square_rank(move.to_square) == 4:
            moves |= {chess.Move(move.from_square, move.to_square, piece).uci() for piece in PROMOTIONS}
        else:
            moves.add(move.uci())
    return moves


def _gardner_played(moves: str, key: int = 0) -> tuple[Any, chess.Board]:
    """Gardner's state and the corner board after ``moves`` (UCI) from the start."""
    _, init, step = _gardner()
    state, board = init(jax.random.PRNGKey(key)), chess.Board(GARDNER_START)
    for uci in moves.split():
        state = step(state, jnp.int32(_gardner_moves(state)[uci]))
        board.push(chess.Move.from_uci(uci))  # python-chess's push_uci would refuse a promotion on the fifth rank
    return state, board


@functools.cache
def _gardner_games() -> list[tuple[list[str], list[tuple[bool, dict[str, int], int, np.ndarray, int]]]]:
    """40 seeded random games of Gardner's: per game the moves, and per position (ended, legal moves, current
    player, rewards, ply)."""
    _, init, step = _gardner()
    generator = np.random.default_rng(SEED)
    games = []
    for game in range(40):
        state, moves, positions = init(jax.random.PRNGKey(game)), [], []
        while True:
            terminated, rewards, current, ply = jax.device_get((state.terminated, state.rewards,
                                                                state.current_player, state._step_count))
            legal = {} if terminated else _gardner_moves(state)
            positions.append((bool(terminated), legal, int(current), rewards, int(ply)))
            if terminated:
                break
            moves.append(str(generator.choice(sorted(legal))))
            state = step(state, jnp.int32(legal[moves[-1]]))
        games.append((moves, positions))
    return games


@pytest.mark.slow("plays 40 random games of Gardner's minichess in pgx (compiles its step)")
def test_gardner_random_games_equal_python_chess_on_a_corner():
    """On every position of 40 random games: Gardner's legal moves are python-chess's on the corner; the game
    ends exactly at no legal move, insufficient material, 100 half-moves without capture or pawn move, a third
    occurrence (the start's first included) or the 256th ply; a mate gives the mated side's player -1."""
    ends: collections.Counter[str] = collections.Counter()
    for moves, positions in _gardner_games():
        board = chess.Board(GARDNER_START)
        for index, (terminated, legal, current, rewards, ply) in enumerate(positions):
            corner = _corner_moves(board)
            if not terminated:
                assert set(legal) == corner, board.fen()
            kind = ("checkmate" if board.is_check() else "stalemate") if not corner else \
                "insufficient material" if board.is_insufficient_material() else \
                "fifty moves" if board.halfmove_clock >= 100 else \
                "threefold repetition" if board.is_repetition(3) else \
                "ply cap" if ply >= gardner.MAX_TERMINATION_STEPS else None
            assert terminated == (kind is not None), board.fen()
            if terminated:
                ends[kind] += 1
                expected = [0.0, 0.0] if kind != "checkmate" else [-1.0 if p == current else 1.0 for p in (0, 1)]
                assert rewards.tolist() == expected
                break
            board.push(chess.Move.from_uci(moves[index]))
    assert {"checkmate", "stalemate", "insufficient material", "threefold repetition"} <= set(ends), ends


@pytest.mark.slow(GARDNER)
def test_gardner_start_and_pawns():
    """Seven moves at the start (five pawn steps, two knight moves); no two-square pawn step even where both
    squares ahead are empty."""
    state, board = _gardner_played("")
    assert set(_gardner_moves(state)) == _corner_moves(board) == {
        "a2a3", "b2b3", "c2c3", "d2d3", "e2e3", "b1a3", "b1c3"}
    state, board = _gardner_played("b2b3 a4b3")
    assert {"a2a3", "a2b3"} <= set(_gardner_moves(state))
    assert "a2a4" not in _gardner_moves(state)
    assert "a2a4" in {move.uci() for move in board.legal_moves}  # python-chess's board would step twice


@pytest.mark.slow(GARDNER)
def test_gardner_has_no_castling():
    """With b1, c1 and d1 empty and unattacked, king on e1 and rook on a1, python-chess with the right to castle
    would play e1c1; Gardner's king has only its one-square steps."""
    state, board = _gardner_played("d2d3 c4d3 b1c3 d3c2 d1c2 d4d3 c1e3 a4a3")
    board.set_castling_fen("Q")
    assert chess.Move.from_uci("e1c1") in board.legal_moves
    king = {uci for uci in _gardner_moves(state) if uci.startswith("e1")}
    assert king
    assert all(chess.square_distance(chess.E1, chess.parse_square(uci[2:4])) == 1 for uci in king)


@pytest.mark.slow(GARDNER)
@pytest.mark.parametrize(("promotion", "piece"), [("q", 5), ("r", 4), ("b", 3), ("n", 2)])
def test_gardner_promotes_on_the_fifth_rank(promotion, piece):
    """A pawn on the fourth rank promotes stepping onto the fifth: to a queen by the plain move, to a rook,
    bishop or knight by an underpromotion."""
    state, board = _gardner_played("a2a3 b5c3 a3b4 d4d3")
    moves = _gardner_moves(state)
    assert {f"b4b5{p}" for p in "qrbn"} <= set(moves)
    assert set(moves) == _corner_moves(board)
    _, _, step = _gardner()
    state = step(state, jnp.int32(moves[f"b4b5{promotion}"]))
    assert int(state._board[5 * 1 + 0]) == -piece  # b5 seen from Black's side (b1): White's new piece


@pytest.mark.slow(GARDNER)
@pytest.mark.parametrize("key", [0, 1])
def test_gardner_checkmate_rewards(key):
    """Black's king walks into a pawn's mate: Black's player -1, White's +1, whichever player White is."""
    state, board = _gardner_played("b1a3 e4e3 a3c4 e5e4 d2d3", key=key)
    assert board.is_check()
    assert not _corner_moves(board)
    black = int(state.current_player)
    assert bool(state.terminated)
    assert state.rewards.tolist() == [-1.0 if p == black else 1.0 for p in (0, 1)]


@pytest.mark.slow(GARDNER)
@pytest.mark.parametrize(("moves", "kind"), [
    ("c2c3 b5c3 a2a3 d4d3 e2e3 d5d4 a3b4 c3b5 b4a5n d4c3 b2c3 c5a3 d1a4 b5c3 b1c3 a3c5 a4b5", "stalemate"),
    ("c2c3 b5a3 d1b3 c4b3 c3b4 e4e3 b4a5q e3d2 e1d2 d5c4 b2a3 c4d3 d2d3 b3a2 a5b4 a2b1r b4a4 c5a3 a4b4 b1b4 a1a2 "
     "b4b2 e2e3 b2e2 a2b2 a3b2 e3d4 b2d4 d3e2", "insufficient material"),
    ("b1a3 b5c3 a3b1 c3b5 b1a3 b5c3 a3b1 c3b5", "threefold repetition"),
])
def test_gardner_draws(moves, kind):
    """A stalemate, insufficient material (king against king and knight), and the start's third occurrence
    (counted from the first, unlike chess: Gardner's hash is updated move by move from its constant): ended,
    0 each."""
    state, board = _gardner_played(moves)
    assert bool(state.terminated)
    assert state.rewards.tolist() == [0.0, 0.0]
    assert {"stalemate": not _corner_moves(board) and not board.is_check(),
            "insufficient material": board.is_insufficient_material(),
            "threefold repetition": board.is_repetition(3)}[kind]
    state, board = _gardner_played(" ".join(moves.split()[:-1]))
    assert not bool(state.terminated)


@pytest.mark.slow(GARDNER)
@pytest.mark.parametrize(("field", "value"), [("_halfmove_count", 99), ("_step_count", 255)])
def test_gardner_fifty_moves_and_ply_cap(field, value):
    """A quiet move at 99 half-moves without capture or pawn move ends the game (the fifty-move rule), and so does
    any move at ply 255 (pgx's cap of 256 plies); a draw each. Neither count is reached by a short line, so the
    counter is set on a played position."""
    state, _ = _gardner_played("b1a3 b5c3")
    state = state.replace(**{field: jnp.int32(value)})
    _, _, step = _gardner()
    state = step(state, jnp.int32(_gardner_moves(state)["a3b1"]))
    assert bool(state.terminated)
    assert state.rewards.tolist() == [0.0, 0.0]
    assert int(getattr(state, field)) == value + 1
