"""The run directory: its files, written the one way every engine and study does (:func:`write_run`), and read
back only when they are all there and belong together (:func:`read_run`, :func:`verify_run`).

A run directory holds everything needed to rebuild every table and figure without training again:

| file                    | what                                                                        |
|-------------------------|-----------------------------------------------------------------------------|
| ``config.json``         | the resolved :class:`ExperimentConfig`                                      |
| ``episodes.parquet``    | one row per seed x episode: ε, behaviour return, length, terminated         |
| ``evaluations.parquet`` | one row per seed x evaluation round x episode of the greedy policy          |
| ``qtables.npz``         | Q-tables at the named stages, state-visit counts, seeds, ε per episode      |
| ``meta.json``           | versions, seeds, timings, command line, and the size and checksum of each   |
|                         | other file; written last, so it marks the run complete                      |

Its files are written as every output of rlcompare is (:mod:`rlcompare.experiment.store`): in a directory
rlcompare owns, under its lock, each one atomically.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

from rlcompare.experiment import store
from rlcompare.experiment.store import StoreError

CONFIG_FILE = "config.json"
EPISODES_FILE = "episodes.parquet"
EVALUATIONS_FILE = "evaluations.parquet"
QTABLES_FILE = "qtables.npz"
META_FILE = "meta.json"
RUN_FILES = (CONFIG_FILE, EPISODES_FILE, EVALUATIONS_FILE, QTABLES_FILE, META_FILE)
CONTENT_FILES = (CONFIG_FILE, EPISODES_FILE, EVALUATIONS_FILE, QTABLES_FILE)
"""The files whose checksums ``meta.json`` records."""
PARAMS_FILE = "params.npz"
DEEP_CONTENT_FILES = (CONFIG_FILE, EPISODES_FILE, EVALUATIONS_FILE, PARAMS_FILE)
"""A deep run's: the network's parameters stand where a tabular run keeps its Q-tables."""
DEEP_RUN_FILES = (*DEEP_CONTENT_FILES, META_FILE)


def is_complete(run_dir: Path, files: tuple[str, ...] = RUN_FILES) -> bool:
    """Whether every file of a finished run is present (``meta.json`` is written last); whether they belong
    together is :func:`verify_run`'s question. ``files``: the engine's, with ``meta.json``."""
    return all((Path(run_dir) / name).is_file() for name in files)


def write_run(run_dir: Path, config: dict, contents: dict[str, bytes], meta: dict, record: dict | None = None
              ) -> Path:
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


def read_run(run_dir: Path, content_files: tuple[str, ...], expected_config: dict | None = None
             ) -> tuple[dict, dict]:
    """``(meta, config)`` of a finished run directory whose files belong together (:func:`verify_run`);
    anything else is a :class:`StoreError` naming the file."""
    meta = verify_run(run_dir, expected_config, content_files)
    config = store.read_json(Path(run_dir) / CONFIG_FILE)
    if not isinstance(config, dict):
        raise StoreError(f"{Path(run_dir) / CONFIG_FILE}: not a configuration rlcompare wrote")
    return meta, config


def file_record(data: bytes) -> dict[str, Any]:
    return {"bytes": len(data), "sha256": hashlib.sha256(data).hexdigest()}


def verify_run(run_dir: Path, expected_config: dict | None = None, content_files: tuple[str, ...] = CONTENT_FILES
               ) -> dict:
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
    if not isinstance(files, dict) or sorted(files) != sorted(content_files):
        raise StoreError(f"{run_dir / META_FILE}: no record of the run's contents (not written by this version of "
                         "rlcompare, or damaged); run it again")
    for name in content_files:
        recorded = files[name] if isinstance(files[name], dict) else {}
        if (run_dir / name).stat().st_size != recorded.get("bytes") or _record_of(run_dir / name) != recorded:
            raise StoreError(f"{run_dir / name}: does not belong to this run (its size or checksum differs from "
                             f"what {META_FILE} recorded when the run was written); run it again")
    if expected_config is not None and store.read_json(run_dir / CONFIG_FILE) != expected_config:
        raise StoreError(f"{run_dir / CONFIG_FILE}: another configuration than the one asked for")
    return meta


def _record_of(path: Path) -> dict[str, Any]:
    digest = hashlib.sha256()
    size = 0
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(2**20), b""):
            digest.update(block)
            size += len(block)
    return {"bytes": size, "sha256": digest.hexdigest()}
