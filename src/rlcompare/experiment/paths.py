"""The paths a marker lists: plain relative paths that stay inside their directory, matched level by level."""

from __future__ import annotations

import fnmatch
from pathlib import Path


class StoreError(OSError):
    """A directory or file that cannot be written or read as asked; names the path and what is wrong."""


def is_inner_path(relative: object) -> bool:
    """Whether ``relative`` is what rlcompare lists in a marker: a relative POSIX path with no ``..``, ``.`` or
    empty component, and no backslash or NUL (so it cannot name anything outside its directory by its text)."""
    if not isinstance(relative, str) or not relative or "\\" in relative or "\0" in relative:
        return False
    return not relative.startswith("/") and all(part not in ("", ".", "..") for part in relative.split("/"))


def inside(directory: Path, relative: str) -> Path:
    """``directory / relative``, refused where a symlink on the way leads out of ``directory``."""
    path = Path(directory) / relative
    if not path.parent.resolve().is_relative_to(Path(directory).resolve()):
        raise StoreError(f"{path}: leads out of {directory} through a symlink; rlcompare neither writes nor removes "
                         "files there")
    return path


def matches(relative: str, pattern: str) -> bool:
    """Whether a listed path matches a pattern (``figures/*.png``) level by level: ``*`` stays within one
    directory, unlike :func:`fnmatch.fnmatchcase`, where it also matches ``/``."""
    parts, wanted = relative.split("/"), pattern.split("/")
    return len(parts) == len(wanted) and all(fnmatch.fnmatchcase(a, b) for a, b in zip(parts, wanted, strict=True))
