"""The run directory: its files, written the one way every engine and study does (:func:`write_run`), and read
back only when they are all there and belong together (:func:`read_run`, :func:`verify_run`). The results of
either engine are written and read here, by one writer and one reader (:func:`write_results`,
:func:`read_results`).

A run directory holds everything needed to rebuild every table and figure without training again:

| file                    | what                                                                        |
|-------------------------|-----------------------------------------------------------------------------|
| ``config.json``         | the resolved configuration, naming its engine                               |
| ``episodes.parquet``    | one row per seed x episode: return, length, terminated (and ε, or the step) |
| ``evaluations.parquet`` | one row per seed x evaluation round x episode of the greedy policy          |
| ``qtables.npz``         | tabular: Q-tables at the named stages, state-visit counts, seeds, ε         |
| ``params.npz``          | deep: the network's parameters at each stage, seeds                         |
| ``meta.json``           | versions, seeds, timings, command line, and the size and checksum of each   |
|                         | other file; written last, so it marks the run complete                      |

Its files are written as every output of rlcompare is (:mod:`rlcompare.experiment.store`): in a directory
rlcompare owns, under its lock, each one atomically.
"""

from __future__ import annotations

import hashlib
import io
import json
from collections.abc import Collection
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, Protocol, TypeVar

from rlcompare.experiment import store
from rlcompare.experiment.store import StoreError
from rlcompare.formatting import cut

if TYPE_CHECKING:
    import numpy as np
    import pandas as pd

CONFIG_FILE = "config.json"
EPISODES_FILE = "episodes.parquet"
EVALUATIONS_FILE = "evaluations.parquet"
QTABLES_FILE = "qtables.npz"
META_FILE = "meta.json"
PARAMS_FILE = "params.npz"
"""A deep run's arrays: the network's parameters stand where a tabular run keeps its Q-tables."""
RUN_FILES = (CONFIG_FILE, EPISODES_FILE, EVALUATIONS_FILE, QTABLES_FILE, META_FILE)
DEEP_RUN_FILES = (CONFIG_FILE, EPISODES_FILE, EVALUATIONS_FILE, PARAMS_FILE, META_FILE)


def is_complete(run_dir: Path, files: tuple[str, ...] = RUN_FILES) -> bool:
    """Whether every file of a finished run is present (``meta.json`` is written last); whether they belong
    together is :func:`verify_run`'s question. ``files``: the engine's, with ``meta.json``."""
    return all((Path(run_dir) / name).is_file() for name in files)


def write_run(run_dir: Path, config: dict[str, Any], contents: dict[str, bytes], meta: dict[str, Any],
              record: dict[str, Any] | None = None) -> Path:
    """Write a run directory, the one way every engine and study does: ``config.json`` and ``contents``
    (file name -> bytes) each under a temporary name renamed into place, then ``meta.json`` last, with
    ``record`` (what the run holds: seeds, rows, shapes) and the size and checksum of every other file. A
    reader (:func:`verify_run`) takes the run as finished only once ``meta.json`` is there and agrees."""
    run_dir = Path(run_dir)
    contents = {CONFIG_FILE: (json.dumps(config, indent=2, sort_keys=True) + "\n").encode(), **contents}
    names = (*contents, META_FILE)
    store.claim(run_dir, store.RUN, outputs=names)
    store.enter_outputs(*(run_dir / name for name in names))
    (run_dir / META_FILE).unlink(missing_ok=True)  # the run is complete again only when rewritten
    for name, data in contents.items():
        store.write_bytes_atomic(run_dir / name, data)
    files = {name: file_record(data) for name, data in contents.items()}
    store.write_json_atomic(run_dir / META_FILE, {**meta, "contents": {**(record or {}), "files": files}})
    return run_dir


def read_run(run_dir: Path, content_files: tuple[str, ...], expected_config: dict[str, Any] | None = None
             ) -> tuple[dict[str, Any], dict[str, Any]]:
    """``(meta, config)`` of a finished run directory whose files belong together (:func:`verify_run`);
    anything else is a :class:`StoreError` naming the file."""
    meta = verify_run(run_dir, expected_config, content_files)
    config = store.read_json(Path(run_dir) / CONFIG_FILE)
    if not isinstance(config, dict):
        raise StoreError(f"{Path(run_dir) / CONFIG_FILE}: not a configuration rlcompare wrote")
    return meta, config


def file_record(data: bytes) -> dict[str, Any]:
    return {"bytes": len(data), "sha256": hashlib.sha256(data).hexdigest()}


