"""The caption strip above a video's frame, drawn in packed pixels (:mod:`rlcompare.report.frames`).

A caption strip is added above Gymnasium's 600x400 frame (the picture itself is left untouched): the
algorithm, the exploration schedule, the stage with the number of training episodes behind it, and the
return so far (the final return on the last frame); a second, smaller line gives the training seed, the
start-state seed and the step, and on the last frame whether the car reached the flag or ran out of time.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Iterator, Sequence
from functools import lru_cache
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from rlcompare.algorithms.registry import label as method_label
from rlcompare.envs.registry import environment
from rlcompare.report import frames
from rlcompare.report.play import Frame
from rlcompare.tabular.config import ExperimentConfig

CAPTION_HEIGHT = 48
"""Height in pixels of the caption strip above the frame (even, so H.264 frame sizes stay even)."""

_CAPTION_BACKGROUND = (255, 255, 255)
_CAPTION_TEXT = (0, 0, 0)
_CAPTION_DETAIL = (90, 90, 90)
_CAPTION_RULE = (200, 200, 200)
"""The caption's colours are greys, and so is every anti-aliased pixel of its text: of two packed grey pixels the
darker is the smaller word, so the strip is drawn in packed pixels directly."""
_PAD = 2
_DIGITS = re.compile(r"\d|\D+")


@lru_cache(maxsize=8)
def _font(size: int) -> ImageFont.FreeTypeFont | ImageFont.ImageFont:
    """DejaVu Sans (shipped with matplotlib, a dependency): Pillow's default font has no ε."""
    try:
        import matplotlib

        return ImageFont.truetype(str(Path(matplotlib.get_data_path()) / "fonts" / "ttf" / "DejaVuSans.ttf"), size)
    except (ImportError, OSError):  # pragma: no cover - matplotlib is a dependency
        return ImageFont.load_default(size=size)


_SPECIAL = {"ε": "epsilon", "·": "-"}


@lru_cache(maxsize=8)
def _missing_glyphs(size: int) -> tuple[str, ...]:
    """The special characters of the captions that the font at ``size`` cannot draw."""
    font = _font(size)
    missing = font.getmask("\ufffe").getbbox()
    return tuple(ch for ch in _SPECIAL if font.getmask(ch).getbbox() == missing)


def _drawable(size: int, text: str) -> str:
    for ch in _missing_glyphs(size):
        text = text.replace(ch, _SPECIAL[ch])
    return text


@lru_cache(maxsize=4096)
def _text_image(text: str, size: int, color: tuple[int, int, int]) -> tuple[np.ndarray, float]:
    """``text`` in ``color`` on the caption background, packed, and how far it advances the pen."""
    font = _font(size)
    text = _drawable(size, text)
    advance = font.getlength(text)
    image = Image.new("RGB", (math.ceil(advance) + 2 * _PAD, round(size * 1.4)), _CAPTION_BACKGROUND)
    ImageDraw.Draw(image).text((_PAD, 0), text, font=font, fill=color)
    pixels = frames.pack(np.asarray(image))
    pixels.flags.writeable = False
    return pixels, advance


@lru_cache(maxsize=8)
def _blank_strip(width: int, height: int) -> np.ndarray:
    strip = np.empty((height, width), dtype=np.uint32)
    strip[:] = frames.pack(np.array([[_CAPTION_BACKGROUND]], dtype=np.uint8))
    strip[-1] = frames.pack(np.array([[_CAPTION_RULE]], dtype=np.uint8))
    strip.flags.writeable = False
    return strip


_Line = tuple[Sequence[str], int, tuple[int, int, int]]
"""A caption line: its pieces (drawn one after the other), font size and colour."""


