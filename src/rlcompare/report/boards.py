"""Chess positions and games as a chess player reads them: boards, value maps, animations, PGN and SVG.

:func:`draw_board` draws a position on an ``ax`` (light and dark squares in lichess's colours, files a-h and ranks
1-8, the pieces as DejaVu Sans's chess glyphs), optionally with a value per square shaded over it (the mappable for a
colour bar: :func:`shade_image`) and the last move marked; :func:`value_map` is that board with the squares shaded by
a value, e.g. of each square the defending king could stand on. :func:`board_frames` draws a game's positions as
video frames, written by the house's encoder (:mod:`rlcompare.report.encode`) as a GIF or an MP4
(:func:`write_game_animation`). :func:`game_pgn` and :func:`write_pgn` give every game as PGN that any chess program
opens, and :func:`board_svg` python-chess's own SVG of a position for the HTML report. Squares are numbered as in
python-chess: a1 = 0, b1 = 1, ..., h8 = 63. The drawing functions draw on the ``ax`` they are given and return it;
the writers, which a study or the command line calls, write their files atomically.
"""

from __future__ import annotations

import functools
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any, NamedTuple

import chess
import chess.pgn
import chess.svg
import matplotlib as mpl
import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import Colormap, to_rgb
from matplotlib.figure import Figure
from matplotlib.font_manager import FontProperties, get_font
from matplotlib.image import AxesImage
from matplotlib.patches import Circle, PathPatch, Rectangle
from matplotlib.path import Path as MplPath
from matplotlib.textpath import TextPath
from matplotlib.transforms import Affine2D
from PIL import Image

from rlcompare.experiment import store
from rlcompare.formatting import number
from rlcompare.report import encode, frames
from rlcompare.report.plots import colorbar_beside

LIGHT, DARK = "#f0d9b5", "#b58863"
"""lichess's brown board: light and dark squares (a1 is dark)."""
LAST_MOVE_LIGHT, LAST_MOVE_DARK = "#cdd26a", "#aaa23a"
"""The last move's from- and to-square, on a light and a dark square: lichess's translucent yellow-green over each."""
CHECK = (0.9, 0.15, 0.15, 0.6)
"""A red disc under a king in check."""
WHITE_FILL, INK = "#ffffff", "#1f1f1f"
"""White's pieces are white with dark lines; Black's are dark with a thin white edge, so they show on any shade."""
SHADE_GID = "shade"
"""The gid of the image :func:`draw_board` shades squares with (:func:`shade_image` finds it)."""
PIECE_HEIGHT = 0.8
"""A king's height, in squares."""
SOLID = {chess.PAWN: "♟", chess.KNIGHT: "♞", chess.BISHOP: "♝", chess.ROOK: "♜", chess.QUEEN: "♛", chess.KING: "♚"}
OUTLINE = {chess.PAWN: "♙", chess.KNIGHT: "♘", chess.BISHOP: "♗", chess.ROOK: "♖", chess.QUEEN: "♕", chess.KING: "♔"}
"""The Unicode chess glyphs: a White piece is the solid glyph's silhouette in white under the outline glyph's lines,
a Black piece the solid glyph in dark."""
FRAME_INCHES = 4.0
"""A frame's side in inches at ``size_px / 4`` dots an inch: a power of two, so the pixels come out exact and the
fonts scale with the frame."""
GAME_FPS = 1.0
"""A game's animation shows one position a second."""
SVG_COLORS = {"square light": LIGHT, "square dark": DARK, "square light lastmove": LAST_MOVE_LIGHT,
              "square dark lastmove": LAST_MOVE_DARK}


# --- the board ---------------------------------------------------------------------------------------------


@functools.lru_cache(maxsize=1)
def _font() -> FontProperties:
    """DejaVu Sans as matplotlib ships it, refused if it lacks a chess glyph (TextPath would draw a box unwarned)."""
    path = Path(mpl.get_data_path()) / "fonts" / "ttf" / "DejaVuSans.ttf"
    missing = missing_glyphs(path)
    if missing:
        raise RuntimeError(f"{path} has no glyph for {missing}: the chess pieces cannot be drawn")
    return FontProperties(fname=path)


