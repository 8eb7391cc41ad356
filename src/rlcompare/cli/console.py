"""What the command line shows: progress bars, tables, one-line errors, and the study interface's UI on a console."""

from __future__ import annotations

import contextlib
import functools
import inspect
import os
import sys
import textwrap
import traceback
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn, ParamSpec, TypeVar

import typer
from rich import box
from rich.console import Console, ConsoleDimensions
from rich.measure import Measurement
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn
from rich.table import Table
from rich.text import Text

from rlcompare.experiment import store
from rlcompare.experiment.store import StoreError
from rlcompare.formatting import cut, quote
from rlcompare.studies.interface import UI, Advance, Report
from rlcompare.validation import ConfigError

if TYPE_CHECKING:
    import pandas as pd

    from rlcompare.bench.tables import BenchTable

P = ParamSpec("P")
R = TypeVar("R")
C = TypeVar("C", bound=Callable[..., Any])


class _Console(Console):
    """rich's console, its width read at each print: a width given to it, else COLUMNS where it is set, else a
    terminal's own width, else (a log, a pipe) 120 columns. rich reads COLUMNS once, when the console is made,
    before a test or a caller has set it."""

    def __init__(self) -> None:
        super().__init__()
        self._width = None

    @property
    def size(self) -> ConsoleDimensions:
        measured = super().size
        columns = os.environ.get("COLUMNS", "")
        if self._width is not None or (self.is_terminal and not columns.isdigit()):
            return measured
        return ConsoleDimensions(int(columns) if columns.isdigit() else 120, measured.height)

    @size.setter
    def size(self, new_size: tuple[int, int]) -> None:
        self.width, self.height = new_size


console = _Console()
"""Everything but errors."""


def print_error(message: str, details: tuple[str, ...] = ()) -> None:
    """``Error: message`` on standard error, unwrapped and never read as markup, and a line per detail."""
    errors = Console(stderr=True, soft_wrap=True, highlight=False)
    errors.print(Text("Error: ", style="red") + Text(cut(message, 2000)))
    for detail in details:
        errors.print(Text(f"  {cut(detail, 2000)}"))


def fail(message: str) -> NoReturn:
    """One line, exit code 2."""
    print_error(message)
    raise typer.Exit(2)


def _standard_output_fails(error: OSError) -> bool:
    """Whether ``error`` is standard output's (a full disk, a closed pipe): raised where rich writes the console's
    buffer. If so, standard output is replaced by the null device, so that nothing more is tried there, Python's
    own flush at exit included."""
    frames = traceback.extract_tb(error.__traceback__)
    if not (frames and frames[-1].name == "_write_buffer" and console.file is sys.stdout):
        return False
    sys.stdout = console.file = open(os.devnull, "w")  # noqa: SIM115 -- kept open for the rest of the process
    return True


def one_line_errors(command: Callable[P, R]) -> Callable[P, R]:
    """A command whose errors of the store or of the operating system (a full disk, a read-only directory), of a
    backend that cannot run, or of a value a run refuses, end it with one clear line and exit code 2; what was
    finished before them stays on disk."""
    from rlcompare.experiment.backends import BackendError
    from rlcompare.experiment.interrupts import EXIT_INTERRUPTED, say

    @functools.wraps(command)
    def wrapped(*args: P.args, **kwargs: P.kwargs) -> R:
        try:
            return command(*args, **kwargs)
        except BackendError as error:
            fail(str(error))
        except ConfigError as error:  # a value only a run can refuse: records larger than this machine's memory
            raise bad_option(error) from None
        except OSError as error:  # StoreError included
            if not isinstance(error, StoreError) and error.filename is None and _standard_output_fails(error):
                fail(f"standard output: cannot write ({error.strerror or error}); what the command wrote to files "
                     "before it stays, and the same command resumes from it")
            message = str(error) if isinstance(error, StoreError) or not error.strerror else (
                f"{error.filename}: {error.strerror}" if error.filename else error.strerror)
            fail(message)
        except KeyboardInterrupt:
            say("Interrupted: the finished runs are kept, and the same command resumes from them")
            raise SystemExit(EXIT_INTERRUPTED) from None

    return wrapped


