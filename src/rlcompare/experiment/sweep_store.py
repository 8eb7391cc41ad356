"""The results store of a sweep: a partitioned Parquet dataset of trials and a manifest.

- ``sweep.toml``: the sweep file the store was last run with;
- ``manifest.json``: every trial of that sweep (id, config hash, seed index, seed, status, swept values);
- ``trials/config=<hash>/trial=<seed>/``: one run directory per trial (``config.json``,
  ``episodes.parquet``, ``evaluations.parquet``, ``qtables.npz``, ``meta.json``; a deep sweep's trials hold
  ``params.npz`` in place of ``qtables.npz``).

``trials/*/*/episodes.parquet`` (and ``evaluations.parquet``) form a Hive-partitioned dataset:
:func:`read_table` reads one whole, with ``config`` (the hash) as a column beside the trial's own ``seed``
and labels, and the swept values from the manifest. A trial is finished when its
run directory is complete (``meta.json``, written last, marks it); every file is written under a temporary
name and renamed, so a killed process leaves nothing that looks finished. The manifest is rewritten
atomically by the one process that writes trials, at most once a second while trials finish and once at
the end; on every start it is rebuilt from the run directories, which are the truth: a re-run skips finished
trials and runs the rest.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pandas as pd
import pyarrow as pa
import pyarrow.dataset as ds

from rlcompare.experiment import engines, rundir, store
from rlcompare.experiment.sweep import Sweep, Trial, config_dict, config_hash, swept_value

if TYPE_CHECKING:
    from rlcompare.experiment.backends import Backend

MANIFEST_FILE = "manifest.json"
SWEEP_FILE = "sweep.toml"
TRIALS_DIR = "trials"
DONE, PENDING = "done", "pending"
MAX_MANIFEST_BYTES = 256 * 2**20
"""About 2,000 bytes for each of the most trials a sweep may have."""


class SweepStore:
    """A sweep's directory: where each trial goes, which are finished, and the results of each configuration.
    :meth:`save` may be called from several threads at once."""

    MANIFEST_EVERY = 1.0
    """Seconds between rewrites of the manifest while trials finish."""

    def __init__(self, root: Path) -> None:
        self.root = Path(root)
        self._lock = threading.Lock()
        self._written = 0.0

    def trial_dir(self, trial: Trial) -> Path:
        return trial_path(self.root, trial.config_hash, trial.seed)

    def is_done(self, trial: Trial) -> bool:
        """Whether the trial's run directory is finished, its files belong together and hold this trial."""
        return is_finished(self.trial_dir(trial), config_dict(trial.config), self._sweep.engine)

    def open(self, sweep: Sweep, sweep_text: str) -> list[Trial]:
        """Prepare the directory for ``sweep`` (claimed and locked by the caller); the trials still to run,
        in the sweep's order. A trial whose files do not belong together is run again."""
        self._sweep, self._trials = sweep, sweep.trials()
        self._status = {t.trial_id: DONE if self.is_done(t) else PENDING for t in self._trials}
        for trial in self._trials:
            trial_dir = self.trial_dir(trial)
            if store.owner_of(trial_dir) == store.RUN:
                store.remove_stale_temporaries(trial_dir)  # left by a process killed mid-write
        store.write_bytes_atomic(self.root / SWEEP_FILE, sweep_text.encode())
        self._write_manifest()
        return [t for t in self._trials if self._status[t.trial_id] == PENDING]

    def save(self, trial: Trial, results: rundir.RunResults) -> None:
        """Write a finished trial's run directory; mark it done in the manifest."""
        rundir.write_results(self.trial_dir(trial), results)  # over an earlier attempt that did not finish, if any
        with self._lock:
            self._status[trial.trial_id] = DONE
            if time.monotonic() - self._written >= self.MANIFEST_EVERY:
                self._write_manifest()

    def flush(self) -> None:
        """Write the manifest as it stands."""
        with self._lock:
            self._write_manifest()

    def _write_manifest(self) -> None:
        self._written = time.monotonic()
        sweep = self._sweep
        store.write_json_atomic(self.root / MANIFEST_FILE, {
            "name": sweep.name, "engine": sweep.engine, "root_seed": sweep.root_seed, "seeds": list(sweep.seeds),
            "swept": list(sweep.swept),
            "trials": [{"id": t.trial_id, "config_hash": t.config_hash, "seed_index": t.seed_index, "seed": t.seed,
                        "status": self._status[t.trial_id],
                        "swept": {key: _plain(swept_value(t.config, key)) for key in sweep.swept}}
                       for t in self._trials],
        })


def _plain(value: Any) -> Any:
    """``value`` as JSON writes it, its tuples (nested too) as lists."""
    return list(map(_plain, value)) if isinstance(value, tuple) else value


def trial_path(root: Path, config_hash: str, seed: int) -> Path:
    return Path(root) / TRIALS_DIR / f"config={config_hash}" / f"trial={seed}"


