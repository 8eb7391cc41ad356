"""Where numba caches the compiled kernels: one directory per version of rlcompare's source.

Numba keys a cached function by its own file's timestamp only. A kernel inlines code from other modules
(the ports, the tables, the random streams), so after one of those changes alone numba would load the old
machine code and give old results. Keying the directory by a hash of the sources of compiled code (the
packages ``algorithms``, ``engine``, ``envs`` and ``rng.py``) makes any change to them compile afresh, and
leaves the cache alone when only the command line or the analysis changes. ``NUMBA_CACHE_DIR``, when set,
wins.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

COMPILED_SOURCES = ("algorithms", "engine", "envs", "rng.py")


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
    numba.config.CACHE_DIR = str(root / f"numba-{source_digest(Path(__file__).parent)}")


use_source_keyed_cache()
