"""Packed frames (:mod:`rlcompare.report.frames`) written as an H.264 MP4 and a small looping GIF, each
file atomically.

The YUV planes ffmpeg encodes are computed here (0.2 ms a frame; ffmpeg's own conversion from RGB took 1.1 ms
of its time), and ffmpeg encodes in its own process while the caller renders the next frames.
"""

from __future__ import annotations

import contextlib
import itertools
import os
import secrets
from collections.abc import Generator, Iterable, Iterator
from pathlib import Path

import numpy as np
from PIL import Image

from rlcompare.experiment import store
from rlcompare.report import frames

FPS = 30
"""Steps of an episode a second, its real-time speed: Gymnasium's ``render_fps`` for MountainCar (and the frame
rate of :func:`write_mp4`, which encodes every frame it is given)."""
MP4_EVERY = 2
"""An episode's MP4 shows every second step (and the last), at ``FPS / MP4_EVERY`` = 15 frames a second, so it
plays in real time: the car moves a few pixels a step and still glides, and drawing and encoding take half the
time (x264 was the slowest part of a video)."""
MP4_OPTIONS = ("-preset", "veryfast", "-x264-params", "me=dia:subme=0:bframes=0", "-crf", "23", "-threads", "1",
               "-movflags", "+faststart")
"""x264 settings: fast to encode and small files (the picture is mostly flat white). CRF 23 rather than 28:
at 28 the digits of the caption smear into those of the frame before; 23 costs no time and keeps a
1000-step video near 260 kB at 15 frames a second. The diamond motion search at whole pixels without B-frames
(``me=dia:subme=0:bframes=0``) takes a third less time than ``veryfast``'s own for about 8% more bytes. One thread
per encoder, so the bytes do not depend on the number of cores (the encoder runs beside the renderer anyway);
``+faststart`` lets a browser play it while it loads."""
GIF_COLORS = 64
GIF_SCALE = 0.5
GIF_EVERY = 3
"""The GIF is a small preview beside the MP4: every third frame (10 a second) at half size in 64 colours. At every
second frame it took a third of the Python side's time."""
GIF_HOLD_MS = 1000
"""The GIF shows its last frame (with the final return) this much longer before it loops."""


def _even(packed: np.ndarray) -> np.ndarray:
    """Pad an odd height or width by repeating the last row or column (H.264 4:2:0 needs even sizes)."""
    height, width = packed.shape
    if height % 2 or width % 2:
        return np.pad(packed, ((0, height % 2), (0, width % 2)), mode="edge")
    return packed


def _rgb(frame: np.ndarray) -> np.ndarray:
    frame = np.asarray(frame)
    if frame.dtype != np.uint8 or frame.ndim != 3 or frame.shape[2] != 3:
        raise ValueError(f"frames must be (H, W, 3) uint8; got {frame.shape} {frame.dtype}")
    return frame