def is_finished(trial_dir: Path, config: dict[str, Any] | None = None, engine: str = engines.DEFAULT) -> bool:
    """Whether a trial's run directory is finished and its files belong together (and hold ``config``);
    ``engine``: the sweep's, whose results say what files a trial has."""
    try:
        rundir.verify_run(trial_dir, config, rundir.files_of(engines.engine(engine).front().Results))
    except store.StoreError:
        return False
    return True


def engine_of(manifest: dict[str, Any]) -> str:
    """The engine of a sweep's trials (stores written before deep sweeps say none: tabular)."""
    return str(manifest.get("engine", engines.DEFAULT))


def read_table(root: Path, name: str = rundir.EPISODES_FILE) -> pd.DataFrame:
    """One table of every finished trial (``episodes.parquet`` or ``evaluations.parquet``) as one frame,
    with the config hash and the swept values as columns; a trial whose files do not belong together is
    left out."""
    manifest = read_manifest(root)
    files = [str(trial_path(root, e["config_hash"], e["seed"]) / name) for e in manifest["trials"]
             if is_finished(trial_path(root, e["config_hash"], e["seed"]), engine=engine_of(manifest))]
    if not files:
        return pd.DataFrame()
    partitioning = ds.partitioning(pa.schema([("config", pa.string()), ("trial", pa.int64())]), flavor="hive")
    frame: pd.DataFrame = ds.dataset(files, format="parquet", partitioning=partitioning,
                       partition_base_dir=str(Path(root) / TRIALS_DIR)).to_table().to_pandas()
    swept = pd.DataFrame([{"config": e["config_hash"], **e["swept"]} for e in manifest["trials"]])
    extra = ["config", *(key for key in swept.columns if key not in frame.columns)]
    return frame.drop(columns="trial").merge(swept[extra].drop_duplicates("config"), on="config", how="left")


def read_manifest(root: Path) -> dict[str, Any]:
    path = Path(root) / MANIFEST_FILE
    if not path.is_file():
        raise store.StoreError(f"{root}: not a sweep directory (no {MANIFEST_FILE})")
    manifest = store.read_json(path, limit=MAX_MANIFEST_BYTES)
    if not isinstance(manifest, dict) or not isinstance(manifest.get("trials"), list):
        raise store.StoreError(f"{path}: not a sweep manifest")
    return manifest


def load_configurations(root: Path) -> tuple[dict[str, Any], list[str]]:
    """The finished trials of each configuration of a sweep, merged into one results of its engine per
    configuration (a deep sweep's: one :class:`~rlcompare.deep.results.DeepResults`), its seeds in the sweep's
    order, by config hash; and a line for each trial whose files do not belong together and each configuration
    that has no finished trial."""
    manifest = read_manifest(root)
    front = engines.engine(engine_of(manifest)).front()  # the deep engine is imported only for a deep sweep
    files = (*rundir.files_of(front.Results), rundir.META_FILE)
    by_config: dict[str, list[rundir.RunResults]] = {}
    problems: list[str] = []
    for entry in manifest["trials"]:
        run_dir = trial_path(root, entry["config_hash"], entry["seed"])
        if rundir.is_complete(run_dir, files):
            try:
                trial = rundir.read_results(run_dir, front.Results)
            except store.StoreError as error:
                problems.append(f"trial {entry['id']} left out: {error}; run the sweep again to redo it")
                continue
            if config_hash(trial.config) != entry["config_hash"] or trial.seeds != (entry["seed"],):
                problems.append(f"trial {entry['id']} left out: {run_dir} holds another trial; run the sweep "
                                "again to redo it")
                continue
            by_config.setdefault(entry["config_hash"], []).append(trial)
    hashes = dict.fromkeys(entry["config_hash"] for entry in manifest["trials"])
    for hash_ in hashes:
        if hash_ not in by_config:
            problems.append(f"config {hash_}: no finished trial")
    return {h: front.merge(trials) for h, trials in by_config.items()}, problems


def run_sweep(sweep: Sweep, sweep_text: str, out: Path, backend: Backend,
              progress: Callable[[Trial], None] | None = None, *, force: bool = False) -> tuple[int, int]:
    """Run every trial of ``sweep`` that ``out`` does not hold yet on ``backend``, saving each as it finishes.
    ``out`` is claimed as a sweep's store and locked while the sweep runs (``force``: even beside files
    rlcompare did not write). Returns (trials already finished, trials run now)."""
    backend.connect()
    with store.output_directory(out, store.SWEEP, force=force):
        sweep_store = SweepStore(out)
        todo = sweep_store.open(sweep, sweep_text)

        def on_done(trial: Trial, results: rundir.RunResults) -> None:
            sweep_store.save(trial, results)
            if progress is not None:
                progress(trial)

        try:
            backend.run(todo, on_done)
        finally:
            sweep_store.flush()
    return len(sweep.trials()) - len(todo), len(todo)
