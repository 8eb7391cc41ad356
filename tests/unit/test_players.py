"""The ladder's players and games: the random player's draws are legal, seeded and uniform, the material player
takes the most it can, a game ends exactly where python-chess says on built positions (or at the ply limit, as a
draw), pairs swap colours, and Stockfish is found, or named with the line that installs it."""

from __future__ import annotations

import collections
import contextlib
import io
import stat

import chess
import chess.pgn
import numpy as np
import pytest
from scipy.stats import chisquare

from rlcompare.envs.chess.games import PIECE_VALUES
from rlcompare.players import stockfish
from rlcompare.players.basic import MaterialPlayer, RandomPlayer
from rlcompare.players.games import GameRecord, play_game, play_pairs
from rlcompare.players.stockfish import LIMIT_1350, SKILL_0, MissingEngine, StockfishPlayer, find_stockfish

MIDGAME = "r1bqkb1r/pppp1ppp/2n2n2/4p3/2B1P3/5N2/PPPP1PPP/RNBQK2R w KQkq - 4 4"


class Scripted:
    """Plays the moves it is given, in order, and fails the test if asked for one more."""

    def __init__(self, name: str, moves: list[str]) -> None:
        self.name, self.moves = name, list(moves)

    def move(self, board: chess.Board) -> chess.Move:
        assert self.moves, f"{self.name} was asked for a move after its script ended, on {board.fen()}"
        return chess.Move.from_uci(self.moves.pop(0))

    def close(self) -> None:
        pass


def scripted_game(fen: str | None, white: list[str], black: list[str], **options) -> GameRecord:
    start = None if fen is None else chess.Board(fen)
    return play_game(Scripted("w", white), Scripted("b", black), start=start, **options)


def moves_drawn(player, board: chess.Board, draws: int) -> collections.Counter[str]:
    return collections.Counter(player.move(board).uci() for _ in range(draws))


def material(board: chess.Board, colour: chess.Color) -> int:
    """``colour``'s material minus the other side's."""
    return sum(PIECE_VALUES[piece.piece_type - 1] * (1 if piece.color == colour else -1)
               for piece in board.piece_map().values())


def test_the_random_player_plays_only_legal_moves_on_many_boards():
    board, player = chess.Board(), RandomPlayer(3)
    for _ in range(300):
        if board.outcome(claim_draw=True):
            board = chess.Board()
        move = player.move(board)
        assert move in board.legal_moves
        board.push(move)


def test_the_random_player_repeats_itself_from_a_seed_and_not_from_another():
    board = chess.Board(MIDGAME)
    first, again, other = (RandomPlayer(seed) for seed in (5, 5, 6))
    drawn = [first.move(board) for _ in range(30)]
    assert drawn == [again.move(board) for _ in range(30)]
    assert drawn != [other.move(board) for _ in range(30)]


def test_the_random_player_draws_from_moves_sorted_by_their_uci_string():
    """The draw hangs on the seed and the set of moves only, not on the order python-chess generates them in."""
    board = chess.Board(MIDGAME)
    ordered = sorted(board.legal_moves, key=chess.Move.uci)
    rng = np.random.default_rng(11)
    expected = [ordered[int(rng.integers(len(ordered)))] for _ in range(20)]
    player = RandomPlayer(11)
    assert [player.move(board) for _ in range(20)] == expected


def test_the_random_player_is_uniform_over_the_legal_moves():
    board = chess.Board(MIDGAME)
    legal = sorted(move.uci() for move in board.legal_moves)
    counts = moves_drawn(RandomPlayer(0), board, 200 * len(legal))
    assert set(counts) == set(legal)
    assert chisquare([counts[move] for move in legal]).pvalue > 0.001


def test_the_material_player_takes_the_queen_before_the_rook():
    # the e4 pawn and the e3 knight each take the queen on d5 or the rook on f5
    board = chess.Board("k7/8/8/3q1r2/4P3/4N3/8/K7 w - - 0 1")
    assert set(moves_drawn(MaterialPlayer(0), board, 40)) == {"e4d5", "e3d5"}


def test_the_material_player_takes_the_rook_before_a_minor_piece_and_a_pawn():
    board = chess.Board("k7/8/2n5/1p1r4/2B5/8/8/K7 w - - 0 1")  # Bc4 takes b5 (pawn), d5 (rook); no way to c6
    assert moves_drawn(MaterialPlayer(0), board, 20) == {"c4d5": 20}