class _Mp4Encoder:
    """ffmpeg encoding packed frames to ``path``: each frame turned into its YUV planes here (ffmpeg's own
    conversion from RGB took as long as the encoding) and piped to ffmpeg, which starts at the first frame."""

    def __init__(self, path: Path, fps: float) -> None:
        self.path, self.fps = path, fps
        self._ffmpeg: Generator[None, np.ndarray | None, None] | None = None
        self._planes = np.empty(0, dtype=np.uint8)

    def append(self, packed: np.ndarray) -> None:
        packed = _even(packed)
        if self._ffmpeg is None:
            import imageio_ffmpeg

            height, width = packed.shape
            self._ffmpeg = imageio_ffmpeg.write_frames(
                str(self.path), (width, height), pix_fmt_in="yuv420p", pix_fmt_out="yuv420p", fps=self.fps,
                codec="libx264", quality=None, macro_block_size=1, output_params=list(MP4_OPTIONS))
            self._ffmpeg.send(None)
            self._planes = np.empty(height * width * 3 // 2, dtype=np.uint8)
        frames.yuv420(packed, self._planes)
        self._ffmpeg.send(self._planes)

    def close(self) -> None:
        if self._ffmpeg is not None:
            self._ffmpeg.close()


@contextlib.contextmanager
def mp4_writer(path: Path, fps: float) -> Iterator[_Mp4Encoder]:
    """An encoder to a temporary file beside ``path``, renamed onto it when all went well."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    store.enter_outputs(path)
    tmp = path.with_name(f".{path.name}.{secrets.token_hex(4)}.tmp.mp4")
    writer = _Mp4Encoder(tmp, fps)
    try:
        yield writer
        writer.close()
        if not tmp.is_file():
            raise OSError(f"{path}: ffmpeg wrote no file (were there no frames?)")
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(Exception):
            writer.close()
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def write_mp4(rgb_frames: Iterable[np.ndarray], path: Path, fps: float = FPS) -> Path:
    """Encode ``rgb_frames`` ((H, W, 3) uint8, any iterable) as an H.264 MP4 that browsers play.

    libx264, yuv420p, ``+faststart``; odd sizes are padded to even ones. Written atomically.
    """
    path = Path(path)
    count = 0
    with mp4_writer(path, fps) as writer:
        for frame in rgb_frames:
            writer.append(frames.pack(_rgb(frame)))
            count += 1
        if count == 0:
            raise ValueError("write_mp4: no frames")
    return path


class GifFrames:
    """Every ``every``-th packed frame (and the last), scaled by ``scale`` and mapped to one shared palette."""

    def __init__(self, scale: float, every: int) -> None:
        if not 0 < scale <= 1:
            raise ValueError(f"scale must be in (0, 1]; got {scale}")
        if every < 1:
            raise ValueError(f"every must be >= 1; got {every}")
        self.scale, self.every = scale, every
        self.images: list[Image.Image] = []
        self.indices: list[int] = []
        """Index in the source of each kept frame."""
        self.palette: Image.Image | None = None
        self.count = 0
        self._pending: np.ndarray | None = None

    def _reduce(self, packed: np.ndarray) -> Image.Image:
        if self.scale == 0.5 and not (packed.shape[0] % 2 or packed.shape[1] % 2):
            image = frames.image(frames.halved(packed))  # Pillow's 2x2 box mean, pixel for pixel, 9x as fast
        else:
            image = frames.image(packed)
            size = (max(1, round(image.width * self.scale)), max(1, round(image.height * self.scale)))
            image = image.resize(size, Image.Resampling.BOX, reducing_gap=1.0) if self.scale < 1 else image
        if self.palette is None:
            self.palette = image.quantize(colors=GIF_COLORS, method=Image.Quantize.MEDIANCUT,
                                          dither=Image.Dither.NONE)
        return image.quantize(palette=self.palette, dither=Image.Dither.NONE)

    def wanted(self, index: int) -> bool:
        """Whether frame ``index`` of the source is kept (the last one is too: give it to :meth:`add_at`)."""
        return index % self.every == 0

    def add_at(self, index: int, packed: np.ndarray) -> None:
        """Frame ``index`` of the source, given where :meth:`wanted` says so and for the last frame, in order: the
        same GIF as :meth:`add` of every frame, without the frames it leaves out."""
        self.images.append(self._reduce(packed))
        self.indices.append(index)
        self.count = index + 1

    def add(self, packed: np.ndarray) -> None:
        if self.count % self.every == 0:
            self.images.append(self._reduce(packed))
            self.indices.append(self.count)
            self._pending = None
        else:
            self._pending = packed.copy()  # kept in case it is the last frame
        self.count += 1

    def finish(self) -> list[Image.Image]:
        if self._pending is not None:
            self.images.append(self._reduce(self._pending))
            self.indices.append(self.count - 1)
            self._pending = None
        return self.images

    def durations(self, fps: float) -> list[int]:
        """Milliseconds each kept frame is shown, so the GIF keeps real time although GIF delays are whole
        centiseconds: each frame starts at its source time rounded to 10 ms."""
        starts = [10 * round(100 * index / fps) for index in [*self.indices, self.count]]
        durations = [b - a for a, b in itertools.pairwise(starts)]
        durations[-1] += GIF_HOLD_MS
        return durations

    def save(self, path: Path, fps: float) -> Path:
        images = self.finish()
        if not images:
            raise ValueError("write_gif: no frames")
        durations = self.durations(fps)
        store.write_atomic(Path(path), lambda handle: images[0].save(
            handle, format="GIF", save_all=True, append_images=images[1:], duration=durations, loop=0,
            optimize=False, disposal=1))
        return Path(path)


def write_gif(rgb_frames: Iterable[np.ndarray], path: Path, fps: float = FPS, scale: float = GIF_SCALE,
              every: int = GIF_EVERY) -> Path:
    """A small looping GIF of ``rgb_frames``: every ``every``-th frame (and the last), scaled by ``scale``.

    It shows each frame as long as ``every`` frames last at ``fps`` (to the centisecond GIF delays
    allow), so it keeps the real-time speed of an MP4 at ``fps``, and holds the last frame one second
    longer before it loops. Written atomically.
    """
    gif = GifFrames(scale, every)
    for frame in rgb_frames:
        gif.add(frames.pack(_rgb(frame)))
    return gif.save(path, fps)