def missing_glyphs(font_path: Path) -> str:
    """The chess glyphs the font at ``font_path`` has no glyph for."""
    font = get_font(font_path)
    return "".join(ch for ch in (*SOLID.values(), *OUTLINE.values()) if font.get_char_index(ord(ch)) == 0)


def _signed_area(polygon: np.ndarray) -> float:
    x, y = polygon[:, 0], polygon[:, 1]
    return float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))) / 2


def _silhouette(path: MplPath) -> MplPath:
    """A glyph's outer outline, its holes filled: the closed outlines turned as its largest one is (a hole is
    turned the other way)."""
    polygons = [np.asarray(outline, dtype=np.float64) for outline in path.to_polygons(closed_only=True)]
    areas = [_signed_area(polygon) for polygon in polygons]
    outer = np.sign(max(areas, key=abs))
    return MplPath.make_compound_path(*(MplPath(polygon, closed=True)
                                        for polygon, area in zip(polygons, areas, strict=True)
                                        if np.sign(area) == outer))


@functools.lru_cache(maxsize=16)
def piece_paths(piece: chess.Piece) -> tuple[MplPath, MplPath]:
    """A piece's silhouette and its glyph, in squares, centred on (0, 0), a king :data:`PIECE_HEIGHT` high: the
    solid glyph for Black, the outline glyph (its lines) for White."""
    solid = TextPath((0, 0), SOLID[piece.piece_type], size=1, prop=_font())
    king = TextPath((0, 0), SOLID[chess.KING], size=1, prop=_font()).get_extents()
    box = solid.get_extents()
    place = Affine2D().translate(-(box.x0 + box.x1) / 2, -(box.y0 + box.y1) / 2).scale(PIECE_HEIGHT / king.height)
    glyph = solid if piece.color == chess.BLACK else TextPath((0, 0), OUTLINE[piece.piece_type], size=1, prop=_font())
    return place.transform_path(_silhouette(solid)), place.transform_path(glyph)


def _square_colors(highlight: chess.Move | None) -> np.ndarray:
    """(8, 8, 3) RGB of the squares, rank by rank from rank 1, the last move's squares in its colours."""
    dark = (np.add.outer(np.arange(8), np.arange(8)) % 2 == 0)[..., None]
    rgb = np.where(dark, to_rgb(DARK), to_rgb(LIGHT))
    for square in _move_squares(highlight):
        rank, file = divmod(square, 8)
        rgb[rank, file] = to_rgb(LAST_MOVE_DARK if (rank + file) % 2 == 0 else LAST_MOVE_LIGHT)
    return rgb


def _move_squares(move: chess.Move | None) -> tuple[int, ...]:
    return () if move is None else (move.from_square, move.to_square)


def _centre(square: int) -> tuple[float, float]:
    return chess.square_file(square) + 0.5, chess.square_rank(square) + 0.5


def _draw_piece(ax: Axes, square: int, piece: chess.Piece) -> None:
    """White's piece: its silhouette in white under its lines. Black's: the solid glyph in dark over its
    silhouette's thin white edge."""
    silhouette, glyph = piece_paths(piece)
    to_square = Affine2D().translate(*_centre(square)) + ax.transData
    white = piece.color == chess.WHITE
    ax.add_patch(PathPatch(silhouette, facecolor=WHITE_FILL if white else "none", edgecolor="none" if white else
                           WHITE_FILL, linewidth=1.0, transform=to_square, zorder=3,
                           gid=f"piece-{chess.square_name(square)}"))
    ax.add_patch(PathPatch(glyph, facecolor=INK, edgecolor="none", transform=to_square, zorder=3.1))


def _shade(ax: Axes, shade: np.ndarray, cmap: str | Colormap, vmin: float | None, vmax: float | None) -> AxesImage:
    values = np.asarray(shade, dtype=np.float64)
    if values.shape != (64,):
        raise ValueError(f"shade must have one value a square, shape (64,); got {values.shape}")
    colormap = (mpl.colormaps[cmap] if isinstance(cmap, str) else cmap).with_extremes(bad=(0, 0, 0, 0))
    return ax.imshow(values.reshape(8, 8), origin="lower", extent=(0, 8, 0, 8), cmap=colormap, vmin=vmin, vmax=vmax,
                     interpolation="nearest", zorder=1, gid=SHADE_GID)


