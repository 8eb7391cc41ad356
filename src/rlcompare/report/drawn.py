"""Figures and videos drawn again only when what they are drawn from changes.

A report's figures and videos are functions of the stored runs each one reads, of rlcompare's code and of the
libraries that draw. A study directory keeps a ledger of the files its last report drew, ``.drawn.json``: for each,
the key of what it was drawn from (:meth:`Drawn.key`) and the sha256 of its bytes as written. A report keeps a file
instead of drawing it again only when all three hold:

- the directory's marker lists it, so rlcompare wrote it (:mod:`rlcompare.experiment.store`);
- the ledger's key for it is the one this report computes: the same runs, by the checksums their ``meta.json``
  recorded and loading verified, the same source of rlcompare and versions of the libraries, the same description
  (a video's seed, stage, start state and title);
- the file's bytes still hash to what the ledger recorded: nobody edited, replaced or truncated it.

Anything else is drawn again and overwritten. So a study that gains a configuration draws the figures that show
it and keeps the others. The ledger is written after the files it lists, so a report stopped half-way leaves a
ledger that vouches only for files whose bytes are still those it recorded.
"""

from __future__ import annotations

import functools
import glob
import hashlib
import importlib.metadata
import json
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from rlcompare.experiment import store
from rlcompare.experiment.paths import matches

LEDGER = ".drawn.json"
LIBRARIES = ("numpy", "matplotlib", "pillow", "pandas", "scipy", "gymnasium", "pygame", "imageio-ffmpeg", "numba")
"""The libraries whose versions enter the key: those that compute, draw or encode what a report shows."""


def _draws(relative: str) -> bool:
    """Whether a file of rlcompare's source can change what a report draws from stored runs: all but the command
    line and the training loops (what training made is in the runs' checksums; the records' layout,
    ``engine/state.py``, is read back, so it counts)."""
    return not (relative.startswith("cli/") or (relative.startswith("engine/") and relative != "engine/state.py"))


@functools.lru_cache(maxsize=1)
def code_fingerprint() -> str:
    """sha256 of rlcompare's Python files that can change what a report draws (paths and bytes, :func:`_draws`) and
    of the versions of :data:`LIBRARIES`: any change to that code or to a library that draws makes every file be
    drawn again."""
    digest = hashlib.sha256()
    package = Path(__file__).resolve().parent.parent
    for path in sorted(package.rglob("*.py")):
        relative = path.relative_to(package).as_posix()
        if _draws(relative):
            digest.update(relative.encode() + b"\0" + path.read_bytes() + b"\0")
    for name in LIBRARIES:
        try:
            version = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            version = ""
        digest.update(f"{name}={version}\0".encode())
    return digest.hexdigest()


def file_digest(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(2**20), b""):
            digest.update(block)
    return digest.hexdigest()


def _recorded_files(results: Any) -> dict[str, Any] | None:
    """The checksums ``meta.json`` recorded for a loaded run's files; None where there are none."""
    meta = getattr(results, "meta", None)
    contents = meta.get("contents") if isinstance(meta, dict) else None
    files = contents.get("files") if isinstance(contents, dict) else None
    return files if isinstance(files, dict) and files else None


class Drawn:
    """The ledger of one study directory for one report: which files can be kept, and what was drawn."""

    def __init__(self, directory: Path) -> None:
        self.directory = Path(directory)
        self.recorded: dict[str, dict[str, str]] = {}
        """The files this report keeps or drew, by path relative to the directory: their key and sha256."""
        self._unkeyed: set[str] = set()
        """Files this report drew from runs without recorded checksums: kept on disk, never in the ledger."""
        self._ledger: dict[str, dict[str, Any]] = {}
        self._listed = store.listed_outputs(self.directory)
        ledger = self.directory / LEDGER
        try:
            data = store.read_json(ledger) if LEDGER in self._listed and ledger.is_file() else None
        except store.StoreError:
            return
        files = data.get("files") if isinstance(data, dict) else None
        if isinstance(files, dict):
            self._ledger = {relative: entry for relative, entry in files.items()
                            if isinstance(entry, dict) and isinstance(entry.get("key"), str)
                            and isinstance(entry.get("sha256"), str)}

    @staticmethod
    def key(runs: Iterable[Any], what: Any = None) -> str | None:
        """The key of a file drawn from ``runs`` (loaded, so their files were verified against the checksums their
        ``meta.json`` recorded) and ``what`` (anything else it shows, as JSON); None where a run has no recorded
        checksums, and then the file is always drawn."""
        files = {}
        for results in runs:
            recorded = _recorded_files(results)
            if recorded is None:
                return None
            files[results.config.name] = recorded
        text = json.dumps({"code": code_fingerprint(), "runs": files, "what": what}, sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()

    def _relative(self, path: Path) -> str:
        return Path(path).absolute().relative_to(self.directory.absolute()).as_posix()

    def kept(self, path: Path, key: str | None) -> bool:
        """Whether ``path`` holds what this report would draw there from what ``key`` stands for (see the
        module's docstring); it is then recorded as kept."""
        relative, path = self._relative(path), Path(path)
        entry = self._ledger.get(relative)
        if (key is None or entry is None or entry["key"] != key or relative not in self._listed
                or path.is_symlink() or not path.is_file() or file_digest(path) != entry["sha256"]):
            return False
        self.recorded[relative] = {"key": key, "sha256": entry["sha256"]}
        return True

    def record(self, paths: Iterable[Path], key: str | None) -> None:
        """Files this report has just written, drawn from what ``key`` stands for."""
        for path in paths:
            if key is None:
                self._unkeyed.add(self._relative(path))
            else:
                self.recorded[self._relative(path)] = {"key": key, "sha256": file_digest(path)}

    def figure(self, path: Path, draw: Callable[[Path], str], runs: Iterable[Any]) -> str:
        """The figure at ``path``, drawn from ``runs``: kept where it can be, else ``draw(path)`` (which saves it
        and returns its path relative to the study directory, as :func:`~rlcompare.report.page.save_figure`
        does)."""
        key = self.key(runs)
        if self.kept(path, key):
            return f"{path.parent.name}/{path.name}"
        shown = draw(path)
        self.record([path], key)
        return shown

    def remove_unrecorded(self, pattern: str) -> list[str]:
        """Delete the files matching ``pattern`` that rlcompare listed here and this report neither kept nor drew
        (figures of runs that are gone), and nothing else; their relative paths."""
        stale = [relative for relative in sorted(store.listed_outputs(self.directory))
                 if matches(relative, pattern) and relative not in self.recorded
                 and relative not in self._unkeyed]
        for relative in stale:
            store.remove_outputs(self.directory, glob.escape(relative))
        return stale

    def save(self) -> None:
        """Write the ledger: the files this report kept or drew. Where a file of that name is there and rlcompare
        did not write it (a directory shared with ``--force``), it is left alone and nothing is ledgered: the next
        report draws everything again."""
        ledger = self.directory / LEDGER
        if (ledger.exists() or ledger.is_symlink()) and LEDGER not in store.listed_outputs(self.directory):
            return
        store.write_json_atomic(ledger, {"files": dict(sorted(self.recorded.items()))})