def test_the_material_player_breaks_ties_at_random():
    board = chess.Board("k7/8/8/2n1n3/3P4/8/8/K7 w - - 0 1")  # d4 takes either knight
    assert set(moves_drawn(MaterialPlayer(0), board, 40)) == {"d4c5", "d4e5"}


def test_en_passant_counts_as_a_pawn():
    alone = chess.Board("k7/8/8/3pP3/8/8/8/K7 w - d6 0 1")
    assert moves_drawn(MaterialPlayer(1), alone, 20) == {"e5d6": 20}
    against_a_pawn = chess.Board("1k6/p7/8/3pP3/8/8/8/R5K1 w - d6 0 1")  # Rxa7 takes a pawn too
    assert set(moves_drawn(MaterialPlayer(1), against_a_pawn, 40)) == {"e5d6", "a1a7"}
    against_a_knight = chess.Board("1k6/n7/8/3pP3/8/8/8/R5K1 w - d6 0 1")
    assert moves_drawn(MaterialPlayer(1), against_a_knight, 20) == {"a1a7": 20}


def test_the_material_player_plays_at_random_with_nothing_to_take():
    board = chess.Board()
    counts = moves_drawn(MaterialPlayer(2), board, 400)
    assert set(counts) == {move.uci() for move in board.legal_moves}


@pytest.mark.slow("plays twenty games of up to 100 plies")
def test_the_material_player_beats_the_random_player_clearly():
    """It loses no game and ends every one a queen or more ahead (most end at the ply limit: it takes, but does
    not look for mate)."""
    records = play_pairs(MaterialPlayer(0), RandomPlayer(0), 10, max_plies=100)
    assert [record.white for record in records[:2]] == ["material", "random"]
    assert all(record.points("material") >= 0.5 for record in records)
    ahead = [material(record.game.end().board(), chess.WHITE if record.white == "material" else chess.BLACK)
             for record in records]
    assert min(ahead) >= PIECE_VALUES[chess.QUEEN - 1], ahead


def test_a_game_ends_at_mate():
    record = scripted_game(None, ["f2f3", "g2g4"], ["e7e5", "d8h4"])  # fool's mate
    assert (record.result, record.termination, record.plies) == ("0-1", "checkmate", 4)
    assert record.game.headers["Result"] == "0-1"
    assert record.game.end().board().is_checkmate()
    assert (record.white_points, record.points("b"), record.points("w")) == (0.0, 1.0, 0.0)


def test_a_game_ends_at_mate_from_a_built_position_with_its_fen_in_the_pgn():
    fen = "6k1/5ppp/8/8/8/8/8/R5K1 w - - 0 1"
    record = scripted_game(fen, ["a1a8"], [])
    assert (record.result, record.termination, record.plies) == ("1-0", "checkmate", 1)
    headers = record.game.headers
    assert (headers["FEN"], headers["SetUp"], headers["White"], headers["Black"]) == (fen, "1", "w", "b")
    assert headers["Termination"] == "checkmate"


def test_the_standard_start_has_no_fen_header():
    record = scripted_game(None, ["f2f3", "g2g4"], ["e7e5", "d8h4"])
    assert "FEN" not in record.game.headers


def test_a_game_ends_at_stalemate():
    record = scripted_game("7k/4Q3/6K1/8/8/8/8/8 w - - 0 1", ["e7f7"], [])
    assert (record.result, record.termination, record.plies) == ("1/2-1/2", "stalemate", 1)


def test_a_game_ends_when_neither_side_can_mate():
    record = scripted_game("8/8/8/4k3/8/8/3r4/2B1K3 w - - 0 1", ["e1d2"], [])
    assert (record.result, record.termination) == ("1/2-1/2", "insufficient material")
    assert record.game.end().board().is_insufficient_material()


def test_a_threefold_repetition_is_claimed_as_soon_as_python_chess_allows():
    """After White's third Ng1-f3-g1 trip the start position can come a third time with Black's next move: the
    claim is made then, at ply 7, without playing the move."""
    white, black = ["g1f3", "f3g1"] * 2, ["g8f6", "f6g8"] * 2
    record = scripted_game(None, white, black)
    assert (record.result, record.termination, record.plies) == ("1/2-1/2", "threefold repetition", 7)
    board = record.game.end().board()
    assert board.can_claim_threefold_repetition()
    assert not board.is_repetition(3)


def test_a_game_from_a_position_claimable_at_once_plays_no_move():
    board = chess.Board("8/8/8/4k3/8/8/8/4K3 w - - 120 90")  # fifty moves passed and bare kings
    record = play_game(Scripted("w", []), Scripted("b", []), start=board)
    assert (record.plies, record.result) == (0, "1/2-1/2")