def with_signature(command: C, signature: inspect.Signature) -> C:
    """``command`` with ``signature``, what typer reads of its options, in place of its own: ``inspect.signature``
    reads a function's ``__signature__``."""
    vars(command)["__signature__"] = signature
    return command


def option_flag(field_name: str) -> str:
    """The option that gives a field: ``--hash-size`` for ``hash_size``, ``--stage`` for ``stages``."""
    return "--stage" if field_name == "stages" else "--" + field_name.replace("_", "-")


def bad_option(error: ConfigError) -> typer.BadParameter:
    """A refused value as a usage error that names its option (exit code 2)."""
    return typer.BadParameter(f"got {quote(error.value)}; allowed: {error.allowed}",
                              param_hint=f"'{option_flag(error.field_name)}'")


def out_path(text: str | None, default: Path) -> Path:
    """The ``--out`` directory: the default where none is given; never the empty path."""
    if text is None:
        return default
    try:
        return store.check_path(text)
    except StoreError as error:
        raise typer.BadParameter(str(error).removeprefix("--out: "), param_hint="'--out'") from None


def check_out(out: Path, owner: store.Owner, force: bool) -> None:
    """Refuse an output directory before any training, so a bad path costs nothing computed."""
    problem = store.refusal(out, owner, force=force)
    if problem:
        raise typer.BadParameter(problem, param_hint="'--out'")


def progress_bars(eta: bool = False) -> Progress:
    """A progress bar on a terminal; nothing but the per-configuration lines in a log."""
    columns = [TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn()]
    if eta:
        columns += [TextColumn("ETA"), TimeRemainingColumn()]
    return Progress(*columns, console=console, disable=not console.is_terminal)


def announce_compiling() -> None:
    """Say so before a run that will compile the kernels, which takes a while on a fresh machine."""
    from rlcompare.compiled import cache_is_writable, holds_nothing_yet, numba_settings

    if not cache_is_writable():
        console.print(f"Compiling: numba's cache directory {numba_settings()['CACHE_DIR']} is not writable, so each "
                      "run compiles its training loops again (seconds each); set NUMBA_CACHE_DIR, or XDG_CACHE_HOME, "
                      "to a writable directory to keep them.")
    elif holds_nothing_yet():
        console.print("Compiling: the first run of each method on each environment and features compiles its "
                      "training loop, once on this machine (seconds each: each configuration's line below says how "
                      "long); later runs load it.")


def plural(n: int, noun: str) -> str:
    """``1 seed``, ``30 seeds``, ``5,000 episodes``."""
    return f"{n:,} {noun}" + ("" if n == 1 else "s")


def done_line(name: str, results: Any, reused: bool) -> str:
    """What a finished configuration took: its seeds (and episodes), and its time or that it was loaded."""
    episodes = getattr(results.config, "episodes", None)
    size = plural(len(results.seeds), "seed") + (f" x {plural(episodes, 'episode')}" if episodes else "")
    if reused:
        return f"{name:<24} {size}: loaded (already complete)"
    timings = results.meta.get("timings", {})
    compiled = timings.get("compile_seconds", 0)
    note = f" (and {compiled:.0f} s compiling or loading its loop)" if compiled >= 1 else ""
    return f"{name:<24} {size}: {timings.get('wall_seconds', 0):.1f} s{note}"


def rounded_steps_line(name: str, results: Any) -> str | None:
    """Where a deep training ran other than the environment steps it was given (each method trains whole batches
    of steps in each evaluation round): the number given and the number trained, in one line; else None."""
    given = (getattr(results.config, "hyperparameters", None) or {}).get("total_steps")
    trained = results.meta.get("timings", {}).get("training_steps")
    if not isinstance(given, int) or not isinstance(trained, int) or given == trained:
        return None
    return f"{name}: {trained:,} steps per seed, not the {given:,} given (whole batches per evaluation round)"


