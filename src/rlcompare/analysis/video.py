"""Videos of the greedy agents at the stages of learning, in the pictures Gymnasium's own renderer draws.

The paper shows "three videos showing how the agents solve the problem in three stages of learning".
For one run directory (one configuration) and one training seed, :func:`render_stage_videos` loads the
stored Q-table of every stage (``config.stages``; by default early, middle and final), plays one episode
of its greedy policy in ``gymnasium.make(env_id, render_mode="rgb_array")`` (``MountainCar-v0`` for the
paper and the book's variant, whose trajectories are the same) from the start state
of ``env.reset(seed=episode_seed)``, and writes an H.264 MP4 (and a small looping GIF) per stage. Every
stage starts from the same start state, so the videos differ only by what the agent has learned.

A caption strip is added above Gymnasium's 600x400 frame (the picture itself is left untouched): the
algorithm, the exploration schedule, the stage with the number of training episodes behind it, and the
return so far (the final return on the last frame); a second, smaller line gives the training seed, the
start-state seed and the step, and on the last frame whether the car reached the flag or ran out of time.

The random baseline does not learn, so its stages would all show the same policy: it gets one video,
``random-seed{seed}.mp4``, of the uniform random policy (its action stream is seeded by the training seed,
so the video is reproducible).

Rendering needs no display: the first call that renders sets ``SDL_VIDEODRIVER=dummy`` (and hides
pygame's banner) with ``os.environ.setdefault``, so a value set by the user wins. Importing this module
changes nothing.

Videos render in parallel, one per worker process (:func:`render_videos`; ``workers=1`` renders them in
this process, one after the other), or in the background while the caller does other work
(:func:`start_videos`, which the report uses: its own process takes the videos no worker has started once its
figures are done), and the files are the same byte for byte whatever the number of workers. Workers start with
``spawn``, so a script that renders in other processes needs the usual ``if __name__ == "__main__":`` guard.

Frames travel as packed pixels (:mod:`rlcompare.analysis.frames`). Where the environment's registry entry has
a painter (Mountain Car's draws Gymnasium's picture pixel for pixel in 0.15 ms, where ``env.render()`` takes
1.9 ms), it draws them; else ``env.render()`` does. The YUV planes ffmpeg encodes are computed here (0.2 ms a
frame; ffmpeg's own conversion from RGB took 1.1 ms of its time).

Cost, measured on 2 cores: the whole Python side (step, picture, caption, YUV, the GIF's frame) takes about
1.2 ms a frame and ffmpeg about 1.4 ms in its own process meanwhile, so one video keeps about 1.9 cores busy;
the paper's 13 videos (3,022 frames) take 4.9 s. So by default one worker renders per two cores
(:func:`default_workers`). Each worker spends about 1.5 s of a core starting (imports, the compiled grid
lookup), once for all its videos.
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import itertools
import math
import multiprocessing
import os
import re
import secrets
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import NamedTuple, Protocol

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from rlcompare.algorithms.registry import label as method_label
from rlcompare.analysis import frames
from rlcompare.envs.registry import environment
from rlcompare.experiment import store
from rlcompare.experiment.config import ExperimentConfig
from rlcompare.experiment.engines import load_agent
from rlcompare.experiment.results import Results

DEFAULT_EPISODE_SEED = 10_000
"""Seed of ``env.reset`` for the recorded episode: one start state shared by every video, apart from the
start states of training (seed ``s`` trains from ``env.reset(seed=s)`` onwards)."""
FPS = 30
"""Frames per second of the MP4: Gymnasium's ``render_fps`` for MountainCar."""
CAPTION_HEIGHT = 48
"""Height in pixels of the caption strip above the frame (even, so H.264 frame sizes stay even)."""
MP4_OPTIONS = ("-preset", "veryfast", "-x264-params", "me=dia:subme=1", "-crf", "23", "-threads", "1",
               "-movflags", "+faststart")