def test_the_fifty_move_rule_is_claimed():
    board = chess.Board("8/8/8/4k3/8/8/8/R3K3 w - - 98 80")
    record = scripted_game(board.fen(), ["a1a2"], [])
    assert (record.termination, record.plies) == ("fifty moves", 1)


def test_max_plies_ends_the_game_as_a_draw_and_says_so():
    record = play_game(RandomPlayer(0), RandomPlayer(1), max_plies=10)
    assert (record.plies, record.result) == (10, "1/2-1/2")
    assert record.game.headers["Termination"] == "draw at the limit of 10 plies"
    board = record.game.end().board()
    assert len(board.move_stack) == 10
    assert board.outcome(claim_draw=True) is None


def test_the_pgn_reads_back_to_the_same_game():
    record = play_game(MaterialPlayer(0), RandomPlayer(1), start=chess.Board(MIDGAME), max_plies=30)
    again = chess.pgn.read_game(io.StringIO(str(record.game)))
    assert again is not None
    assert again.end().board() == record.game.end().board()
    assert again.headers["Result"] == record.result
    assert again.headers["FEN"] == MIDGAME


def test_a_player_that_plays_an_illegal_move_or_changes_the_board_is_an_error():
    with pytest.raises(ValueError, match="w played the illegal move e2e5"):
        scripted_game(None, ["e2e5"], [])

    class Pusher(Scripted):
        def move(self, board: chess.Board) -> chess.Move:
            board.push(chess.Move.from_uci("e2e4"))
            return chess.Move.from_uci("e7e5")

    with pytest.raises(ValueError, match="pusher changed the board"):
        play_game(Pusher("pusher", []), Scripted("b", []))


def test_play_pairs_swaps_colours_in_each_pair():
    a, b = RandomPlayer(0, name="a"), RandomPlayer(1, name="b")
    records = play_pairs(a, b, 3, max_plies=4)
    assert [(record.white, record.black) for record in records] == [("a", "b"), ("b", "a")] * 3
    assert [record.game.headers["White"] for record in records] == ["a", "b"] * 3


def test_points_are_only_for_the_two_players():
    record = play_game(RandomPlayer(0, name="a"), RandomPlayer(1, name="b"), max_plies=2)
    with pytest.raises(ValueError, match="'c' did not play"):
        record.points("c")


def executable(path) -> None:
    path.write_text("#!/bin/sh\n")
    path.chmod(path.stat().st_mode | stat.S_IXUSR)


def test_find_stockfish_says_in_one_line_how_to_install_it(tmp_path, monkeypatch):
    monkeypatch.setenv("PATH", str(tmp_path))
    monkeypatch.setattr(stockfish, "STOCKFISH_DIRS", (str(tmp_path / "games"),))
    with pytest.raises(MissingEngine) as missing:
        find_stockfish()
    message = str(missing.value)
    assert "apt-get install stockfish" in message
    assert "\n" not in message


def test_find_stockfish_looks_on_path_then_in_its_folders(tmp_path, monkeypatch):
    on_path, games = tmp_path / "bin", tmp_path / "games"
    on_path.mkdir(), games.mkdir()
    executable(games / "stockfish")
    monkeypatch.setenv("PATH", str(on_path))
    monkeypatch.setattr(stockfish, "STOCKFISH_DIRS", (str(games),))
    assert find_stockfish() == str(games / "stockfish")
    executable(on_path / "stockfish")
    assert find_stockfish() == str(on_path / "stockfish")


def stockfish_or_skip() -> str:
    try:
        return find_stockfish()
    except MissingEngine as missing:
        pytest.skip(str(missing))


@pytest.mark.slow("starts Stockfish and plays six games")
def test_stockfish_at_skill_0_beats_the_random_player():
    with contextlib.closing(StockfishPlayer(SKILL_0, stockfish_or_skip())) as stockfish:
        records = play_pairs(stockfish, RandomPlayer(0), 3, max_plies=300)
    assert sum(record.points(SKILL_0.name) for record in records) >= 5
    assert [record.white for record in records] == [SKILL_0.name, "random"] * 3


def test_stockfish_limited_to_uci_elo_1350_plays_legal_moves_and_closes():
    stockfish = StockfishPlayer(LIMIT_1350, stockfish_or_skip())
    try:
        board = chess.Board(MIDGAME)
        assert stockfish.move(board) in board.legal_moves
        assert stockfish.name == "stockfish-limit1350-nodes5000"
    finally:
        stockfish.close()
    assert stockfish.engine.returncode.result(timeout=10) == 0
    stockfish.close()  # a second close does nothing

