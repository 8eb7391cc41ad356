"""Output directories: what rlcompare may write where, atomic writes and locks.

Ownership. rlcompare writes only inside directories it owns: each holds a marker, ``.rlcompare.json``, that
names what the directory is (a run, a study, a sweep's store) and lists every file rlcompare wrote there, a
file's name entered before the file is written. A file is created, replaced or deleted only when it is new
or listed, so a user's own files, in a directory rlcompare made or in one it was told to share with
``--force``, are never touched. A directory that holds anything else is refused unless ``--force`` is given.
A process writing a directory holds its lock (``.rlcompare.lock``, an ``flock`` the kernel drops when the
process dies), so a second process stops with a message instead of racing it.

Every file is written to a temporary name in the same directory and renamed into place, so a reader never
sees half a file and an interrupted run leaves nothing that looks finished.

What a run directory holds, and how it is written and verified, is :mod:`rlcompare.experiment.rundir`.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import glob
import json
import os
import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

from rlcompare.atomic import FILE_MODE, atomic_file
from rlcompare.experiment.paths import StoreError as StoreError  # the error of every store function
from rlcompare.experiment.paths import inside, is_inner_path, matches
from rlcompare.formatting import cut, quote

MARKER_FILE = ".rlcompare.json"
LOCK_FILE = ".rlcompare.lock"
OWN_FILES = (MARKER_FILE, LOCK_FILE)
MAX_JSON_BYTES = 16 * 2**20
"""The largest metadata file rlcompare reads (its own are far smaller); a larger one is not of a run."""
MAX_NAME_BYTES = 255




@dataclass(frozen=True)
class Owner:
    """What an output directory is: a ``run``, a ``study`` (``name``: which one), a ``sweep`` store or a
    ``bench``mark's measurements."""

    kind: str
    name: str = ""

    def __str__(self) -> str:
        return f"the {self.name} study" if self.kind == "study" else f"a {self.kind} directory"


RUN = Owner("run")
SWEEP = Owner("sweep")
BENCH = Owner("bench")


# --- paths and markers ----------------------------------------------------------------------------------

def check_path(path: Path | str, option: str = "--out") -> Path:
    """A path that can name an output directory: not empty, no component longer than the system allows; a leading
    ``~`` is the user's home, as a shell would read it (a quoted ``--out "~/runs"`` is not a directory named ``~``)."""
    text = os.path.expanduser(str(path))
    if not text.strip():
        raise StoreError(f"{option}: got an empty path; allowed: a directory path")
    for part in Path(text).parts:
        if len(part.encode()) > MAX_NAME_BYTES:
            raise StoreError(f"{option}: got a name of {len(part.encode())} bytes ({quote(part, 40)}); allowed: "
                             f"at most {MAX_NAME_BYTES} bytes per path component")
    return Path(text)


def read_json(path: Path, limit: int = MAX_JSON_BYTES) -> Any:
    """A JSON file rlcompare wrote; one larger than ``limit`` bytes is refused unread."""
    path = Path(path)
    try:
        size = path.stat().st_size
        if size > limit:
            raise StoreError(f"{path}: {size:,} bytes, more than rlcompare writes there (at most {limit:,}); "
                             "not a file of this run")
        return json.loads(path.read_text())
    except (OSError, ValueError) as error:
        if isinstance(error, StoreError):
            raise
        raise StoreError(f"{path}: cannot read ({cut(str(error), 200)})") from None


def owner_of(directory: Path) -> Owner | None:
    """Who wrote ``directory``, from its marker; None where there is none."""
    marker = Path(directory) / MARKER_FILE
    if not marker.is_file():
        return None
    data = _read_marker(marker)
    return Owner(data["kind"], data["name"])


def listed_outputs(directory: Path) -> set[str]:
    """The files (relative paths) ``directory``'s marker says rlcompare wrote there; none where it has no marker
    or one rlcompare did not write."""
    try:
        return set(_read_marker(Path(directory) / MARKER_FILE)["outputs"])
    except StoreError:
        return set()


