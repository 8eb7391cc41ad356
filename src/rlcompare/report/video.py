"""Videos of the greedy agents at the stages of learning, in the pictures Gymnasium's own renderer draws.

The paper shows "three videos showing how the agents solve the problem in three stages of learning". For one run
directory and one training seed, :func:`plan_stage_videos` plans a video per stage (``config.stages``), and
:func:`render_videos` loads each stage's stored Q-table, plays one episode of its greedy policy from the start state
of ``env.reset(seed=episode_seed)`` (the same for every stage, so the videos differ only by what was learned), and
writes an H.264 MP4 and a small looping GIF. The random baseline, whose stages would all show the same
policy, gets one video of its seeded random policy.

Frames are played by :mod:`rlcompare.report.play`, captioned by :mod:`rlcompare.report.captions` above Gymnasium's
untouched picture, and encoded by :mod:`rlcompare.report.encode`. Videos render in worker processes
(:func:`render_videos`; by default one per two cores, :func:`default_workers`) or in the background while the
report draws its figures (:func:`start_videos`), byte for byte the same whatever the number of workers. Workers
start with ``spawn``, so a script that renders in other processes needs the ``if __name__ == "__main__":`` guard.
What it costs: the README, "How long it takes".
"""

from __future__ import annotations

import concurrent.futures
import functools
import multiprocessing
import os
import time
from collections.abc import Iterable, Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rlcompare.experiment import rundir, store
from rlcompare.experiment.engines import front, load_run
from rlcompare.report import captions, frames
from rlcompare.report.encode import FPS, GIF_EVERY, GIF_SCALE, MP4_EVERY, GifFrames, mp4_writer
from rlcompare.report.play import Agent, Frame, play
from rlcompare.tabular.config import ExperimentConfig

DEFAULT_EPISODE_SEED = 10_000
"""Seed of ``env.reset`` for the recorded episode: one start state shared by every video, apart from the
start states of training (seed ``s`` trains from ``env.reset(seed=s)`` onwards)."""


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


# --- recording ------------------------------------------------------------------------------------


def record_episode(agent: Agent, *, episode_seed: int, max_steps: int = 1000, title: str | None = None,
                   seed: int | None = None, env_id: str) -> Episode:
    """Play one episode of ``agent`` from ``env.reset(seed=episode_seed)`` and keep every frame.

    Without ``title`` the frames are Gymnasium's own; with it each frame is captioned with the title
    and the return so far (``seed``, the training seed, goes on the caption's second line). For long
    episodes the frames take memory (about 0.8 MB each); :func:`render_videos` streams instead.
    """
    played: Iterable[Frame] = play(agent, episode_seed, max_steps, env_id)
    images, returns = [], []
    last: Frame | None = None
    if title is None:
        for frame in played:
            if frame.picture is None:  # not drawn: none is here, as every step is drawn
                continue
            images.append(frames.unpack(frame.picture))
            returns.append(frame.return_so_far)
            last = frame
    else:
        for image, frame in captions.captioned(played, title, seed=seed, episode_seed=episode_seed,
                                               max_steps=max_steps, env_id=env_id):
            images.append(frames.unpack(image))
            returns.append(frame.return_so_far)
            last = frame
    assert last is not None
    return Episode(frames=images, returns=np.asarray(returns, dtype=np.float64), length=last.step,
                   terminated=last.terminated)


# --- stage videos ---------------------------------------------------------------------------------


def _render_video(agent: Agent, title: str, mp4: Path, gif: Path | None, *, seed: int, episode_seed: int,
                  max_steps: int, fps: float, env_id: str) -> list[Path]:
    """Play, caption and encode one video in a single pass: ffmpeg encodes in its own process while
    Python renders the next frames, and no more than one frame is held in memory (plus the GIF's).

    The episode plays at ``fps`` steps a second; the MP4 shows every :data:`MP4_EVERY`-th step and the GIF every
    :data:`GIF_EVERY`-th (each also the last), and only the steps one of them shows are drawn."""
    small = GifFrames(GIF_SCALE, GIF_EVERY) if gif is not None else None

    def drawn(step: int) -> bool:
        return step % MP4_EVERY == 0 or (small is not None and small.wanted(step))

    captioned = captions.captioned(play(agent, episode_seed, max_steps, env_id, drawn), title, seed=seed,
                                   episode_seed=episode_seed, max_steps=max_steps, env_id=env_id)
    with mp4_writer(mp4, fps / MP4_EVERY) as writer:
        for packed, frame in captioned:
            last = frame.terminated or frame.truncated
            if frame.step % MP4_EVERY == 0 or last:
                writer.append(packed)
            if small is not None and (small.wanted(frame.step) or last):
                small.add_at(frame.step, packed)
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