def verify_run(run_dir: Path, expected_config: dict[str, Any] | None, content_files: tuple[str, ...]
               ) -> dict[str, Any]:
    """``meta.json`` of a finished run whose files belong together: each one's size and checksum equal what
    ``meta.json`` recorded when the run was written, and ``config.json`` is ``expected_config`` where given.
    Anything else is a :class:`StoreError` naming the file."""
    run_dir = Path(run_dir)
    missing = [name for name in (*content_files, META_FILE) if not (run_dir / name).is_file()]
    if missing:
        raise StoreError(f"{run_dir}: not a complete run directory; missing {', '.join(missing)}")
    meta = store.read_json(run_dir / META_FILE)
    contents = meta.get("contents") if isinstance(meta, dict) else None
    files = contents.get("files") if isinstance(contents, dict) else None
    if not isinstance(meta, dict) or not isinstance(files, dict) or sorted(files) != sorted(content_files):
        raise StoreError(f"{run_dir / META_FILE}: no record of the run's contents (not written by this version of "
                         "rlcompare, or damaged); run it again")
    for name in content_files:
        check_recorded(run_dir / name, files[name], run_dir / META_FILE)
    if expected_config is not None and store.read_json(run_dir / CONFIG_FILE) != expected_config:
        raise StoreError(f"{run_dir / CONFIG_FILE}: another configuration than the one asked for")
    return meta


def check_recorded(path: Path, recorded: Any, record_file: Path, whose: str = "run") -> None:
    """A :class:`StoreError` naming ``path`` where it is missing or its size or checksum differs from ``recorded``
    (what ``record_file`` entered when the ``whose`` was written)."""
    if not path.is_file():
        raise StoreError(f"{path}: missing; {record_file} records it")
    if not isinstance(recorded, dict) or path.stat().st_size != recorded.get("bytes") or (
            _record_of(path) != recorded):
        raise StoreError(f"{path}: does not belong to this {whose} (its size or checksum differs from what "
                         f"{record_file.name} recorded when the {whose} was written); run it again")


def _record_of(path: Path) -> dict[str, Any]:
    digest = hashlib.sha256()
    size = 0
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(2**20), b""):
            digest.update(block)
            size += len(block)
    return {"bytes": size, "sha256": digest.hexdigest()}


class Config(Protocol):
    """A configuration of either engine, as its run directory holds it."""

    @property
    def seeds(self) -> tuple[int, ...]: ...

    def to_dict(self) -> dict[str, Any]: ...


R = TypeVar("R", bound="RunResults")


class RunResults(Protocol):
    """What a run of either engine produces, as its run directory holds it."""

    arrays_file: ClassVar[str]
    """The file of arrays beside the tables: ``qtables.npz`` or ``params.npz``."""
    meta: dict[str, Any]

    @property
    def config(self) -> Any: ...

    @property
    def seeds(self) -> tuple[int, ...]: ...

    def labels(self) -> dict[str, str]:
        """The columns every row of its tables carries: study, env, algorithm, schedule."""
        ...

    def columns(self) -> dict[str, dict[str, np.ndarray]]:
        """Its tables' other columns: ``episodes`` and ``evaluations``."""
        ...

    def arrays(self) -> dict[str, np.ndarray]:
        """What :attr:`arrays_file` holds."""
        ...

    def record(self) -> dict[str, Any]:
        """What the run holds, for ``meta.json``'s ``contents``: seeds, rows, shapes."""
        ...

    @classmethod
    def read_config(cls, stored: dict[str, Any], expected: Any) -> Any:
        """The configuration ``config.json`` holds (a :class:`ValueError` where it is not ``expected``)."""
        ...

    @classmethod
    def from_files(cls: type[R], config: Any, episodes: pd.DataFrame, evaluations: pd.DataFrame,
                   arrays: dict[str, np.ndarray], meta: dict[str, Any]) -> R:
        """The results the files hold (a :class:`ValueError` where they do not belong to ``config``)."""
        ...


def files_of(results: type[RunResults] | RunResults) -> tuple[str, ...]:
    """The files of a run directory of ``results``' engine whose checksums ``meta.json`` records."""
    return (CONFIG_FILE, EPISODES_FILE, EVALUATIONS_FILE, results.arrays_file)


def write_results(run_dir: Path, results: RunResults) -> Path:
    """Write the run directory of ``results`` (:func:`write_run`): its configuration, its two tables in Parquet,
    each label a dictionary-encoded column, and its arrays."""
    labels, columns = results.labels(), results.columns()
    return write_run(run_dir, results.config.to_dict(), {
        EPISODES_FILE: _parquet_bytes(labels, columns["episodes"]),
        EVALUATIONS_FILE: _parquet_bytes(labels, columns["evaluations"]),
        results.arrays_file: _npz_bytes(results.arrays()),
    }, results.meta, results.record())


