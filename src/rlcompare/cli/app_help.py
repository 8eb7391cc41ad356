"""What ``rlcompare --help`` and ``rlcompare --version`` need, and nothing heavier than typer: the app's words, each
command's one-line summary, the version option, and help that names no Python types.

``rlcompare`` alone, ``--help`` and ``--version`` are answered from here (:func:`rlcompare.cli.main`) without
importing the commands; every other command line builds the whole app (:mod:`rlcompare.cli.commands`), whose
top-level help is the same text (tested).
"""

from __future__ import annotations

from importlib import metadata
from pathlib import Path
from typing import Annotated, Any, get_args, get_origin

import typer
from typer.core import TyperArgument, TyperCommand, TyperGroup, TyperOption

APP_HELP = "Run, measure and explain comparisons of reinforcement-learning algorithms."
SUMMARIES = {
    "run": "Train one configuration over many seeds and write its run directory.",
    "sweep": "Run every configuration of a sweep over its seeds; finished trials in OUT are kept, the rest run.",
    "report": "Rebuild the tables, verdicts, figures, videos and report.html of a study or a sweep, without "
              "training; or show a single run's results.",
    "compare": "Verdicts and a report for runs other libraries made: Stable-Baselines3's Monitor files, RL Zoo's "
               "evaluations, TensorBoard files, tidy tables.",
    "export": "Write a run's training episodes where other tools read them: a tidy CSV, or TensorBoard files.",
    "uci": "Serve a network trained at chess as a UCI engine on standard input and output, for any chess program.",
    "bench": "Steps per second of the kernels on 1 and all threads against a plain Gymnasium loop.",
    "reproduce": "Reproduce a study (the paper's by default): train what its directory lacks, then build its report.",
}
"""Each command's line in ``rlcompare --help``, in its order."""
APP_SETTINGS: dict[str, Any] = {"no_args_is_help": True, "pretty_exceptions_enable": False,
                                "rich_markup_mode": "rich"}

_WORDS: dict[object, str] = {int: "INTEGER", float: "NUMBER", str: "TEXT", Path: "PATH"}
"""What the help shows after an option that takes a value, by its type: a word, not ``<int>``."""


def version() -> str:
    """rlcompare's version, as installed (its package metadata)."""
    try:
        return metadata.version("rlcompare")
    except metadata.PackageNotFoundError:  # run from a source tree that was never installed
        return "unknown (not installed)"


def _print_version(value: bool) -> None:
    if value:
        typer.echo(f"rlcompare {version()}")
        raise typer.Exit()


def root(
    show_version: Annotated[bool, typer.Option("--version", callback=_print_version, is_eager=True,
                                               help="Print rlcompare's version and exit.")] = False,
) -> None:
    """The options before a command's name."""


class _PlainOption(TyperOption):
    def display_type_rich(self, ctx: Any) -> str | None:
        if self.metavar is not None:
            return self.metavar
        if self.is_flag:
            return None
        kind: object = self.type_descriptor.annotation
        kind = (get_args(kind) or (kind,))[0] if get_origin(kind) is list else kind  # repeated: the option says so
        return _WORDS.get(kind, "VALUE")


class _PlainArgument(TyperArgument):
    def display_type_rich(self, ctx: Any) -> str | None:
        return None  # its name says what it is (SWEEP_FILE, STUDY_DIR)

    def get_usage_pieces(self, ctx: Any) -> list[str]:
        """``STUDY_DIR`` (``[NAME]`` where it may be left out), not typer's ``{STUDY_DIR}``."""
        name = self.display_name_raw if self.required else f"[{self.display_name_raw}]"
        return [name + ("..." if self.nargs != 1 else "")]


def _plain(params: list[Any]) -> list[Any]:
    """The parameters, shown in the help without typer's ``<str>``, ``<int>``, ``<bool>``: nothing after a flag, a
    word after an option that takes a value (INTEGER, NUMBER, TEXT, PATH)."""
    for param in params:
        if type(param) is TyperOption:
            param.__class__ = _PlainOption
        elif type(param) is TyperArgument:
            param.__class__ = _PlainArgument
    return params


class PlainCommand(TyperCommand):
    """A command whose help names no Python types."""

    def get_params(self, ctx: Any) -> list[Any]:
        return _plain(super().get_params(ctx))


class PlainGroup(TyperGroup):
    """A group whose help names no Python types."""

    def get_params(self, ctx: Any) -> list[Any]:
        return _plain(super().get_params(ctx))


def new_app() -> typer.Typer:
    """The ``rlcompare`` app without its commands: its help, its settings and ``--version``."""
    app = typer.Typer(help=APP_HELP, cls=PlainGroup, **APP_SETTINGS)
    app.callback()(root)
    return app


def summary_app() -> typer.Typer:
    """``rlcompare`` with each command's name and summary only: what ``rlcompare --help`` shows, built without the
    commands' options."""
    app = new_app()
    for name, summary in SUMMARIES.items():
        app.command(name, help=summary, short_help=summary, cls=PlainCommand)(lambda: None)
    return app