def fitting_table(title: str, columns: Any, rows: list[tuple[str, ...]], caption: str = "") -> Table:
    """A table that fits the console, with light rules; the first column (the rows' names) left, the others right.
    Where its rows do not fit on one line each, a number's interval goes under it and a header wraps to its
    column's widest cell; then cells wrap at spaces (and fold a word longer than its column) instead of being
    cut."""
    table = _table(title, columns, rows, caption)
    if Measurement.get(console, console.options.update_width(10_000), table).maximum <= console.width:
        return table
    cells = [tuple(cell.replace(" [", "\n[") for cell in row) for row in rows]
    headers = []
    for index, column in enumerate(map(str, columns)):
        widest = max((len(line) for row in cells for line in row[index].splitlines()), default=0)
        longest_word = max((len(word) for word in column.split()), default=0)
        headers.append("\n".join(textwrap.wrap(column, max(widest, longest_word))) or column)
    return _table(title, headers, cells, caption)


def _table(title: str, columns: Any, rows: list[tuple[str, ...]], caption: str) -> Table:
    table = Table(title=title, caption=caption or None, box=box.SIMPLE_HEAD, collapse_padding=True,
                  pad_edge=False, title_justify="left", caption_justify="left")
    for index, column in enumerate(columns):
        table.add_column(str(column), justify="right" if index else "left", overflow="fold")
    for row in rows:
        table.add_row(*row)
    return table


def print_frame(frame: pd.DataFrame, title: str, caption: str = "") -> None:
    rows = [tuple(str(value) for value in row) for row in frame.itertuples(index=False)]
    console.print(fitting_table(title, frame.columns, rows, caption))


def print_bench(table: BenchTable) -> None:
    """A benchmark's table: its label column left, its numbers right; then its notes."""
    console.print(fitting_table(table.title, table.columns, table.rows))
    for note in table.notes:
        console.print(Text(note, style="yellow"))


@contextlib.contextmanager
def measurement_lines(what: str) -> Iterator[Callable[[str], None]]:
    """``with measurement_lines(what) as say``: a line saying what is measured, a spinner while it runs, and
    ``say(text)`` prints each measurement as it is taken."""
    console.print(f"Measuring {what}:", highlight=False)
    with console.status(f"Measuring {what}") as status:
        done = 0

        def say(text: str) -> None:
            nonlocal done
            done += 1
            console.print(Text(f"  {text}"), highlight=False)
            status.update(f"Measuring {what}: {done} done, the next one running")

        yield say


def print_report(report: Report) -> None:
    """A report's sentences, what it could not build, and where it is; exit code 2 when something is missing or
    damaged (what the user's files hold, as for any input refused)."""
    for line in report.lines:
        console.print(Text(f"  {line}"), highlight=False)
    for problem in report.problems:
        console.print(Text("Warning: ", style="yellow") + Text(problem), highlight=False)
    timings = ", ".join(f"{part} {seconds:.1f} s" for part, seconds in report.seconds.items())
    console.print(f"Report: {report.path}" + (f"  ({timings})" if timings else ""))
    if report.problems:
        raise typer.Exit(2)


class ConsoleUI(UI):
    """The study interface's UI on the console: progress bars on a terminal, a line per configuration."""

    def __init__(self) -> None:
        self._progress: Progress | None = None

    @contextlib.contextmanager
    def tasks(self, totals: dict[str, int], *, eta: bool = False) -> Iterator[Advance]:
        with progress_bars(eta) as progress:
            ids = {name: progress.add_task(name, total=total) for name, total in totals.items()}
            self._progress = progress
            try:
                yield lambda task, n: progress.advance(ids[task], n)
            finally:
                self._progress = None

    def _console(self) -> Console:
        return self._progress.console if self._progress is not None else console

    def done(self, name: str, results: Any, reused: bool) -> None:
        self._console().print(done_line(name, results, reused), highlight=False)
        rounded = rounded_steps_line(name, results)
        if rounded:
            self._console().print(Text(rounded, style="yellow"), highlight=False)

    def say(self, text: str) -> None:
        self._console().print(Text(text), highlight=False)

    def table(self, frame: pd.DataFrame, title: str, caption: str = "") -> None:
        print_frame(frame, title, caption)

    @contextlib.contextmanager
    def working(self, text: str) -> Iterator[None]:
        with console.status(text):
            yield