def draw_board(ax: Axes, board: chess.BaseBoard, *, shade: np.ndarray | None = None,
               cmap: str | Colormap = "viridis", vmin: float | None = None, vmax: float | None = None,
               highlight: chess.Move | None = None, title: str = "", coordinates: bool = True, size: int = 8) -> Axes:
    """``board`` from White's side: squares (a1 dark), pieces, and with ``coordinates`` files a-h below and ranks
    1-8 left of it; with ``size`` 5, Gardner's board, the corner a1-e5 alone.

    ``shade`` (64,) colours each square by its value through ``cmap`` from ``vmin`` to ``vmax`` (NaN: unshaded);
    its image is :func:`shade_image` of ``ax``, for a colour bar. ``highlight`` marks a move's from- and to-square
    (outlined where shaded), and a king in check stands on a red disc.
    """
    ax.imshow(_square_colors(highlight), origin="lower", extent=(0, 8, 0, 8), interpolation="nearest", zorder=0)
    if shade is not None:
        _shade(ax, shade, cmap, vmin, vmax)
        for square in _move_squares(highlight):
            if np.isfinite(shade[square]):
                file, rank = chess.square_file(square), chess.square_rank(square)
                ax.add_patch(Rectangle((file + 0.04, rank + 0.04), 0.92, 0.92, facecolor="none",
                                       edgecolor=LAST_MOVE_DARK, linewidth=2.5, zorder=2))
    if isinstance(board, chess.Board) and board.is_check():
        king = board.king(board.turn)
        if king is not None:
            ax.add_patch(Circle(_centre(king), 0.45, facecolor=CHECK, edgecolor="none", zorder=2.5, gid="check"))
    for square, piece in board.piece_map().items():
        _draw_piece(ax, square, piece)
    ax.set_xlim(0, size)
    ax.set_ylim(0, size)
    ax.set_aspect("equal")
    ax.set_xticks(np.arange(size) + 0.5, list("abcdefgh"[:size]) if coordinates else [])
    ax.set_yticks(np.arange(size) + 0.5, list("12345678"[:size]) if coordinates else [])
    ax.tick_params(length=0)
    for spine in ax.spines.values():
        spine.set_visible(False)
    if title:
        ax.set_title(title)
    return ax


def shade_image(ax: Axes) -> AxesImage | None:
    """The image :func:`draw_board` shaded the squares of ``ax`` with (a mappable for a colour bar), or None."""
    return next((image for image in ax.images if image.get_gid() == SHADE_GID), None)


def value_map(ax: Axes, values: np.ndarray, *, pieces: chess.BaseBoard, title: str = "",
              cmap: str | Colormap = "viridis", vmin: float | None = None, vmax: float | None = None,
              numbers: bool = False, colorbar: str | None = None) -> Axes:
    """The board of ``pieces`` with each square shaded by ``values`` (64,), e.g. the value of each square the
    defending king could stand on (NaN: unshaded). Two maps that share ``vmin`` and ``vmax`` compare colour for
    colour. ``numbers`` writes each shaded square's value in it where no piece stands; ``colorbar`` (its label)
    puts a colour bar beside the board."""
    draw_board(ax, pieces, shade=values, cmap=cmap, vmin=vmin, vmax=vmax, title=title)
    image = shade_image(ax)
    assert image is not None
    if numbers:
        _write_numbers(ax, image, np.asarray(values, dtype=np.float64), pieces)
    if colorbar is not None:
        colorbar_beside(ax, image, colorbar)
    return ax


