"""Chess pictures are checked for what a player reads in them: square colours, pieces, shades and the last move in
the pixels, frames and animations by their shape and frame count, and PGN by reading it back and replaying it."""

from __future__ import annotations

import gc
import io
import warnings

import chess
import chess.pgn
import imageio
import imageio.v3 as iio
import matplotlib as mpl
import numpy as np
import pytest
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import to_rgb
from matplotlib.figure import Figure

from rlcompare.report import boards as chess_boards

SIDE = 20
"""Pixels a square on the test's board: the axes fill a 160-pixel figure."""
MATE_START = "6k1/8/5K2/8/8/8/8/R7 w - - 0 1"
MATE_MOVES = ("f6g6", "g8h8", "a1a8")
"""Kg6 Kh8 Ra8#: a KRK mate in two."""


def board_axes() -> Axes:
    figure = Figure(figsize=(2, 2), dpi=8 * SIDE / 2)
    FigureCanvasAgg(figure)
    return figure.add_axes((0, 0, 1, 1))


def pixels(ax: Axes) -> np.ndarray:
    canvas = ax.figure.canvas
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3].astype(int)


def drawn(board: chess.Board, **options) -> np.ndarray:
    ax = board_axes()
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a missing glyph, or any other complaint, fails the test
        chess_boards.draw_board(ax, board, coordinates=False, **options)
        return pixels(ax)


def square_box(square: int) -> tuple[slice, slice]:
    """Rows and columns of ``square``'s pixels (row 0 is the top, rank 8)."""
    file, rank = chess.square_file(square), chess.square_rank(square)
    return slice((7 - rank) * SIDE, (8 - rank) * SIDE), slice(file * SIDE, (file + 1) * SIDE)


