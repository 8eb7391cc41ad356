"""Where numba caches the compiled kernels: one directory per version of rlcompare's source.

Numba keys a cached function by its own file's timestamp only. A kernel inlines code from other modules
(the ports, the tables, the random streams), so after one of those changes alone numba would load the old
machine code and give old results. Keying the directory by a hash of the sources of compiled code (the
packages ``algorithms``, ``engine``, ``envs`` and ``rng.py``) makes any change to them compile afresh, and
leaves the cache alone when only the command line or the analysis changes. Each use touches its directory;
directories of other versions unused for :data:`KEEP_UNUSED_DAYS` days are deleted. ``NUMBA_CACHE_DIR``, when
set, wins.
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


def use_source_keyed_cache() -> None:
    if os.environ.get("NUMBA_CACHE_DIR"):
        return
    import numba

    root = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "rlcompare"
    current = root / f"numba-{source_digest(Path(__file__).parent)}"
    numba.config.CACHE_DIR = str(current)
    try:
        current.mkdir(parents=True, exist_ok=True)
        os.utime(current)
        prune_unused(root, keep=current)
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