"""x264 settings: fast to encode and small files (the picture is mostly flat white). CRF 23 rather than 28:
at 28 the digits of the caption smear into those of the frame before; 23 costs no time and keeps a
1000-step video near 340 kB. The diamond motion search and the quickest subpixel refinement (``me=dia:subme=1``)
take a fifth less time than ``veryfast``'s own for 7% more bytes. One thread per encoder, so the bytes do not
depend on the number of cores (the encoder runs beside the renderer anyway); ``+faststart`` lets a browser play
it while it loads."""
GIF_COLORS = 64
GIF_SCALE = 0.5
GIF_EVERY = 3
"""The GIF is a small preview beside the MP4: every third frame (10 a second) at half size in 64 colours. At every
second frame it took a third of the Python side's time."""
GIF_HOLD_MS = 1000
"""The GIF shows its last frame (with the final return) this much longer before it loops."""

_CAPTION_BACKGROUND = (255, 255, 255)
_CAPTION_TEXT = (0, 0, 0)
_CAPTION_DETAIL = (90, 90, 90)
_CAPTION_RULE = (200, 200, 200)
"""The caption's colours are greys, and so is every anti-aliased pixel of its text: of two packed grey pixels the
darker is the smaller word, so the strip is drawn in packed pixels directly."""
_PAD = 2
_DIGITS = re.compile(r"\d|\D+")


class Agent(Protocol):
    def act(self, observation: np.ndarray) -> int: ...


@dataclass(frozen=True)
class Episode:
    """One recorded episode: ``length + 1`` frames, the start frame included."""

    frames: list[np.ndarray]
    """(H, W, 3) uint8 each: Gymnasium's (400, 600, 3), or (448, 600, 3) with a caption."""
    returns: np.ndarray
    """(length + 1,) return so far at each frame; 0 at the start frame."""
    length: int
    """Steps taken."""
    terminated: bool
    """The episode reached a terminal state, the car the flag (else the step limit truncated it)."""

    @property
    def episode_return(self) -> float:
        return float(self.returns[-1])


class _Frame(NamedTuple):
    picture: np.ndarray
    """The environment's picture, packed (:mod:`rlcompare.analysis.frames`), in a buffer the next frame reuses."""
    step: int
    return_so_far: float
    terminated: bool
    truncated: bool


def _headless() -> None:
    """Let pygame render without a display and without its banner; a value the user set wins."""
    os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
    os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")


def _play(agent: Agent, episode_seed: int, max_steps: int, env_id: str) -> Iterator[_Frame]:
    """Step ``agent`` through one rendered episode, yielding the start frame and one frame per step."""
    _headless()
    import gymnasium as gym  # after _headless: gymnasium imports pygame when it first renders

    env = gym.make(env_id, render_mode="rgb_array", max_episode_steps=max_steps)
    try:
        observation, _ = env.reset(seed=episode_seed)
        picture = _painter(env, env_id)
        total, step, terminated, truncated = 0.0, 0, False, False
        yield _Frame(picture(), step, total, terminated, truncated)
        while not (terminated or truncated):
            observation, reward, terminated, truncated, _ = env.step(agent.act(observation))
            total += float(reward)
            step += 1
            yield _Frame(picture(), step, total, bool(terminated), bool(truncated))
    finally:
        env.close()


def _painter(env, env_id: str) -> Callable[[], np.ndarray]:
    """What draws ``env``'s current picture, packed: the registry's painter, equal to ``env.render()`` and
    quicker, where the environment has one; else ``env.render()`` itself."""
    painter = environment(env_id).painter
    if painter is None:
        return lambda: frames.pack(env.render())
    drawn = painter(env.unwrapped)
    buffer = np.empty(drawn.size[::-1], dtype=np.uint32)

    def picture() -> np.ndarray:
        drawn.paint(buffer)
        return buffer
    return picture


# --- captions -------------------------------------------------------------------------------------


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


