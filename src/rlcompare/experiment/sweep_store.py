"""The results store of a sweep: a partitioned Parquet dataset of trials and a manifest.

- ``sweep.toml``: the sweep file the store was last run with;
- ``manifest.json``: every trial of that sweep (id, config hash, seed index, seed, status, swept values);
- ``trials/config=<hash>/trial=<seed>/``: one run directory per trial (``config.json``,
  ``episodes.parquet``, ``evaluations.parquet``, ``qtables.npz``, ``meta.json``).

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

import shutil
import threading
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.dataset as ds

from rlcompare.engine.kernel import Records
from rlcompare.experiment import store
from rlcompare.experiment.results import Results
from rlcompare.experiment.sweep import Sweep, Trial

MANIFEST_FILE = "manifest.json"
SWEEP_FILE = "sweep.toml"
TRIALS_DIR = "trials"
DONE, PENDING = "done", "pending"


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
        return store.is_complete(self.trial_dir(trial))

    def open(self, sweep: Sweep, sweep_text: str) -> list[Trial]:
        """Prepare the directory for ``sweep``; the trials still to run, in the sweep's order."""
        store.prepare_directory(self.root)
        for stale in self.root.glob(f"{TRIALS_DIR}/*/*/.*.tmp"):  # left by a process killed mid-write
            stale.unlink(missing_ok=True)
        self._sweep, self._trials = sweep, sweep.trials()
        self._status = {t.trial_id: DONE if self.is_done(t) else PENDING for t in self._trials}
        store.write_atomic(self.root / SWEEP_FILE, lambda handle: handle.write(sweep_text.encode()))
        self._write_manifest()
        return [t for t in self._trials if self._status[t.trial_id] == PENDING]

    def save(self, trial: Trial, results: Results) -> None:
        """Write a finished trial's run directory; mark it done in the manifest."""
        trial_dir = self.trial_dir(trial)
        if trial_dir.exists() and not store.is_complete(trial_dir):
            shutil.rmtree(trial_dir)  # an earlier attempt that did not finish
        results.save(trial_dir)
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
            "name": sweep.name, "root_seed": sweep.root_seed, "seeds": list(sweep.seeds), "swept": list(sweep.swept),
            "trials": [{"id": t.trial_id, "config_hash": t.config_hash, "seed_index": t.seed_index, "seed": t.seed,
                        "status": self._status[t.trial_id],
                        "swept": {key: _plain(getattr(t.config, key)) for key in sweep.swept}}
                       for t in self._trials],
        })


def _plain(value):
    return list(map(_plain, value)) if isinstance(value, tuple) else value


def trial_path(root: Path, config_hash: str, seed: int) -> Path:
    return Path(root) / TRIALS_DIR / f"config={config_hash}" / f"trial={seed}"


def read_table(root: Path, name: str = store.EPISODES_FILE) -> pd.DataFrame:
    """One table of every finished trial (``episodes.parquet`` or ``evaluations.parquet``) as one frame,
    with the config hash and the swept values as columns."""
    manifest = read_manifest(root)
    files = [str(trial_path(root, e["config_hash"], e["seed"]) / name) for e in manifest["trials"]
             if store.is_complete(trial_path(root, e["config_hash"], e["seed"]))]
    if not files:
        return pd.DataFrame()
    partitioning = ds.partitioning(pa.schema([("config", pa.string()), ("trial", pa.int64())]), flavor="hive")
    frame = ds.dataset(files, format="parquet", partitioning=partitioning,
                       partition_base_dir=str(Path(root) / TRIALS_DIR)).to_table().to_pandas()
    swept = pd.DataFrame([{"config": e["config_hash"], **e["swept"]} for e in manifest["trials"]])
    extra = ["config", *(key for key in swept.columns if key not in frame.columns)]
    return frame.drop(columns="trial").merge(swept[extra].drop_duplicates("config"), on="config", how="left")


def read_manifest(root: Path) -> dict:
    path = Path(root) / MANIFEST_FILE
    if not path.is_file():
        raise store.StoreError(f"{root}: not a sweep directory (no {MANIFEST_FILE})")
    manifest = store.read_json(path)
    if not isinstance(manifest, dict) or not isinstance(manifest.get("trials"), list):
        raise store.StoreError(f"{path}: not a sweep manifest")
    return manifest


def load_configurations(root: Path) -> tuple[dict[str, Results], list[str]]:
    """The finished trials of each configuration of a sweep, merged into one :class:`Results` per
    configuration (its seeds in the sweep's order), by config hash; and a line per configuration that has
    none finished."""
    manifest = read_manifest(root)
    by_config: dict[str, list[Results]] = {}
    missing = []
    for entry in manifest["trials"]:
        run_dir = trial_path(root, entry["config_hash"], entry["seed"])
        if store.is_complete(run_dir):
            by_config.setdefault(entry["config_hash"], []).append(Results.load(run_dir))
    hashes = dict.fromkeys(entry["config_hash"] for entry in manifest["trials"])
    for config_hash in hashes:
        if config_hash not in by_config:
            missing.append(f"config {config_hash}: no finished trial")
    return {h: merge(trials) for h, trials in by_config.items()}, missing


def merge(trials: list[Results]) -> Results:
    """One :class:`Results` from the one-seed trials of a configuration."""
    first = trials[0]
    records = Records(*(np.concatenate([getattr(t.records, name) for t in trials])
                        if name != "snapshot_episodes" else first.records.snapshot_episodes
                        for name in Records._fields))
    seeds = tuple(seed for t in trials for seed in t.seeds)
    timings = {key: sum(t.meta["timings"][key] for t in trials)
               for key in ("wall_seconds", "training_steps", "evaluation_steps")}
    timings["threads"] = 1
    meta = {**first.meta, "seeds": list(seeds), "timings": timings}
    return Results(config=replace(first.config, seeds=seeds), epsilons=first.epsilons, records=records, meta=meta)


def run_sweep(sweep: Sweep, sweep_text: str, out: Path, backend, progress: Callable[[Trial], None] | None = None,
              ) -> tuple[int, int]:
    """Run every trial of ``sweep`` that ``out`` does not hold yet on ``backend``, saving each as it finishes.
    Returns (trials already finished, trials run now)."""
    backend.connect()
    sweep_store = SweepStore(out)
    todo = sweep_store.open(sweep, sweep_text)

    def on_done(trial: Trial, results: Results) -> None:
        sweep_store.save(trial, results)
        if progress is not None:
            progress(trial)

    try:
        backend.run(todo, on_done)
    finally:
        sweep_store.flush()
    return len(sweep.trials()) - len(todo), len(todo)