def _draw(strip: np.ndarray, x: float, y: int, line: _Line) -> None:
    """Draw a line's pieces on the strip, one after the other.

    Each piece is rasterised once and cached: a caption whose numbers change every frame is split into a
    fixed head and single digits (DejaVu Sans has tabular digits, no kerning), so it costs a few array
    copies. Text is darker than the background, so where pieces overlap the darker pixel is kept.
    """
    pieces, size, color = line
    for piece in pieces:
        pixels, advance = _text_image(piece, size, color)
        left = round(x) - _PAD
        h, w = min(pixels.shape[0], strip.shape[0] - 1 - y), min(pixels.shape[1], strip.shape[1] - left)
        if h > 0 and w > 0:
            region = strip[y:y + h, left:left + w]
            np.minimum(region, pixels[:h, :w], out=region)
        x += advance


def _draw_strip(strip: np.ndarray, title: Sequence[str], detail: Sequence[str]) -> None:
    """The caption's two lines on a packed strip, in place."""
    height, width = strip.shape
    strip[:] = _blank_strip(width, height)
    big, small = max(8, round(height * 0.36)), max(8, round(height * 0.27))
    _draw(strip, 8, round(height * 0.06), (title, big, _CAPTION_TEXT))
    _draw(strip, 8, round(height * 0.56), (detail, small, _CAPTION_DETAIL))


def add_caption(frame: np.ndarray, title: str, detail: str = "") -> np.ndarray:
    """``frame`` ((H, W, 3) uint8) under a caption strip: ``(H + CAPTION_HEIGHT, W, 3)``, the frame's pixels
    unchanged."""
    return frames.unpack(_stack(frames.pack(frame), (title,), (detail,) if detail else (), None))


def _stack(picture: np.ndarray, title: Sequence[str], detail: Sequence[str], out: np.ndarray | None) -> np.ndarray:
    """A packed picture under its caption strip, in ``out`` (a new frame if None)."""
    height, width = picture.shape
    if out is None:
        out = np.empty((height + CAPTION_HEIGHT, width), dtype=np.uint32)
    _draw_strip(out[:CAPTION_HEIGHT], title, detail)
    out[CAPTION_HEIGHT:] = picture
    return out


def _caption_pieces(title: str, frame: Frame, *, seed: int | None, episode_seed: int,
                    max_steps: int, env_id: str) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """The two caption lines of a frame, split into a fixed head (cached once drawn) and what changes."""
    finished = frame.terminated or frame.truncated
    ret = f"{'final return' if finished else 'return'} {frame.return_so_far:.0f}"
    head = f"training seed {seed} · " if seed is not None else ""
    head += f"start state: reset(seed={episode_seed}) · "
    detail = [head, *_DIGITS.findall(f"step {frame.step}/{max_steps}")]
    terminated, truncated = environment(env_id).endings
    if frame.terminated:
        detail.append(f" · {terminated}")
    elif frame.truncated:
        detail.append(f" · {truncated}")
    return (f"{title} · ", *_DIGITS.findall(ret)), tuple(detail)


def captioned(played: Iterable[Frame], title: str, *, seed: int | None, episode_seed: int,
              max_steps: int, env_id: str) -> Iterator[tuple[np.ndarray, Frame]]:
    """Each frame under its caption, packed, in one reused buffer (copy it to keep it); a frame without a picture
    (not drawn, :func:`~rlcompare.report.play.play`) is passed over."""
    buffer = None
    for frame in played:
        if frame.picture is None:
            continue
        line, detail = _caption_pieces(title, frame, seed=seed, episode_seed=episode_seed, max_steps=max_steps,
                                       env_id=env_id)
        buffer = _stack(frame.picture, line, detail, buffer)
        yield buffer, frame


def stage_title(config: ExperimentConfig, stage: str | None) -> str:
    """``SARSA · ε decay · middle (episode 2500)``; the random baseline: ``Random · uniform actions``."""
    name = method_label(config.algorithm)
    algorithm = name[:1].upper() + name[1:]
    if config.algorithm == "random" or stage is None:
        return f"{algorithm} · uniform actions" if config.algorithm == "random" else algorithm
    schedule = "ε decay" if config.schedule == "decay" else f"ε = {config.epsilon:g}"
    return f"{algorithm} · {schedule} · {stage} (episode {config.stage_episodes()[stage]})"