def _read_marker(marker: Path) -> dict[str, Any]:
    data = read_json(marker)
    if not (isinstance(data, dict) and data.get("written_by") == "rlcompare" and isinstance(data.get("kind"), str)
            and isinstance(data.get("name"), str) and isinstance(data.get("outputs"), list)):
        raise StoreError(f"{marker}: not a marker rlcompare wrote")
    for relative in data["outputs"]:
        if not is_inner_path(relative):
            raise StoreError(f"{marker}: lists {quote(str(relative), 80)}, not a path inside its directory; "
                             "rlcompare writes only plain relative paths there, so the list was changed by hand and "
                             "nothing is removed or replaced")
    return data


def _write_marker(directory: Path, owner: Owner, outputs: list[str]) -> None:
    data = {"written_by": "rlcompare", "kind": owner.kind, "name": owner.name, "outputs": sorted(set(outputs))}
    with atomic_file(Path(directory) / MARKER_FILE, "w") as handle:
        json.dump(data, handle, indent=1)


def _foreign_entries(directory: Path) -> list[str]:
    interrupted = {p.name for p in _marker_temporaries(directory)}
    return sorted(p.name for p in Path(directory).iterdir() if p.name not in OWN_FILES and p.name not in interrupted)


def _marker_temporaries(directory: Path) -> list[Path]:
    """What a first write of the marker killed halfway left: the temporary names rlcompare gives it."""
    return list(Path(directory).glob(f".{glob.escape(MARKER_FILE)}.*.tmp*"))


def refusal(directory: Path, owner: Owner, *, force: bool = False) -> str | None:
    """Why rlcompare may not write ``owner``'s outputs into ``directory``, or None where it may."""
    directory = Path(directory)
    if not directory.exists():
        existing = next((p for p in directory.absolute().parents if p.exists()), Path("/"))
        if not existing.is_dir():
            return f"{existing} is a file; allowed: a directory path"
        if not os.access(existing, os.W_OK | os.X_OK):
            return f"{existing}: the directory is not writable, so {directory} cannot be created there"
        return None
    if not directory.is_dir():
        return f"{directory} is a file; allowed: a directory (new, empty, or written by rlcompare)"
    found = owner_of(directory)
    if found is not None:
        if found != owner:
            return (f"{directory} holds {found}, written by rlcompare; allowed for {owner}: a new or empty "
                    "directory, or one rlcompare wrote for it")
    elif not force:
        entries = _foreign_entries(directory)
        if entries:
            shown = ", ".join(quote(e, 40) for e in entries[:3]) + (f" and {len(entries) - 3} more"
                                                                    if len(entries) > 3 else "")
            return (f"{directory} holds files rlcompare did not write ({shown}); allowed: a new or empty "
                    "directory, or --force to write beside them (rlcompare never replaces a file it did not write)")
    if not os.access(directory, os.W_OK):
        return f"{directory}: the directory is not writable"
    return None


def claim(directory: Path, owner: Owner, *, force: bool = False, outputs: tuple[str, ...] = ()) -> bool:
    """Make ``directory`` an output directory of ``owner`` (see the module's docstring); whether it was created.
    A new marker lists ``outputs`` (names to be written) that do not exist yet, saving a rewrite per file."""
    directory = check_path(directory)
    problem = refusal(directory, owner, force=force)
    if problem:
        raise StoreError(problem)
    made = [d for d in (directory, *directory.parents) if not d.exists()]
    try:
        directory.mkdir(parents=True, exist_ok=True)
        if not (directory / MARKER_FILE).is_file():
            for stale in _marker_temporaries(directory):
                stale.unlink(missing_ok=True)
            _write_marker(directory, owner, [name for name in outputs if not (directory / name).exists()])
    except OSError as error:
        for new in made:  # a full disk had room for the directories but not the marker: leave nothing behind
            with contextlib.suppress(OSError):
                new.rmdir()
        if isinstance(error, StoreError):
            raise
        raise StoreError(f"{directory}: cannot create the directory ({error.strerror})") from None
    return bool(made)


