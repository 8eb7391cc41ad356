"""Signals while rlcompare works. A compiled training cannot be stopped halfway, so the first Ctrl-C starts nothing
new, says which trainings it is finishing and waits for them (each is then kept, as a finished run); a second
abandons them at once, ending the process with exit code 130. SIGTERM (a scheduler's, ``kill``'s) is an exception
in the main thread, so that what holds worker processes ends them before the directory's lock is released, and
abandons the trainings in flight (exit code 143). What was finished stays on disk, and the same command resumes
from it."""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
from collections.abc import Callable, Iterator, Mapping
from concurrent.futures import Future, wait
from types import FrameType
from typing import Any

EXIT_INTERRUPTED = 130
"""The exit code of a process ended by SIGINT, as a shell reports it (128 + 2)."""
EXIT_TERMINATED = 143
"""The exit code of a process ended by SIGTERM (128 + 15)."""


class Terminated(SystemExit):
    """SIGTERM, raised in the main thread by :func:`raise_on_sigterm`'s handler."""


def raise_on_sigterm() -> None:
    """From now on SIGTERM raises :class:`Terminated` (exit code 143) in the main thread, so that context managers
    end their worker processes; called by the command line, from its main thread."""
    def terminated(signum: int, frame: FrameType | None) -> None:
        say("Terminated (SIGTERM): what was finished is kept")
        raise Terminated(EXIT_TERMINATED)

    signal.signal(signal.SIGTERM, terminated)


@contextlib.contextmanager
def trainings(in_flight: Callable[[], Mapping[Future[Any], str]]) -> Iterator[None]:
    """Trainings submitted to a pool in this block (``in_flight()``: each future -> its name). On Ctrl-C here, or
    a caller that stops between two results (``GeneratorExit``), nothing new starts and those running are
    finished and kept (:func:`finish_in_flight`); on SIGTERM they are abandoned (:func:`abandon`); on any other
    error nothing new starts."""
    try:
        yield
    except (KeyboardInterrupt, GeneratorExit) as stop:
        submitted = in_flight()
        for future in submitted:
            future.cancel()
        finish_in_flight({future: name for future, name in submitted.items() if future.running()},
                         "Ctrl-C" if isinstance(stop, KeyboardInterrupt) else "Stopping")
        raise
    except Terminated:
        abandon(signal.SIGTERM)
    except BaseException:
        for future in in_flight():
            future.cancel()
        raise


def finish_in_flight(running: dict[Future[Any], str], cause: str = "Ctrl-C") -> None:
    """After a first Ctrl-C (or another ``cause`` of stopping): wait for the trainings ``running`` (future ->
    name), saying so; a Ctrl-C now ends the process at once (:func:`abandon`)."""
    if not running:
        return
    again = " again" if cause == "Ctrl-C" else ""
    say(f"{cause}: finishing the trainings in flight ({', '.join(sorted(running.values()))}) to keep them, since a "
        f"compiled training cannot stop halfway; Ctrl-C{again} abandons them")
    if threading.current_thread() is not threading.main_thread():
        wait(running)
        return
    previous = signal.signal(signal.SIGINT, abandon)
    try:
        wait(running)
    finally:
        signal.signal(signal.SIGINT, previous)


def abandon(signum: int = signal.SIGINT, frame: FrameType | None = None) -> None:
    """End the process now, with the trainings in flight: ``os._exit``, because a thread inside XLA cannot be
    unwound (Python's exit would wait for it, and an exception through it aborts the process). The directory's
    lock is the kernel's and goes with the process; the temporary files left are cleared by the next run."""
    what = "Ctrl-C again" if signum == signal.SIGINT else "Terminated"
    say(f"{what}: the trainings in flight are abandoned; the finished runs are kept, and the same command resumes "
        "from them")
    os._exit(EXIT_INTERRUPTED if signum == signal.SIGINT else EXIT_TERMINATED)


def say(line: str) -> None:
    print(line, file=sys.stderr, flush=True)
