"""The run loop, one for every method: episodes of a run with its evaluation rounds and snapshots, and runs
spread over threads.

:func:`train_block` compiles once per combination of (rule, environment, features) types, and numba caches it
on disk; the compiled runs release the GIL, so :func:`train_chunks` puts blocks of runs on each of
``numba.get_num_threads()`` threads.
"""

from __future__ import annotations

import queue
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numba
import numpy as np

from rlcompare.algorithms.registry import METHODS
from rlcompare.compiled import njit
from rlcompare.tabular.borrowed import borrowed
from rlcompare.tabular.episodes import Traces
from rlcompare.tabular.loops import evaluation_episode, train_episode
from rlcompare.tabular.state import (
    AGENT_STREAM,
    ENV_STREAM,
    EVAL_AGENT_STREAM,
    EVAL_ENV_STREAM,
    EVAL_TRANSITION_STREAM,
    TRANSITION_STREAM,
    Records,
    RunState,
    Settings,
)
from rlcompare.tabular.steps import COMPILED_ONLY, by_type, for_instance, snapshot


@njit(inline="always")
def _no_traces(rule: Any, w: np.ndarray) -> Traces:
    return Traces(np.zeros(1), np.empty(1, np.int64), np.zeros(1, np.bool_))


@njit(inline="always")
def _traces(rule: Any, w: np.ndarray) -> Traces:
    return Traces(np.zeros(w.size), np.empty(w.size, np.int64), np.zeros(w.size, np.bool_))


@by_type({m.rule: _traces for m in METHODS.values() if m.family == "traces"}, default=_no_traces)
def workspace(rule: Any, w: np.ndarray) -> Traces:
    """The traces a run of ``rule`` keeps between steps (a stub for methods without)."""
    raise NotImplementedError(COMPILED_ONLY)


@njit(inline="always")
def record_episode(returns: np.ndarray, lengths: np.ndarray, terminated: np.ndarray, at: tuple[int, ...], ret: float,
                   length: int, ended: bool) -> None:
    """Write one episode's return, length and termination at index ``at`` (training or evaluation)."""
    returns[at], lengths[at], terminated[at] = ret, length, ended


@njit(inline="always")
def evaluation_round(settings: Settings, completed: int) -> int:
    """The evaluation round due after ``completed`` episodes, or -1 when none is."""
    if settings.eval_every > 0 and completed % settings.eval_every == 0:
        return completed // settings.eval_every - 1
    return -1


@njit(cache=True, nogil=True)
def train_block(
    first_run: int, stop_run: int, rule: Any, settings: Settings, env: Any, features: Any, state: RunState,
    epsilons: np.ndarray, first_episode: int, stop_episode: int, records: Records,
) -> None:
    """Episodes ``[first_episode, stop_episode)`` of runs ``[first_run, stop_run)``, with their evaluations and
    snapshots, in one call from Python: calling compiled code costs tens of microseconds a call (its arguments'
    types are read), which a study of 50,000 short runs would pay 50,000 times a chunk."""
    eval_episodes = records.eval_returns.shape[2]
    env = borrowed(env)  # an environment's tables, read on every step, counted nowhere (the caller holds them)
    for run in range(first_run, stop_run):
        w, w2, rng = state.w[run], state.w2[run], state.rng[run]
        training, evaluation = for_instance(env, 2 * run), for_instance(env, 2 * run + 1)
        work = workspace(rule, w)
        for episode in range(first_episode, stop_episode):
            ret, length, terminated = train_episode(
                rule, settings, training, features, w, w2, work, epsilons[episode], rng[ENV_STREAM],
                rng[AGENT_STREAM], rng[TRANSITION_STREAM], records.visits[run],
            )
            record_episode(records.returns, records.lengths, records.terminated, (run, episode), ret, length,
                           terminated)
            completed = episode + 1
            round_ = evaluation_round(settings, completed)
            if round_ >= 0:
                for k in range(eval_episodes):
                    ret, length, terminated = evaluation_episode(
                        rule, settings, evaluation, features, w, w2, rng[EVAL_ENV_STREAM], rng[EVAL_AGENT_STREAM],
                        rng[EVAL_TRANSITION_STREAM],
                    )
                    record_episode(records.eval_returns, records.eval_lengths, records.eval_terminated,
                                   (run, round_, k), ret, length, terminated)
            for stage in range(records.snapshot_episodes.size):
                if records.snapshot_episodes[stage] == completed:
                    snapshot(rule, w, w2, records.snapshots[run, stage])


BLOCKS_PER_THREAD = 8
"""Blocks of runs per thread: runs differ in length, and smaller blocks share them out evenly."""


def train_runs(
    rule: Any, settings: Settings, env: Any, features: Any, state: RunState, epsilons: np.ndarray,
    first_episode: int, stop_episode: int, records: Records,
) -> None:
    """Every run over episodes ``[first_episode, stop_episode)``, blocks of runs spread over threads."""
    train_chunks(rule, settings, env, features, state, epsilons, [(first_episode, stop_episode)], records)


