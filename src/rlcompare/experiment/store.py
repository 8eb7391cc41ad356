"""Atomic writes and the layout of a run directory.

A run directory holds everything needed to rebuild every table and figure without training again:

| file                | what                                                                       |
|---------------------|----------------------------------------------------------------------------|
| ``config.json``     | the resolved :class:`ExperimentConfig`                                     |
| ``episodes.parquet``| one row per seed x episode: ε, behaviour return, length, terminated        |
| ``evaluations.parquet`` | one row per seed x evaluation round x episode of the greedy policy      |
| ``qtables.npz``     | Q-tables at the named stages and their episodes, state-visit counts, seeds, ε per episode |
| ``meta.json``       | versions, seeds, timings, command line; written last, so it marks the run complete |

Every file is written to a temporary name in the same directory and renamed into place, so a reader never
sees half a file and an interrupted run leaves nothing that looks finished.
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import IO, Any

CONFIG_FILE = "config.json"
EPISODES_FILE = "episodes.parquet"
EVALUATIONS_FILE = "evaluations.parquet"
QTABLES_FILE = "qtables.npz"
META_FILE = "meta.json"
RUN_FILES = (CONFIG_FILE, EPISODES_FILE, EVALUATIONS_FILE, QTABLES_FILE, META_FILE)


def _default_file_mode() -> int:
    umask = os.umask(0)
    os.umask(umask)
    return 0o666 & ~umask


_FILE_MODE = _default_file_mode()


class StoreError(OSError):
    """A run directory that cannot be written or read; names the path and what is wrong."""


@contextlib.contextmanager
def _atomic_file(path: Path, mode: str) -> Iterator[IO[Any]]:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        os.chmod(tmp, _FILE_MODE)
        with os.fdopen(fd, mode) as handle:
            yield handle
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def write_atomic(path: Path, write: Callable[[IO[bytes]], None]) -> None:
    """Call ``write`` on a binary handle to a temporary file, then rename it to ``path``."""
    with _atomic_file(Path(path), "wb") as handle:
        write(handle)


def write_json_atomic(path: Path, data: Any) -> None:
    with _atomic_file(Path(path), "w") as handle:
        json.dump(data, handle, indent=2, sort_keys=True)
        handle.write("\n")


def read_json(path: Path) -> Any:
    try:
        return json.loads(Path(path).read_text())
    except (OSError, json.JSONDecodeError) as error:
        raise StoreError(f"{path}: cannot read ({error})") from None


def is_complete(run_dir: Path) -> bool:
    """Whether every file of a finished run is present (``meta.json`` is written last)."""
    return all((Path(run_dir) / name).is_file() for name in RUN_FILES)


def prepare_directory(path: Path) -> Path:
    """Create ``path`` as a directory, or say why it cannot be one."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise StoreError(f"{path} is a file; an output directory is needed")
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise StoreError(f"{path}: cannot create the directory ({error.strerror})") from None
    if not os.access(path, os.W_OK):
        raise StoreError(f"{path}: the directory is not writable")
    return path