def _write_numbers(ax: Axes, image: AxesImage, values: np.ndarray, pieces: chess.BaseBoard) -> None:
    """Each shaded, empty square's value in it, dark on a light colour and white on a dark one."""
    size = 0.28 * 72 * min(ax.bbox.width, ax.bbox.height) / ax.figure.dpi / 8  # points: about a quarter of a square
    rgba = np.asarray(image.to_rgba(values), dtype=np.float64)
    light = rgba[:, :3] @ np.array([0.299, 0.587, 0.114]) > 0.5
    for square in np.flatnonzero(np.isfinite(values)):
        if pieces.piece_at(int(square)) is None:
            ax.text(*_centre(int(square)), number(float(values[square]), 2), ha="center", va="center",
                    fontsize=size, color=INK if light[square] else WHITE_FILL, zorder=2)


# --- games: positions, frames, animation -------------------------------------------------------------------


def positions(start: chess.Board, moves: Sequence[chess.Move]) -> list[chess.Board]:
    """The game's positions, ``start`` first: one board a move more, each with its moves made (so its last move
    is marked by :func:`board_frames`)."""
    board = start.copy(stack=False)
    boards = [board.copy()]
    for move in moves:
        board.push(move)
        boards.append(board.copy())
    return boards


def move_captions(start: chess.Board, moves: Sequence[chess.Move]) -> list[str]:
    """A caption for each of :func:`positions`: "start", then "move 12, Rh7+" for White's moves and
    "move 12, ...Kg8" for Black's, in standard algebraic notation."""
    board = start.copy(stack=False)
    captions = ["start"]
    for move in moves:
        dots = "" if board.turn == chess.WHITE else "..."
        captions.append(f"move {board.fullmove_number}, {dots}{board.san(move)}")
        board.push(move)
    return captions


class _Canvas(NamedTuple):
    figure: Figure
    canvas: Any
    """A FigureCanvasAgg: matplotlib's Agg backend has no type hints."""
    ax: Axes


def _frame_canvas(size_px: int) -> _Canvas:
    """A square figure of ``size_px`` pixels: the board centred, room for a caption above and files below."""
    figure = Figure(figsize=(FRAME_INCHES, FRAME_INCHES), dpi=size_px / FRAME_INCHES)
    canvas = FigureCanvasAgg(figure)
    side, top = 3.35, 0.42
    left = (FRAME_INCHES - side) / 2
    bottom = FRAME_INCHES - top - side
    ax = figure.add_axes((left / FRAME_INCHES, bottom / FRAME_INCHES, side / FRAME_INCHES, side / FRAME_INCHES))
    return _Canvas(figure, canvas, ax)


def board_frames(boards: Sequence[chess.Board], *, size_px: int = 360,
                 captions: Sequence[str] | None = None) -> np.ndarray:
    """(n, size_px, size_px, 3) uint8 RGB frames, one a board, each with its caption above it and its last move
    (the last of its move stack) marked; one figure is drawn again for each."""
    if captions is not None and len(captions) != len(boards):
        raise ValueError(f"{len(captions)} captions for {len(boards)} boards")
    if size_px < 32:
        raise ValueError(f"size_px must be at least 32; got {size_px}")
    canvas = _frame_canvas(size_px)
    out = np.empty((len(boards), size_px, size_px, 3), dtype=np.uint8)
    for index, board in enumerate(boards):
        canvas.ax.clear()
        last = board.move_stack[-1] if board.move_stack else None
        draw_board(canvas.ax, board, highlight=last, title=captions[index] if captions is not None else "")
        canvas.canvas.draw()
        out[index] = np.asarray(canvas.canvas.buffer_rgba())[..., :3]
    return out


def _gif_palette(rgb_frames: np.ndarray) -> Image.Image:
    """One palette for the whole game, from up to 32 of its frames at half size: the first frame alone (the
    house GIF's palette) has no last move or check in it."""
    chosen = rgb_frames[np.unique(np.linspace(0, len(rgb_frames) - 1, min(32, len(rgb_frames))).astype(int))]
    half = chosen[:, ::2, ::2]
    mosaic = Image.fromarray(np.ascontiguousarray(half.reshape(-1, *half.shape[2:])))
    return mosaic.quantize(colors=encode.GIF_COLORS, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)


