"""The ``rlcompare`` command line: parse, call one library function, print.

``rlcompare``, ``rlcompare --help`` and ``rlcompare --version`` are answered by :mod:`rlcompare.cli.app_help`, which
imports nothing heavier than typer, so they start at once; ``rlcompare uci ...`` builds that command alone
(:mod:`rlcompare.cli.uci`), so that a chess program's ``uci`` is answered at once; anything else builds the whole app
(:mod:`rlcompare.cli.commands`), whose commands take their options from the configuration classes.
"""

from __future__ import annotations

import sys
from typing import Any

__all__ = ["ALGORITHM_HELP", "app", "main"]

_SUMMARY_ONLY: tuple[list[str], ...] = ([], ["--help"], ["--version"])
"""Command lines the summary app answers alone."""


def main() -> None:
    if sys.argv[1:] in _SUMMARY_ONLY:
        from rlcompare.cli.app_help import summary_app

        summary_app()()
    elif sys.argv[1:2] == ["uci"]:  # answered at once: a chess program sends uci as it starts the engine
        from rlcompare.cli.uci import uci_app
        from rlcompare.experiment.interrupts import raise_on_sigterm

        raise_on_sigterm()
        uci_app()()
    else:
        from rlcompare.cli.commands import app
        from rlcompare.experiment.interrupts import raise_on_sigterm

        raise_on_sigterm()
        app()


def __getattr__(name: str) -> Any:
    """``app`` and ``ALGORITHM_HELP``, imported when first asked for (they build every command's options)."""
    if name in ("app", "ALGORITHM_HELP"):
        from rlcompare.cli import commands

        return getattr(commands, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