@functools.lru_cache(maxsize=2)
def _loaded_run(run_dir: Path, signature: tuple[int, ...]) -> Any:
    """The run in ``run_dir``, loaded (and verified) once for the several videos of one run a process renders;
    ``signature`` (its ``meta.json``'s inode, size and time, which a rewrite of the run changes) keys it."""
    return load_run(run_dir)


def _agent(job: VideoJob) -> Any:
    meta = os.stat(job.run_dir / rundir.META_FILE)
    results = _loaded_run(Path(job.run_dir).absolute(), (meta.st_ino, meta.st_size, meta.st_mtime_ns))
    return front(results.config).agent(results, job.seed, job.stage)


def render_job(job: VideoJob) -> list[Path]:
    """Load the agent of ``job`` and render its video (MP4, then GIF); the paths written."""
    agent = _agent(job)
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
    """The videos of training seed ``seed`` in ``run_dir``, one per stage of learning, for :func:`render_videos`.

    Files are ``{config.name}-seed{seed}-{stage}.mp4`` (and ``.gif`` where ``gif``) in ``out_dir``, in stage order.
    ``stages`` defaults to the run's ``config.stages``; ``max_steps`` to the run's episode limit. The random
    baseline gets one video, ``random-seed{seed}.mp4`` (``stages`` is then ignored), since its policy does not change
    with training. ``config`` is the run's, where the caller has loaded it already; else it is read from
    ``run_dir``. Unknown seeds and stages raise :class:`KeyError` here, before anything is rendered. Several runs'
    plans rendered together share one pool of workers.
    """
    run_dir, out_dir = Path(run_dir), Path(out_dir)
    config = load_run(run_dir).config if config is None else config
    known = [name for name, _ in config.stages]
    if seed not in config.seeds:
        raise KeyError(f"seed {seed} is not in this run; seeds: {list(config.seeds)}")
    limit = config.step_limit if max_steps is None else int(max_steps)
    if config.algorithm == "random":
        plan = [(known[-1], captions.stage_title(config, None), f"{config.name}-seed{seed}")]
    else:
        chosen = known if stages is None else list(stages)
        unknown = [name for name in chosen if name not in known]
        if unknown:
            raise KeyError(f"stage {unknown[0]!r} is not in this run; stages: {known}")
        plan = [(name, captions.stage_title(config, name), f"{config.name}-seed{seed}-{name}") for name in chosen]
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

    def stop(self) -> None:
        """End the worker processes now, renders in flight with them (each file is written atomically, so no half
        video is left under its name), and wait until they are gone: nothing of theirs writes afterwards."""
        if self._pool is None:
            return
        workers = list((getattr(self._pool, "_processes", None) or {}).values())  # the executor lists no public handle
        manager = getattr(self._pool, "_executor_manager_thread", None)
        self._pool.shutdown(wait=False, cancel_futures=True)
        for process in workers:
            process.terminate()
        for process in workers:
            process.join()
        if manager is not None:
            # The executor's own thread closes its wake-up pipe once it sees the workers gone; left running, it
            # races Python 3.11's exit hook, which writes to that pipe (OSError: Bad file descriptor, a traceback
            # after "Terminated").
            manager.join(timeout=10)

    def __enter__(self) -> VideoRenders:
        return self

    def __exit__(self, kind: type[BaseException] | None, *rest: object) -> None:
        """Leaving normally, or on an error of a render: :meth:`close`. On an interrupt or SIGTERM: :meth:`stop`."""
        if kind is not None and issubclass(kind, KeyboardInterrupt | SystemExit):
            self.stop()
        else:
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
