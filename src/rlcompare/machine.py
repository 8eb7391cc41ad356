"""What rlcompare reads of the machine it runs on: its memory, and the versions a result depends on."""

from __future__ import annotations

import functools
import os
import platform
from importlib import metadata
from pathlib import Path

FALLBACK_MEMORY = 16 * 2**30
"""Physical memory assumed where the machine does not say."""
RESULT_PACKAGES = ("rlcompare", "numpy", "numba", "gymnasium", "pandas")
"""The packages every run's results depend on; an engine adds its own (:func:`versions`)."""


def physical_memory() -> int:
    """This machine's physical memory in bytes; :data:`FALLBACK_MEMORY` where it does not say."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, ValueError, OSError):
        return FALLBACK_MEMORY


def cache_root() -> Path:
    """rlcompare's directory for what it keeps between runs on this machine (compiled code, the pace of its
    trainings): ``$XDG_CACHE_HOME/rlcompare``, else ``~/.cache/rlcompare``."""
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "rlcompare"


def gib(size: int) -> str:
    """A size in GiB as a message says it: ``1.5 GiB``, ``24 GiB``."""
    return f"{size / 2**30:,.1f} GiB" if size < 10 * 2**30 else f"{size / 2**30:,.0f} GiB"


@functools.cache
def versions(*extra: str) -> dict[str, str | None]:
    """Python, the platform and the packages a result depends on, :data:`RESULT_PACKAGES` and ``extra`` (read once
    a process: reading them costs milliseconds)."""
    return {"python": platform.python_version(), "platform": platform.platform(),
            **{package: package_version(package) for package in (*RESULT_PACKAGES, *extra)}}


def package_version(package: str) -> str | None:
    """The installed version of ``package``; None where it is not installed."""
    try:
        return metadata.version(package)
    except metadata.PackageNotFoundError:
        return None