def read_results(run_dir: Path, results: type[R], expected: Any = None) -> R:
    """The results of a finished run directory whose files belong together (:func:`read_run`), in ``results``'
    type; anything else is a :class:`StoreError` naming the file."""
    import numpy as np  # what reads the tables and arrays: imported once a run is read
    import pandas as pd

    run_dir = Path(run_dir)
    meta, stored = read_run(run_dir, files_of(results))
    try:
        config = results.read_config(stored, expected)
    except (ValueError, TypeError) as error:
        raise StoreError(f"{run_dir / CONFIG_FILE}: {cut(str(error), 300)}") from None
    try:
        episodes = pd.read_parquet(run_dir / EPISODES_FILE)
        evaluations = pd.read_parquet(run_dir / EVALUATIONS_FILE)
        with np.load(run_dir / results.arrays_file, allow_pickle=False) as stored_arrays:
            arrays = {key: stored_arrays[key] for key in stored_arrays.files}
    except Exception as error:
        raise StoreError(f"{run_dir}: cannot read the stored records ({cut(str(error), 200)})") from None
    try:
        return results.from_files(config, episodes, evaluations, arrays, meta)
    except (ValueError, KeyError) as error:
        raise StoreError(f"{run_dir}: {cut(str(error), 300)}") from None


def _parquet_bytes(labels: dict[str, str], columns: dict[str, np.ndarray]) -> bytes:
    """The labels, each one dictionary-encoded (categorical) column, then ``columns``, in Parquet."""
    import numpy as np
    import pyarrow as pa
    import pyarrow.parquet as pq

    rows = len(next(iter(columns.values())))
    label_columns = {name: pa.DictionaryArray.from_arrays(np.zeros(rows, dtype=np.int32), pa.array([str(value)]))
                     for name, value in labels.items()}
    buffer = io.BytesIO()
    pq.write_table(pa.table({**label_columns, **columns}), buffer)
    return buffer.getvalue()


def _npz_bytes(arrays: dict[str, np.ndarray]) -> bytes:
    """The arrays in a compressed ``.npz``, without pickles: :func:`read_results` loads none."""
    import numpy as np

    buffer = io.BytesIO()
    np.savez_compressed(buffer, allow_pickle=False, **arrays)
    return buffer.getvalue()


# --- a study's record of its members ------------------------------------------------------------------------------

MEMBERS_FILE = "members.json"
"""A study directory's record: each run it trained or loaded, by name, with the checksum of its ``meta.json``
(which holds the checksums of the run's other files), and the study's own files with theirs."""


def enter_members(study_dir: Path, runs: list[str], files: dict[str, bytes] | None = None) -> None:
    """Enter ``runs`` (run directories of ``study_dir``, finished) and ``files`` (the study's own files, just
    written: name relative to ``study_dir`` -> bytes) in the study's record, beside what it recorded before."""
    study_dir = Path(study_dir)
    try:
        record = members_of(study_dir)
    except StoreError:  # its own record, damaged: begun again from the runs entered now
        record = {"runs": {}, "files": {}}
    record["runs"].update({name: _record_of(study_dir / name / META_FILE) for name in runs})
    record["files"].update({name: file_record(data) for name, data in (files or {}).items()})
    store.write_json_atomic(study_dir / MEMBERS_FILE, record)


def members_of(study_dir: Path) -> dict[str, dict[str, Any]]:
    """What the study recorded (empty where it has no record yet: a study of an earlier version)."""
    path = Path(study_dir) / MEMBERS_FILE
    data = store.read_json(path) if path.is_file() else {}
    if not isinstance(data, dict) or not all(isinstance(data.get(key, {}), dict) for key in ("runs", "files")):
        raise StoreError(f"{path}: not a study's record rlcompare wrote")
    return {"runs": dict(data.get("runs", {})), "files": dict(data.get("files", {}))}


def missing_members(study_dir: Path, reported: Collection[str] = ()) -> list[str]:
    """A line for each run the study recorded that is gone or was replaced since (its ``meta.json`` not the one
    recorded), but those of ``reported`` (runs a report has named already): a report names them and reads nothing
    as if they were there."""
    study_dir = Path(study_dir)
    try:
        runs = members_of(study_dir)["runs"]
    except StoreError as error:
        return [str(error)]
    problems = []
    for name, recorded in sorted(runs.items()):
        if name in reported:
            continue
        meta = study_dir / name / META_FILE
        if not (study_dir / name).is_dir():
            problems.append(f"{name}: the study trained this run ({MEMBERS_FILE}) and {study_dir / name} is gone; "
                            "run the study's command again to train it")
        elif not meta.is_file() or _record_of(meta) != recorded:
            problems.append(f"{name}: not the run the study trained ({meta} differs from what {MEMBERS_FILE} "
                            "recorded); run the study's command again")
    return problems


def read_member_file(study_dir: Path, name: str) -> bytes:
    """One of the study's own files, verified against its record: a :class:`StoreError` naming it where it is
    missing, changed, or never recorded."""
    path, record_file = Path(study_dir) / name, Path(study_dir) / MEMBERS_FILE
    recorded = members_of(Path(study_dir))["files"].get(name)
    if recorded is None:
        raise StoreError(f"{path}: not recorded in {record_file}; run the study's command again")
    check_recorded(path, recorded, record_file, "study")
    return path.read_bytes()