def centre(rgb: np.ndarray, square: int) -> np.ndarray:
    rows, columns = square_box(square)
    return rgb[(rows.start + rows.stop) // 2, (columns.start + columns.stop) // 2]


def rgb255(color: str) -> np.ndarray:
    return np.round(np.array(to_rgb(color)) * 255).astype(int)


def only_in(changed: np.ndarray, squares: list[int]) -> bool:
    inside = np.zeros(changed.shape, dtype=bool)
    for square in squares:
        inside[square_box(square)] = True
    return bool(changed.any()) and not (changed & ~inside).any()


def mate_game() -> tuple[chess.Board, list[chess.Move]]:
    return chess.Board(MATE_START), [chess.Move.from_uci(uci) for uci in MATE_MOVES]


EMPTY = chess.Board(None)


def test_dark_and_light_squares_have_lichess_colours_with_a1_dark() -> None:
    rgb = drawn(EMPTY)
    assert rgb.shape == (8 * SIDE, 8 * SIDE, 3)
    for square in (chess.A1, chess.C1, chess.B2, chess.H8, chess.E5):
        np.testing.assert_array_equal(centre(rgb, square), rgb255(chess_boards.DARK), chess.square_name(square))
    for square in (chess.B1, chess.A2, chess.H1, chess.A8, chess.D5):
        np.testing.assert_array_equal(centre(rgb, square), rgb255(chess_boards.LIGHT), chess.square_name(square))


def test_the_font_has_every_chess_glyph() -> None:
    path = chess_boards._font().get_file()
    assert chess_boards.missing_glyphs(path) == ""
    assert chess_boards.missing_glyphs(mpl.get_data_path() + "/fonts/ttf/cmr10.ttf") != ""  # the check can fail


def test_a_piece_changes_only_its_square_white_in_white_and_black_in_dark() -> None:
    empty = drawn(EMPTY)
    white = drawn(chess.Board("8/8/8/8/8/8/8/4K3 w - - 0 1"))
    black = drawn(chess.Board("8/8/8/8/3k4/8/8/8 w - - 0 1"))
    assert only_in(np.any(white != empty, axis=2), [chess.E1])
    assert only_in(np.any(black != empty, axis=2), [chess.D4])
    king_white = white[square_box(chess.E1)]
    assert (np.all(king_white == 255, axis=2)).sum() > 0.15 * SIDE**2  # a white body...
    assert (king_white.max(axis=2) < 60).sum() > 0.05 * SIDE**2  # ...with dark lines
    king_black = black[square_box(chess.D4)]
    assert (king_black.max(axis=2) < 60).sum() > 0.1 * SIDE**2


def test_every_piece_draws_a_glyph_of_its_own() -> None:
    board = chess.Board("rnbqk3/8/8/8/8/8/8/RNBQK3 w - - 0 1")
    rgb = drawn(board)
    empty = drawn(EMPTY)
    pictures = {}
    for square, piece in board.piece_map().items():
        assert np.any(rgb[square_box(square)] != empty[square_box(square)]), piece.symbol()
        silhouette, glyph = chess_boards.piece_paths(piece)
        pictures[piece.symbol()] = glyph.vertices.round(3).tobytes()
        assert silhouette.get_extents().width == pytest.approx(glyph.get_extents().width, abs=0.02)
    assert len(set(pictures.values())) == 10


def test_shading_one_square_changes_only_that_square_to_the_colour_of_its_value() -> None:
    shade = np.full(64, np.nan)
    shade[chess.D4] = 1.0
    ax = board_axes()
    chess_boards.draw_board(ax, EMPTY, shade=shade, cmap="viridis", vmin=0.0, vmax=2.0, coordinates=False)
    rgb = pixels(ax)
    assert only_in(np.any(rgb != drawn(EMPTY), axis=2), [chess.D4])
    expected = np.round(np.array(mpl.colormaps["viridis"](0.5)[:3]) * 255)
    assert np.abs(centre(rgb, chess.D4) - expected).max() <= 1
    image = chess_boards.shade_image(ax)
    assert image is not None
    assert image.get_clim() == (0.0, 2.0)
    assert chess_boards.shade_image(board_axes()) is None


def test_shade_must_have_a_value_a_square() -> None:
    with pytest.raises(ValueError, match="64"):
        chess_boards.draw_board(board_axes(), EMPTY, shade=np.zeros((8, 8)))


def test_highlight_colours_the_moves_squares_and_check_puts_a_red_disc_under_the_king() -> None:
    board, moves = mate_game()
    for move in moves:
        board.push(move)
    rgb = drawn(board, highlight=board.peek())
    np.testing.assert_array_equal(centre(rgb, chess.A1), rgb255(chess_boards.LAST_MOVE_DARK))
    rows, columns = square_box(chess.A8)
    np.testing.assert_array_equal(rgb[rows.start + 1, columns.start + 1], rgb255(chess_boards.LAST_MOVE_LIGHT))
    king = rgb[square_box(chess.H8)]
    assert ((king[..., 0] > 180) & (king[..., 1] < 120)).sum() > 0.1 * SIDE**2  # red, where the plain board has none
    assert not ((drawn(EMPTY)[..., 0] > 180) & (drawn(EMPTY)[..., 1] < 120)).any()


def test_value_map_shades_the_squares_writes_values_and_adds_a_colour_bar() -> None:
    values = np.full(64, np.nan)
    values[[chess.A1, chess.C3, chess.H8]] = [-3.0, -0.25, -12.0]
    pieces = chess.Board("8/8/8/8/8/8/8/R3K3 w - - 0 1")
    ax = board_axes()
    chess_boards.value_map(ax, values, pieces=pieces, title="learnt", vmin=-20, vmax=0, numbers=True,
                           colorbar="value")
    image = chess_boards.shade_image(ax)
    assert image is not None
    np.testing.assert_array_equal(np.ma.getdata(image.get_array()).ravel(), values)
    assert sorted(text.get_text() for text in ax.texts) == ["-0.25", "-12"]  # a1 holds the rook: no number there
    assert ax.get_title() == "learnt"
    assert len(ax.figure.axes) == 2


def test_frames_have_the_declared_shape_and_differ_between_positions() -> None:
    start, moves = mate_game()
    boards = chess_boards.positions(start, moves[:1])
    captions = chess_boards.move_captions(start, moves[:1])
    assert captions == ["start", "move 1, Kg6"]
    frames = chess_boards.board_frames(boards, size_px=200, captions=captions)
    assert frames.shape == (2, 200, 200, 3)
    assert frames.dtype == np.uint8
    changed = np.any(frames[0] != frames[1], axis=2)
    assert changed.sum() > 200  # the king moved and its squares are marked
    assert changed[:20].any()  # the caption changed
    with pytest.raises(ValueError, match="captions"):
        chess_boards.board_frames(boards, captions=["one"])


def test_captions_number_moves_in_algebraic_notation() -> None:
    start, moves = mate_game()
    assert chess_boards.move_captions(start, moves) == ["start", "move 1, Kg6", "move 1, ...Kh8", "move 2, Ra8#"]


def test_pgn_round_trips_headers_moves_result_and_start() -> None:
    start, moves = mate_game()
    game = chess_boards.game_pgn(moves, start, {"Event": "KRK study", "White": "Q-Learning seed 3"},
                                 comments=["", "", "mate"], comment="greedy policy")
    drawn_game = chess_boards.game_pgn(moves[:2], start, {"Event": "KRK study"})
    assert game.headers["Result"] == "1-0"
    assert drawn_game.headers["Result"] == "1/2-1/2"
    text = str(game)
    read = chess.pgn.read_game(io.StringIO(text))
    assert read is not None
    assert read.errors == []
    assert list(read.headers)[:7] == list(chess_boards.SEVEN_TAG_ROSTER)
    assert dict(read.headers) == {**dict(game.headers), "FEN": MATE_START, "SetUp": "1"}
    assert list(read.mainline_moves()) == moves
    assert read.end().board().is_checkmate()
    assert read.end().comment == "mate"
    assert read.comment == "greedy policy"


def test_a_game_from_the_initial_position_has_no_fen_and_black_can_win() -> None:
    fools_mate = [chess.Move.from_uci(uci) for uci in ("f2f3", "e7e5", "g2g4", "d8h4")]
    game = chess_boards.game_pgn(fools_mate, chess.Board(), {})
    assert "FEN" not in game.headers
    assert "SetUp" not in game.headers
    assert game.headers["Result"] == "0-1"


def test_pgn_refuses_an_illegal_move_or_a_contradicting_header() -> None:
    start, moves = mate_game()
    with pytest.raises(ValueError, match="not legal"):
        chess_boards.game_pgn([moves[0], moves[0]], start, {})
    with pytest.raises(ValueError, match="Result"):
        chess_boards.game_pgn(moves, start, {"Result": "1/2-1/2"})
    with pytest.raises(ValueError, match="not a legal chess position"):
        chess_boards.game_pgn([], chess.Board("8/8/8/8/8/8/8/8 w - - 0 1"), {})


def test_a_pgn_file_replays_every_game_to_its_final_position(tmp_path) -> None:
    start, moves = mate_game()
    games = [chess_boards.game_pgn(moves[:n], start, {"Round": str(n)}) for n in (3, 2)]
    path = chess_boards.write_pgn(tmp_path / "games.pgn", games)
    with open(path, encoding="utf-8") as handle:
        read = [chess.pgn.read_game(handle) for _ in range(3)]
    assert read[2] is None
    for game, back in zip(games, read[:2], strict=True):
        assert back is not None
        board = back.board()
        for move in back.mainline_moves():
            assert board.is_legal(move)
            board.push(move)
        assert board.fen() == game.end().board().fen()
        assert back.headers["Result"] == game.headers["Result"]
        assert back.headers["Round"] == game.headers["Round"]
    assert not list(tmp_path.glob(".*tmp*"))
    with pytest.raises(ValueError, match="no games"):
        chess_boards.write_pgn(tmp_path / "none.pgn", [])


def test_the_gif_has_a_frame_a_position_and_keeps_the_last_move_colour(tmp_path) -> None:
    start, moves = mate_game()
    boards = chess_boards.positions(start, moves)
    path = chess_boards.write_game_animation(tmp_path / "game.gif", boards, chess_boards.move_captions(start, moves),
                                             size_px=160)
    read = iio.imread(path, index=None)
    assert read.shape == (4, 160, 160, 3)
    colours = {tuple(pixel) for pixel in read[-1].reshape(-1, 3)}
    assert tuple(rgb255(chess_boards.LAST_MOVE_DARK)) in colours  # the palette is the game's, not the first frame's
    with pytest.raises(ValueError, match=r"\.gif or an \.mp4"):
        chess_boards.write_game_animation(tmp_path / "game.avi", boards)


@pytest.mark.slow("starts ffmpeg to encode and again to decode the MP4")
def test_the_mp4_has_a_frame_a_position(tmp_path) -> None:
    start, moves = mate_game()
    path = chess_boards.write_game_animation(tmp_path / "game.mp4", chess_boards.positions(start, moves),
                                             size_px=160, fps=2)
    with warnings.catch_warnings():  # imageio-ffmpeg leaves its pipes for the collector: tests/studies/test_video.py
        warnings.simplefilter("ignore", ResourceWarning)
        with imageio.get_reader(path, "FFMPEG") as reader:
            frames = np.stack(list(reader.iter_data()))
            fps = reader.get_meta_data()["fps"]
        del reader
        gc.collect()
    assert frames.shape == (4, 160, 160, 3)
    assert fps == 2


def test_svg_marks_the_last_move_with_an_arrow_and_the_check() -> None:
    start, moves = mate_game()
    for move in moves:
        start.push(move)
    svg = chess_boards.board_svg(start)
    assert svg.startswith("<svg")
    assert 'class="arrow' in svg
    assert chess_boards.LAST_MOVE_DARK in svg
    assert 'id="check_gradient"' in svg
    assert 'class="arrow' not in chess_boards.board_svg(start, arrow=False)