def train_chunks(
    rule: Any, settings: Settings, env: Any, features: Any, state: RunState, epsilons: np.ndarray,
    chunks: list[tuple[int, int]], records: Records, progress: Callable[[int], None] | None = None,
) -> None:
    """Every run over each chunk ``[first, stop)`` of episodes in turn (:func:`over_chunks`); ``progress(n)`` is
    called in this thread with the episodes of each chunk once every run has finished it."""
    over_chunks(lambda first_run, stop_run, first, stop: train_block(
        first_run, stop_run, rule, settings, env, features, state, epsilons, first, stop, records),
        state.w.shape[0], chunks, progress)


def over_chunks(train: Callable[[int, int, int, int], None], runs: int, chunks: list[tuple[int, int]],
                progress: Callable[[int], None] | None = None) -> None:
    """Call ``train(first_run, stop_run, first_episode, stop_episode)`` for every block of runs (:func:`run_blocks`)
    and every chunk of episodes, each block's chunks in order, on ``numba.get_num_threads()`` threads.

    A block's next chunk is queued as soon as it finishes one, behind the blocks waiting already, so the blocks go
    through the chunks together but no thread waits for another at the end of a chunk: only the last chunk's
    stragglers leave a thread idle, and the last chunk is cut smaller (:func:`tapered`). (Waiting for every block
    at the end of every chunk cost the paper's study 2-6% of two threads' time.) Each run writes only its own
    slices, so the order changes no result. If a call fails or this thread is interrupted, no further chunk starts
    and the running ones finish before it raises."""
    threads = min(numba.get_num_threads(), runs)
    blocks = run_blocks(runs, threads)
    if threads > 1:
        chunks = tapered(chunks)
    if threads <= 1:
        for first, stop in chunks:
            for first_run, stop_run in blocks:
                train(first_run, stop_run, first, stop)
            if progress is not None:
                progress(stop - first)
        return
    finished: queue.SimpleQueue[tuple[int, int, BaseException | None]] = queue.SimpleQueue()

    def task(block: int, chunk: int) -> None:
        try:
            train(*blocks[block], *chunks[chunk])
            finished.put((block, chunk, None))
        except BaseException as error:  # raised again in the calling thread
            finished.put((block, chunk, error))

    runs_done = [0] * len(chunks)
    reported = 0
    pool = ThreadPoolExecutor(threads)
    try:
        for block in range(len(blocks)):
            pool.submit(task, block, 0)
        for _ in range(len(blocks) * len(chunks)):
            block, chunk, error = finished.get()
            if error is not None:
                raise error
            if chunk + 1 < len(chunks):
                pool.submit(task, block, chunk + 1)
            runs_done[chunk] += blocks[block][1] - blocks[block][0]
            while reported < len(chunks) and runs_done[reported] == runs:
                if progress is not None:
                    progress(chunks[reported][1] - chunks[reported][0])
                reported += 1
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


TAPER_EPISODES = 8
"""The fewest episodes of a piece :func:`tapered` cuts the last chunk into."""


def tapered(chunks: list[tuple[int, int]]) -> list[tuple[int, int]]:
    """``chunks`` with the last cut in halves, each half the one before, down to :data:`TAPER_EPISODES` episodes:
    at the end of the last chunk a thread waits for the blocks still running, and smaller pieces make the wait
    shorter (250 episodes: 125, 63, 31, 16, 15)."""
    if not chunks:
        return chunks
    *head, (first, stop) = chunks
    while stop - first >= 2 * TAPER_EPISODES:
        middle = first + (stop - first + 1) // 2
        head.append((first, middle))
        first = middle
    return [*head, (first, stop)]


def run_blocks(runs: int, threads: int) -> list[tuple[int, int]]:
    """``[first, stop)`` of ``min(runs, threads * BLOCKS_PER_THREAD)`` blocks covering ``[0, runs)``, whose sizes
    differ by one run at most, the larger first: the threads take them in turn, so the last handed out are the
    shortest, and the threads end together (30 runs on 2 threads in 15 blocks of 2 left one thread idle for a
    block at the end of every chunk: 1.89x one thread where these make 1.98x)."""
    count = max(1, min(runs, threads * BLOCKS_PER_THREAD))
    size, larger = divmod(runs, count)
    stops = np.cumsum([size + (block < larger) for block in range(count)])
    return [(int(stop - size - (block < larger)), int(stop)) for block, stop in enumerate(stops)]


def over_runs(train: Callable[[int, int], None], runs: int) -> None:
    """Call ``train(first, stop)`` for blocks of runs covering ``[0, runs)`` (:func:`run_blocks`) on
    ``numba.get_num_threads()`` threads; each run writes only its own slices, so the order does not matter."""
    threads = min(numba.get_num_threads(), runs)
    blocks = run_blocks(runs, threads)
    if threads <= 1:
        for first, stop in blocks:
            train(first, stop)
        return
    with ThreadPoolExecutor(threads) as pool:
        for future in [pool.submit(train, first, stop) for first, stop in blocks]:
            future.result()
