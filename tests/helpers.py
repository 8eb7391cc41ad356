"""What many tests share: the command line, in this process or in a process of its own, a small study of the paper,
and the digests of a directory's files (to show that nothing changed)."""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

from click.testing import Result
from typer.testing import CliRunner


def invoke(*args: str, columns: int | None = 200, **options: Any) -> Result:
    """``rlcompare ARGS`` in this process (typer's runner), the console ``columns`` wide (None: rich's width for a
    log, 120)."""
    from rlcompare import cli

    env = {} if columns is None else {"COLUMNS": str(columns)}
    return CliRunner(env=env).invoke(cli.app, list(args), prog_name="rlcompare", **options)


def command_line(*args: str, columns: int = 200, python: tuple[str, ...] = (), **options: Any
                 ) -> subprocess.CompletedProcess[str]:
    """``rlcompare ARGS`` as a user runs it, in a process of its own (``python``: options of the interpreter)."""
    environment = {**os.environ, "COLUMNS": str(columns), **options.pop("env", {})}
    return subprocess.run([sys.executable, *python, "-m", "rlcompare.cli", *args], capture_output=True, text=True,
                          env=environment, check=False, **options)


def digests(directory: Path) -> dict[str, str]:
    """Every file under ``directory`` and its SHA-256, by its path relative to ``directory``."""
    return {str(path.relative_to(directory)): hashlib.sha256(path.read_bytes()).hexdigest()
            for path in sorted(Path(directory).rglob("*")) if path.is_file()}


def paper_study(path: Path, seeds: int, episodes: int, **settings: Any) -> Path:
    """The paper's configurations on ``seeds`` seeds trained into the study directory ``path``."""
    from rlcompare.studies.paper import paper_configs, reproduce

    list(reproduce(path, paper_configs(tuple(range(seeds)), episodes, **settings)))
    return path