def _caption_pieces(title: str, frame: _Frame, *, seed: int | None, episode_seed: int,
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


def _captioned(played: Iterable[_Frame], title: str, *, seed: int | None, episode_seed: int,
               max_steps: int, env_id: str) -> Iterator[tuple[np.ndarray, _Frame]]:
    """Each frame under its caption, packed, in one reused buffer (copy it to keep it)."""
    buffer = None
    for frame in played:
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


# --- recording ------------------------------------------------------------------------------------


def record_episode(agent: Agent, *, episode_seed: int, max_steps: int = 1000, title: str | None = None,
                   seed: int | None = None, env_id: str) -> Episode:
    """Play one episode of ``agent`` from ``env.reset(seed=episode_seed)`` and keep every frame.

    Without ``title`` the frames are Gymnasium's own; with it each frame is captioned with the title
    and the return so far (``seed``, the training seed, goes on the caption's second line). For long
    episodes the frames take memory (about 0.8 MB each); :func:`render_stage_videos` streams instead.
    """
    played: Iterable[_Frame] = _play(agent, episode_seed, max_steps, env_id)
    images, returns = [], []
    last: _Frame | None = None
    if title is None:
        for frame in played:
            images.append(frames.unpack(frame.picture))
            returns.append(frame.return_so_far)
            last = frame
    else:
        for image, frame in _captioned(played, title, seed=seed, episode_seed=episode_seed, max_steps=max_steps,
                                       env_id=env_id):
            images.append(frames.unpack(image))
            returns.append(frame.return_so_far)
            last = frame
    assert last is not None
    return Episode(frames=images, returns=np.asarray(returns, dtype=np.float64), length=last.step,
                   terminated=last.terminated)


# --- writing --------------------------------------------------------------------------------------


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
        self._ffmpeg: Iterator | None = None
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
def _mp4_writer(path: Path, fps: float) -> Iterator[_Mp4Encoder]:
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
    with _mp4_writer(path, fps) as writer:
        for frame in rgb_frames:
            writer.append(frames.pack(_rgb(frame)))
            count += 1
        if count == 0:
            raise ValueError("write_mp4: no frames")
    return path


class _GifFrames:
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
    gif = _GifFrames(scale, every)
    for frame in rgb_frames:
        gif.add(frames.pack(_rgb(frame)))
    return gif.save(path, fps)


# --- stage videos ---------------------------------------------------------------------------------


def _render_video(agent: Agent, title: str, mp4: Path, gif: Path | None, *, seed: int, episode_seed: int,
                  max_steps: int, fps: float, env_id: str) -> list[Path]:
    """Play, caption and encode one video in a single pass: ffmpeg encodes in its own process while
    Python renders the next frames, and no more than one frame is held in memory (plus the GIF's)."""
    captioned = _captioned(_play(agent, episode_seed, max_steps, env_id), title, seed=seed,
                           episode_seed=episode_seed, max_steps=max_steps, env_id=env_id)
    small = _GifFrames(GIF_SCALE, GIF_EVERY) if gif is not None else None
    with _mp4_writer(mp4, fps) as writer:
        for packed, _ in captioned:
            writer.append(packed)
            if small is not None:
                small.add(packed)
    if small is None or gif is None:
        return [mp4]
    return [mp4, small.save(gif, fps)]


@dataclass(frozen=True)
class VideoJob:
    """One video to render: paths and numbers only, so it pickles small for a worker process, which loads
    the agent from the run directory itself."""

    run_dir: Path
    seed: int
    """Training seed of the agent."""
    stage: str
    """Stage whose Q-table is loaded (the random baseline: the last; its policy does not depend on it)."""
    title: str
    mp4: Path
    gif: Path | None
    episode_seed: int
    max_steps: int
    fps: float
    env_id: str

    @property
    def outputs(self) -> list[Path]:
        """The files it writes: the MP4, then the GIF if any."""
        return [self.mp4] if self.gif is None else [self.mp4, self.gif]


def render_job(job: VideoJob) -> list[Path]:
    """Load the agent of ``job`` and render its video (MP4, then GIF); the paths written."""
    agent = load_agent(job.run_dir, seed=job.seed, stage=job.stage)
    return _render_video(agent, job.title, job.mp4, job.gif, seed=job.seed, episode_seed=job.episode_seed,
                         max_steps=job.max_steps, fps=job.fps, env_id=job.env_id)


def plan_stage_videos(
    run_dir: Path,
    out_dir: Path,
    *,
    seed: int,
    stages: Sequence[str] | None = None,
    episode_seed: int = DEFAULT_EPISODE_SEED,
    max_steps: int | None = None,
    gif: bool = True,
    fps: float = FPS,
    config: ExperimentConfig | None = None,
) -> list[VideoJob]:
    """The videos :func:`render_stage_videos` renders, in its order, without rendering any.

    ``config`` is the run's, where the caller has loaded it already; else it is read from ``run_dir``.
    Unknown seeds and stages raise :class:`KeyError` here, before anything is rendered.
    """
    run_dir, out_dir = Path(run_dir), Path(out_dir)
    config = Results.load(run_dir).config if config is None else config
    known = [name for name, _ in config.stages]
    if seed not in config.seeds:
        raise KeyError(f"seed {seed} is not in this run; seeds: {list(config.seeds)}")
    limit = config.max_steps if max_steps is None else int(max_steps)
    if config.algorithm == "random":
        plan = [(known[-1], stage_title(config, None), f"{config.name}-seed{seed}")]
    else:
        chosen = known if stages is None else list(stages)
        unknown = [name for name in chosen if name not in known]
        if unknown:
            raise KeyError(f"stage {unknown[0]!r} is not in this run; stages: {known}")
        plan = [(name, stage_title(config, name), f"{config.name}-seed{seed}-{name}") for name in chosen]
    return [VideoJob(run_dir=run_dir, seed=int(seed), stage=stage, title=title, mp4=out_dir / f"{stem}.mp4",
                     gif=out_dir / f"{stem}.gif" if gif else None, episode_seed=int(episode_seed), max_steps=limit,
                     fps=float(fps), env_id=config.environment.gymnasium_id)
            for stage, title, stem in plan]


_START_METHOD = "spawn"
"""How worker processes start: fresh interpreters (not ``fork``, which would copy the parent's threads and
open renderers); each imports what it needs, about 1.5 s of one core, once for all its videos."""


def default_workers() -> int:
    """Processes that render at once by default: one per two cores, since each render keeps about 1.9
    cores busy (Python steps and draws, ffmpeg encodes beside it); so 1 on 2 cores."""
    return max(1, (os.cpu_count() or 1) // 2)


class VideoRenders:
    """Videos being rendered, from :func:`start_videos`; :meth:`wait` for their paths.

    In the ``background``, or with more than one worker and more than one job, they render in a pool of worker
    processes, started at once, so the caller can do other work meanwhile; otherwise they render in this
    process when :meth:`wait` is called. Use it as a context manager: leaving the block cancels what has not started
    and waits for what has (a render is never cut off halfway; each file is written atomically anyway).
    """

    def __init__(self, jobs: Sequence[VideoJob], workers: int | None = None, *, background: bool = False) -> None:
        workers = default_workers() if workers is None else int(workers)
        if workers < 1:
            raise ValueError(f"workers must be >= 1; got {workers}")
        self.jobs = list(jobs)
        self.workers = min(workers, len(self.jobs))
        self._pool: ProcessPoolExecutor | None = None
        self._futures: list[Future[list[Path]]] = []
        self.started: float | None = None
        """``time.perf_counter()`` when rendering began: here with a pool, else when :meth:`wait` was called."""
        if self.workers > 1 or (background and self.workers):
            self.started = time.perf_counter()
            # Workers enter nothing in a directory's list of outputs (each process would rewrite the list
            # from what it read): every file is entered here, once, before any is rendered.
            for paths in _by_directory(path for job in self.jobs for path in job.outputs):
                store.enter_outputs(*paths)
            self._pool = ProcessPoolExecutor(self.workers, mp_context=multiprocessing.get_context(_START_METHOD))
            try:
                self._futures = [self._pool.submit(render_job, job) for job in self.jobs]
            except BaseException:
                self.close()
                raise

    def wait(self) -> list[Path]:
        """The files written, in the jobs' order, each MP4 followed by its GIF.

        Jobs no worker has started by then are rendered here, from the last one back, while the workers go on
        from the first: the caller has done its own work and its core is free. The first job (in their order)
        that failed raises what it raised, as it would in this process; the others that had not started are
        cancelled.
        """
        if self._pool is None:
            self.started = time.perf_counter()
            return [path for job in self.jobs for path in render_job(job)]
        for index in reversed(range(len(self.jobs))):
            if not self._futures[index].cancel():
                break  # a worker has it, and every job before it
            self._futures[index] = _rendered_here(self.jobs[index])
            if self._futures[index].exception() is not None:
                break
        concurrent.futures.wait(self._futures, return_when=concurrent.futures.FIRST_EXCEPTION)
        if any(f.done() and not f.cancelled() and f.exception() is not None for f in self._futures):
            self.close()  # cancel what has not started, let the rest finish
            for job, future in zip(self.jobs, self._futures, strict=True):
                error = None if future.cancelled() else future.exception()
                if isinstance(error, BrokenProcessPool):
                    raise RuntimeError(f"{job.mp4}: a process rendering the videos died before it finished "
                                       "(killed, out of memory, or started from a script without "
                                       f"'if __name__ == \"__main__\":'?): {error}") from error
                if error is not None:
                    raise error
        return [path for future in self._futures for path in future.result()]

    def close(self) -> None:
        """Cancel the jobs not started and wait for the worker processes to finish the others."""
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)

    def __enter__(self) -> VideoRenders:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()


def _rendered_here(job: VideoJob) -> Future[list[Path]]:
    """``job`` rendered in this process, as a finished future: its paths, or what it raised."""
    future: Future[list[Path]] = Future()
    try:
        future.set_result(render_job(job))
    except Exception as error:
        future.set_exception(error)
    return future


def _by_directory(paths: Iterable[Path]) -> list[list[Path]]:
    groups: dict[Path, list[Path]] = {}
    for path in paths:
        groups.setdefault(Path(path).absolute().parent, []).append(Path(path))
    return list(groups.values())


def start_videos(jobs: Sequence[VideoJob], *, workers: int | None = None) -> VideoRenders:
    """Start rendering ``jobs`` on ``workers`` other processes (default: :func:`default_workers`), so this one
    can do other work meanwhile. Use the result as a context manager and call its ``wait()`` for the paths."""
    return VideoRenders(jobs, workers, background=True)


def render_videos(jobs: Sequence[VideoJob], *, workers: int | None = None) -> list[Path]:
    """Render ``jobs`` on ``workers`` processes (default: :func:`default_workers`; 1: in this process); the
    files, in the jobs' order.

    The files are the same, byte for byte, whatever the number of workers: each video is rendered by one
    process, from the same agent and start state, and x264 runs on one thread.
    """
    with VideoRenders(jobs, workers) as renders:
        return renders.wait()


def render_stage_videos(
    run_dir: Path,
    out_dir: Path,
    *,
    seed: int,
    stages: Sequence[str] | None = None,
    episode_seed: int = DEFAULT_EPISODE_SEED,
    max_steps: int | None = None,
    gif: bool = True,
    fps: float = FPS,
    workers: int | None = None,
) -> list[Path]:
    """One MP4 (and GIF) per stage of learning of training seed ``seed`` in ``run_dir``.

    Files are ``{config.name}-seed{seed}-{stage}.mp4`` / ``.gif`` in ``out_dir``, returned in stage
    order, each MP4 followed by its GIF. ``stages`` defaults to the run's ``config.stages``; ``max_steps``
    to the run's episode limit. The random baseline gets one video, ``random-seed{seed}.mp4`` (``stages``
    is then ignored), since its policy does not change with training.

    The stages render at once on ``workers`` processes (default: :func:`default_workers`; 1: one after
    the other in this process); the files are the same either way. To render several runs' videos in one pool,
    pass their :func:`plan_stage_videos` together to :func:`render_videos`.
    """
    jobs = plan_stage_videos(run_dir, out_dir, seed=seed, stages=stages, episode_seed=episode_seed,
                             max_steps=max_steps, gif=gif, fps=fps)
    return render_videos(jobs, workers=workers)
