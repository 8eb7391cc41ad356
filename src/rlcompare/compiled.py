"""Numba's ``njit``, with its cache in rlcompare's own directory: every compiled kernel of rlcompare is made by the
``njit`` of this module, so the cache directory is set before the first kernel is defined.

Numba caches compiled kernels in one directory per version of rlcompare's source.

Numba keys a cached function by its own file's timestamp only. A kernel inlines code from other modules
(the ports, the tables, the random streams), so after one of those changes alone numba would load the old
machine code and give old results. Keying the directory by a hash of the sources of compiled code (the
packages ``algorithms``, ``engine``, ``envs`` and ``rng.py``) makes any change to them compile afresh, and
leaves the cache alone when only the command line or the analysis changes. ``NUMBA_CACHE_DIR``, when set, wins.

Importing this module points numba at this version's directory (numba reads it when a cached kernel is defined);
nothing on disk changes then. Where a run starts (:func:`tend`), the directory is made and touched, and directories
of other versions unused for :data:`KEEP_UNUSED_DAYS` days are deleted.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar, overload

import numba

from rlcompare import machine

if TYPE_CHECKING:
    from numba.core.typing.templates import Signature

__all__ = ["cache_is_writable", "holds_nothing_yet", "njit", "tend"]

Function = TypeVar("Function", bound=Callable[..., Any])
Codegen = Callable[[Any, Any, "Signature", tuple[Any, ...]], Any]
"""``codegen(context, builder, signature, arguments)``: the LLVM code of a numba intrinsic (llvmlite has no
types)."""

COMPILED_SOURCES = ("algorithms", "envs", "rng.py", "tabular/state.py", "tabular/steps.py", "tabular/episodes.py",
                    "tabular/loops.py", "tabular/runs.py", "tabular/borrowed.py", "tabular/games.py")
"""The packages and modules compiled code is made of: the kernels inline the rules, the ports, the tables, the
random streams and the tabular engine's loops."""
KEEP_UNUSED_DAYS = 30


def source_digest(package: Path) -> str:
    """A short hash of the Python files that compiled code comes from, by relative path and content."""
    digest = hashlib.sha256()
    files = (path for name in COMPILED_SOURCES for path in [package / name, *(package / name).rglob("*.py")]
             if path.is_file())
    for path in sorted(p for p in files if p.suffix == ".py"):
        digest.update(str(path.relative_to(package)).encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def numba_settings() -> dict[str, Any]:
    """Numba's settings (``CACHE_DIR``, ...): globals its config module makes from the environment at import,
    which the type checker does not see."""
    return vars(numba.config)


def use_source_keyed_cache() -> None:
    """Point numba's cache at this version's directory (no file is touched)."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return
    numba_settings()["CACHE_DIR"] = str(machine.cache_root() / f"numba-{source_digest(Path(__file__).parent)}")


@overload
def njit(function: Function, /) -> Function: ...


@overload
def njit(*, cache: bool = ..., nogil: bool = ..., inline: str = ..., forceinline: bool = ...
         ) -> Callable[[Function], Function]: ...


def njit(function: Any = None, /, **options: Any) -> Any:
    """``numba.njit``, as ``@njit`` or ``@njit(cache=True, ...)``; to the type checker, the compiled function keeps
    the Python function's signature."""
    return numba.njit(**options) if function is None else numba.njit(function)


def tend() -> None:
    """Where a run starts: make and touch this version's cache directory, and delete other versions' unused for
    :data:`KEEP_UNUSED_DAYS` days (nothing where ``NUMBA_CACHE_DIR`` chose the directory)."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return
    current = Path(numba_settings()["CACHE_DIR"])
    try:
        current.mkdir(parents=True, exist_ok=True)
        os.utime(current)
        prune_unused(current.parent, keep=current)
    except OSError:  # a read-only home: numba falls back to its own cache locations
        pass


def holds_nothing_yet() -> bool:
    """Whether this version's cache holds no compiled kernel yet: the next run compiles them."""
    cache_dir = numba_settings()["CACHE_DIR"]
    return bool(cache_dir) and not any(Path(cache_dir).rglob("*.nbi"))


def cache_is_writable() -> bool:
    """Whether numba can keep what it compiles: this version's cache directory can be made and written (tried, as
    permissions alone do not say it for every user or file system)."""
    try:
        cache_dir = Path(numba_settings()["CACHE_DIR"])
        cache_dir.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=cache_dir):
            return True
    except OSError:
        return False


def prune_unused(root: Path, keep: Path, days: float = KEEP_UNUSED_DAYS) -> None:
    """Delete the cache directories of other source versions that no process has used for ``days`` days."""
    cutoff = time.time() - days * 86400
    for stale in root.glob("numba-*"):
        if stale != keep and stale.is_dir() and stale.stat().st_mtime < cutoff:
            shutil.rmtree(stale, ignore_errors=True)


use_source_keyed_cache()
