"""Where numba caches the compiled kernels: one directory per version of rlcompare's source.

Numba keys a cached function by its own file's timestamp only. A kernel inlines code from other modules
(the ports, the tables, the random streams), so after one of those changes alone numba would load the old
machine code and give old results. Keying the directory by a hash of the sources of compiled code (the
packages ``algorithms``, ``engine``, ``envs`` and ``rng.py``) makes any change to them compile afresh, and
leaves the cache alone when only the command line or the analysis changes. ``NUMBA_CACHE_DIR``, when set, wins.

Importing rlcompare only points numba at this version's directory (numba reads it when it first compiles, so it
must be set before any kernel module is imported); nothing on disk changes then. Where a run starts
(:func:`tend`), the directory is made and touched, and directories of other versions unused for
:data:`KEEP_UNUSED_DAYS` days are deleted.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import time
from pathlib import Path

COMPILED_SOURCES = ("algorithms", "engine", "envs", "rng.py")
KEEP_UNUSED_DAYS = 30


def source_digest(package: Path) -> str:
    """A short hash of the Python files that compiled code comes from, by relative path and content."""
    digest = hashlib.sha256()
    files = (path for name in COMPILED_SOURCES for path in [package / name, *(package / name).rglob("*.py")])
    for path in sorted(p for p in files if p.suffix == ".py"):
        digest.update(str(path.relative_to(package)).encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def _root() -> Path:
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "rlcompare"


def use_source_keyed_cache() -> None:
    """Point numba's cache at this version's directory (no file is touched)."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return
    import numba

    numba.config.CACHE_DIR = str(_root() / f"numba-{source_digest(Path(__file__).parent)}")


def tend() -> None:
    """Where a run starts: make and touch this version's cache directory, and delete other versions' unused for
    :data:`KEEP_UNUSED_DAYS` days (nothing where ``NUMBA_CACHE_DIR`` chose the directory)."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return
    import numba

    current = Path(numba.config.CACHE_DIR)
    try:
        current.mkdir(parents=True, exist_ok=True)
        os.utime(current)
        prune_unused(current.parent, keep=current)
    except OSError:  # a read-only home: numba falls back to its own cache locations
        pass


def holds_nothing_yet() -> bool:
    """Whether this version's cache holds no compiled kernel yet: the next run compiles them."""
    import numba

    directory = Path(numba.config.CACHE_DIR or "")
    return bool(numba.config.CACHE_DIR) and not any(directory.rglob("*.nbi"))


def prune_unused(root: Path, keep: Path, days: float = KEEP_UNUSED_DAYS) -> None:
    """Delete the cache directories of other source versions that no process has used for ``days`` days."""
    cutoff = time.time() - days * 86400
    for stale in root.glob("numba-*"):
        if stale != keep and stale.is_dir() and stale.stat().st_mtime < cutoff:
            shutil.rmtree(stale, ignore_errors=True)


use_source_keyed_cache()