def write_game_animation(path: Path, boards: Sequence[chess.Board], captions: Sequence[str] | None = None, *,
                         fps: float = GAME_FPS, size_px: int = 360) -> Path:
    """The game's :func:`board_frames` at ``fps`` positions a second, written atomically by the house's encoder:
    a looping GIF at full size (its last frame held a second longer) for ``.gif``, an H.264 MP4 for ``.mp4``."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".gif", ".mp4"):
        raise ValueError(f"{path}: a game's animation is a .gif or an .mp4")
    if not boards:
        raise ValueError(f"{path}: no positions to animate")
    rgb = board_frames(boards, size_px=size_px, captions=captions)
    if suffix == ".mp4":
        return encode.write_mp4(rgb, path, fps)
    gif = encode.GifFrames(scale=1.0, every=1)
    gif.palette = _gif_palette(rgb)
    for frame in rgb:
        gif.add(frames.pack(frame))
    return gif.save(path, fps)


# --- PGN and SVG -------------------------------------------------------------------------------------------


SEVEN_TAG_ROSTER = ("Event", "Site", "Date", "Round", "White", "Black", "Result")


def result(board: chess.Board) -> str:
    """PGN's result of a game that ended in ``board``: the mating side's win after mate, else a draw."""
    if board.is_checkmate():
        return "0-1" if board.turn == chess.WHITE else "1-0"
    return "1/2-1/2"


def game_pgn(moves: Sequence[chess.Move], start: chess.Board, headers: Mapping[str, str], *,
             comments: Sequence[str] | None = None, comment: str = "") -> chess.pgn.Game:
    """The game of ``moves`` from ``start`` as PGN: the Seven Tag Roster ("?" where ``headers`` leave a tag
    out), ``FEN`` and ``SetUp`` where ``start`` is not the initial position, the result (:func:`result`),
    ``comment`` before the first move and ``comments[i]`` after move ``i`` ("" for none). An illegal start or
    move, or a header that contradicts the game, is refused."""
    if not start.is_valid():
        raise ValueError(f"{start.fen()}: not a legal chess position ({start.status()!r})")
    if comments is not None and len(comments) != len(moves):
        raise ValueError(f"{len(comments)} comments for {len(moves)} moves")
    game = chess.pgn.Game()
    game.setup(start)
    game.comment = comment
    board = start.copy(stack=False)
    node: chess.pgn.GameNode = game
    for index, move in enumerate(moves):
        if not board.is_legal(move):
            raise ValueError(f"move {index + 1}, {move.uci()}, is not legal in {board.fen()}")
        node = node.add_variation(move, comment=comments[index] if comments is not None else "")
        board.push(move)
    game.headers["Result"] = result(board)
    for key, value in headers.items():
        if key in ("Result", "FEN", "SetUp") and game.headers.get(key) != value:
            raise ValueError(f"header {key} {value!r} contradicts the game's {game.headers.get(key)!r}")
        game.headers[key] = value
    return game


def write_pgn(path: Path, games: Iterable[chess.pgn.Game]) -> Path:
    """``games`` as one PGN file (UTF-8, lines of at most 80 characters, a blank line after each game), written
    atomically."""
    texts = [game.accept(chess.pgn.StringExporter(columns=80)) for game in games]
    if not texts:
        raise ValueError(f"{path}: no games")
    store.write_bytes_atomic(Path(path), "".join(f"{text}\n\n" for text in texts).encode())
    return Path(path)


def board_svg(board: chess.Board, *, lastmove: chess.Move | None = None, arrow: bool = True, size: int = 360,
              coordinates: bool = True, fill: Mapping[chess.Square, str] | None = None) -> str:
    """python-chess's SVG of ``board`` in :func:`draw_board`'s colours: the last move (``lastmove``, else the
    board's own) marked and, with ``arrow``, drawn as an arrow; a king in check in red; ``fill`` colours squares."""
    if lastmove is None and board.move_stack:
        lastmove = board.peek()
    arrows = [chess.svg.Arrow(lastmove.from_square, lastmove.to_square)] if arrow and lastmove is not None else []
    check = board.king(board.turn) if board.is_check() else None
    return str(chess.svg.board(board, lastmove=lastmove, check=check, arrows=arrows, fill=dict(fill or {}),
                               size=size, coordinates=coordinates, colors=SVG_COLORS))