def discard(directory: Path) -> None:
    """Remove a directory this process created and wrote nothing into (a run that failed before any output)."""
    directory = Path(directory)
    with contextlib.suppress(OSError):
        if not _foreign_entries(directory) and not _read_marker(directory / MARKER_FILE)["outputs"]:
            for name in OWN_FILES:
                (directory / name).unlink(missing_ok=True)
            directory.rmdir()


# --- what a directory's marker lists ----------------------------------------------------------------------

_LEDGER_LOCK = threading.RLock()


def _owning_directory(path: Path) -> Path | None:
    for directory in Path(path).parents:
        if (directory / MARKER_FILE).is_file():
            return directory
    return None


def enter_outputs(*paths: Path) -> None:
    """Enter ``paths`` in their directory's list of outputs before they are written, and refuse to replace a
    file rlcompare did not write. Their directory is the nearest one above them with a marker (the same for
    all); outside such directories rlcompare only creates new files."""
    paths = tuple(Path(p).absolute() for p in paths)
    directory = _owning_directory(paths[0])
    with _LEDGER_LOCK:
        listed = _read_marker(directory / MARKER_FILE) if directory is not None else {"outputs": []}
        new = []
        for path in paths:
            relative = path.relative_to(directory).as_posix() if directory is not None else ""
            if directory is not None:
                inside(directory, relative)
            if relative and relative in listed["outputs"]:
                continue
            if path.exists() or path.is_symlink():
                raise StoreError(f"{path}: a file rlcompare did not write; it is left as it is (choose a new "
                                 "directory)")
            new.append(relative)
        if directory is not None and new:
            _write_marker(directory, Owner(listed["kind"], listed["name"]), [*listed["outputs"], *new])


def remove_outputs(directory: Path, pattern: str) -> list[str]:
    """Delete the files rlcompare listed in ``directory`` whose relative path matches ``pattern``
    (``figures/*.png``), and nothing else; the paths removed."""
    directory = Path(directory)
    with _LEDGER_LOCK:
        data = _read_marker(directory / MARKER_FILE)
        removed = [p for p in data["outputs"] if matches(p, pattern)]
        for path in [inside(directory, relative) for relative in removed]:  # every path checked before any removal
            path.unlink(missing_ok=True)
        _write_marker(directory, Owner(data["kind"], data["name"]), [p for p in data["outputs"] if p not in removed])
    return removed


# --- locks ------------------------------------------------------------------------------------------------

_held: dict[Path, list[int]] = {}
"""Each directory this process holds the lock of -> ``[its lock file's descriptor, how many hold it]``."""
_held_lock = threading.Lock()


@contextlib.contextmanager
def locked(directory: Path) -> Iterator[None]:
    """Hold ``directory``'s lock: one process at a time writes it. Re-entrant within a process."""
    key = Path(directory).resolve()
    with _held_lock:
        entry = _held.get(key)
        if entry is None:
            entry = _held[key] = [_acquire(key), 0]
        entry[1] += 1
    try:
        yield
    finally:
        with _held_lock:
            entry[1] -= 1
            if entry[1] == 0:
                os.close(entry[0])  # closing the descriptor releases the flock
                del _held[key]


def _acquire(directory: Path) -> int:
    try:
        fd = os.open(directory / LOCK_FILE, os.O_RDWR | os.O_CREAT, FILE_MODE)
    except OSError as error:
        raise StoreError(f"{directory}: cannot write here ({error.strerror})") from None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        os.close(fd)
        raise _in_use(directory) from None
    os.ftruncate(fd, 0)
    os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
    return fd


