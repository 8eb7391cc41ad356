"""Figures and videos drawn again only when what they are drawn from changes.

A report's figures and videos are functions of the stored runs it reads, of its options, of rlcompare's code and
of the libraries that draw. A study directory keeps a ledger of the files its last report drew, ``.drawn.json``:
the key of what they were drawn from and the sha256 of each file's bytes as written. A report keeps a file
instead of drawing it again only when all three hold:

- the directory's marker lists it, so rlcompare wrote it (:mod:`rlcompare.experiment.store`);
- the ledger's key is this report's (:func:`report_key`): the same runs, by the checksums their ``meta.json``
  recorded and loading verified, the same options, the same source of rlcompare and versions of the libraries;
- the file's bytes still hash to what the ledger recorded: nobody edited, replaced or truncated it.

Anything else is drawn again and overwritten. The ledger is written after the files it lists, so a report stopped
half-way leaves a ledger that vouches only for files whose bytes are still those it recorded.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.metadata
import json
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from rlcompare.experiment import store

LEDGER = ".drawn.json"
LIBRARIES = ("numpy", "matplotlib", "pillow", "pandas", "scipy", "gymnasium", "pygame", "imageio-ffmpeg", "numba")
"""The libraries whose versions enter the key: those that compute, draw or encode what a report shows."""


@functools.lru_cache(maxsize=1)
def code_fingerprint() -> str:
    """sha256 of every Python file of the installed rlcompare (paths and bytes) and of the versions of
    :data:`LIBRARIES`: any change to the code or to a library that draws makes every file be drawn again."""
    digest = hashlib.sha256()
    package = Path(__file__).resolve().parent.parent
    for path in sorted(package.rglob("*.py")):
        digest.update(path.relative_to(package).as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
    for name in LIBRARIES:
        try:
            version = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            version = ""
        digest.update(f"{name}={version}\0".encode())
    return digest.hexdigest()


def report_key(runs: dict[str, Any], options: dict[str, Any]) -> str | None:
    """The key of a report drawn from ``runs`` (loaded, so their files were verified against the checksums their
    ``meta.json`` recorded) with ``options``; None where a run has no recorded checksums (nothing is then kept)."""
    files = {}
    for name, results in runs.items():
        contents = results.meta.get("contents") if isinstance(getattr(results, "meta", None), dict) else None
        recorded = contents.get("files") if isinstance(contents, dict) else None
        if not isinstance(recorded, dict) or not recorded:
            return None
        files[name] = recorded
    text = json.dumps({"code": code_fingerprint(), "runs": files, "options": options}, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def file_digest(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(2**20), b""):
            digest.update(block)
    return digest.hexdigest()


class Drawn:
    """The ledger of one study directory for one report: which files can be kept, and what was drawn."""

    def __init__(self, directory: Path, key: str | None) -> None:
        self.directory, self.key = Path(directory), key
        self.recorded: dict[str, str] = {}
        """The files this report keeps or drew, by path relative to the directory: their sha256."""
        self._kept: dict[str, str] = {}
        if key is None:
            return
        ledger, marker = self.directory / LEDGER, self.directory / store.MARKER_FILE
        try:
            listed = set(store.read_json(marker)["outputs"])
            data = store.read_json(ledger) if LEDGER in listed and ledger.is_file() else None
        except (store.StoreError, KeyError, TypeError):
            return
        if not (isinstance(data, dict) and data.get("key") == key and isinstance(data.get("files"), dict)):
            return
        for relative, digest in data["files"].items():
            path = self.directory / relative
            if (isinstance(relative, str) and relative in listed and isinstance(digest, str) and path.is_file()
                    and not path.is_symlink() and file_digest(path) == digest):
                self._kept[relative] = digest

    def _relative(self, path: Path) -> str:
        return Path(path).absolute().relative_to(self.directory.absolute()).as_posix()

    def kept(self, path: Path) -> bool:
        """Whether ``path`` holds what this report would draw there (see the module's docstring); it is then
        recorded as kept."""
        relative = self._relative(path)
        if relative not in self._kept:
            return False
        self.recorded[relative] = self._kept[relative]
        return True

    def keeps(self, pattern_matches: Callable[[str], bool]) -> list[str]:
        """The paths (relative) that can be kept among those ``pattern_matches`` accepts."""
        return [relative for relative in self._kept if pattern_matches(relative)]

    def record(self, paths: Iterable[Path]) -> None:
        """Files this report has just written."""
        for path in paths:
            self.recorded[self._relative(path)] = file_digest(path)

    def figure(self, path: Path, draw: Callable[[Path], str]) -> str:
        """The figure at ``path``: kept where it can be, else ``draw(path)`` (which saves it and returns its path
        relative to the study directory, as :func:`~rlcompare.analysis.report.save_figure` does)."""
        if self.kept(path):
            return f"{path.parent.name}/{path.name}"
        shown = draw(path)
        self.record([path])
        return shown

    def save(self) -> None:
        """Write the ledger: this report's key and the files it kept or drew. Where a file of that name is there
        and rlcompare did not write it (a directory shared with ``--force``), it is left alone and nothing is
        ledgered: the next report draws everything again."""
        ledger = self.directory / LEDGER
        if self.key is None:
            return
        if ledger.exists() or ledger.is_symlink():
            try:
                listed = LEDGER in store.read_json(self.directory / store.MARKER_FILE)["outputs"]
            except (store.StoreError, KeyError, TypeError):
                listed = False
            if not listed:
                return
        store.write_json_atomic(ledger, {"key": self.key, "files": dict(sorted(self.recorded.items()))})