def _in_use(directory: Path) -> StoreError:
    """The refusal of a directory another process holds the lock of, naming that process (the lock file's)."""
    try:
        with (directory / LOCK_FILE).open("rb") as lock:
            holder = lock.read(32).decode(errors="replace").strip() or "unknown"
    except OSError:
        holder = "unknown"
    return StoreError(f"{directory}: another rlcompare process (pid {holder}) is writing here; wait for it to "
                      "finish, or use another directory")


def refuse_while_written(directory: Path) -> None:
    """Refuse to read ``directory`` while another process holds its lock: what it holds is not finished. Nothing
    is written (a directory never locked has no lock file, and none is made)."""
    directory = Path(directory).resolve()
    with _held_lock:
        if directory in _held:
            return  # this process is the writer
    try:
        fd = os.open(directory / LOCK_FILE, os.O_RDONLY)
    except OSError:
        return
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except BlockingIOError:
        raise _in_use(directory) from None
    finally:
        os.close(fd)


@contextlib.contextmanager
def rewriting(directory: Path, kind: str) -> Iterator[Owner]:
    """Hold the lock of a directory rlcompare wrote for a ``kind`` (``study``, ``sweep``), to rewrite its
    outputs (a report), and clear what interrupted writes left there; anything else is refused."""
    found = owner_of(directory)
    if found is None or found.kind != kind:
        what = "no marker of rlcompare's" if found is None else f"{found}"
        raise StoreError(f"{directory}: {what}; allowed: a {kind} directory written by rlcompare")
    with locked(directory):
        remove_stale_temporaries(directory)
        yield found


@contextlib.contextmanager
def output_directory(directory: Path, owner: Owner, *, force: bool = False) -> Iterator[Path]:
    """Claim ``directory`` for ``owner``, hold its lock and clear what interrupted writes left there; if it was
    created here and the block fails before writing anything into it, remove it again."""
    directory = check_path(directory)
    created = claim(directory, owner, force=force)
    try:
        with locked(directory):
            remove_stale_temporaries(directory)
            yield directory
    except BaseException:
        if created:
            discard(directory)
        raise


# --- atomic writes ----------------------------------------------------------------------------------------

@contextlib.contextmanager
def _owned_file(path: Path, mode: str) -> Iterator[IO[Any]]:
    """An atomic write of a file rlcompare may write (:func:`enter_outputs`), with OS errors as one line."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        enter_outputs(path)
        with atomic_file(path, mode) as handle:
            yield handle
    except StoreError:
        raise
    except OSError as error:
        reason = "no space left on the device" if error.errno == errno.ENOSPC else (error.strerror or str(error))
        raise StoreError(f"{path}: cannot write ({cut(reason, 200)})") from None


def write_atomic(path: Path, write: Callable[[IO[bytes]], object]) -> None:
    """Call ``write`` on a binary handle to a temporary file, then rename it to ``path``."""
    with _owned_file(Path(path), "wb") as handle:
        write(handle)


def write_bytes_atomic(path: Path, data: bytes) -> None:
    write_atomic(path, lambda handle: handle.write(data))


def write_json_atomic(path: Path, data: Any) -> None:
    with _owned_file(Path(path), "w") as handle:
        json.dump(data, handle, indent=2, sort_keys=True)
        handle.write("\n")


def remove_stale_temporaries(directory: Path) -> None:
    """Delete what interrupted writes left of the files listed in ``directory``'s marker (call with its lock):
    the temporary names rlcompare gives them, and nothing else."""
    directory = Path(directory)
    listed = [MARKER_FILE, *_read_marker(directory / MARKER_FILE)["outputs"]]
    targets = [inside(directory, relative) for relative in listed]  # every path checked before any removal
    for target in targets:
        for stale in target.parent.glob(f".{glob.escape(target.name)}.*.tmp*"):
            stale.unlink(missing_ok=True)
