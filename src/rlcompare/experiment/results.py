"""What a run produces, in memory and in its run directory (layout in :mod:`rlcompare.experiment.store`)."""

from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from rlcompare.engine.state import Records
from rlcompare.experiment import rundir, store
from rlcompare.experiment.config import ExperimentConfig


@dataclass
class Results:
    """Records of every seed of one configuration, with the configuration and how the run went."""

    content_files: ClassVar[tuple[str, ...]] = rundir.CONTENT_FILES
    """The files of its run directory beside ``meta.json``."""

    config: ExperimentConfig
    epsilons: np.ndarray
    """(episodes,) ε of each episode."""
    records: Records
    meta: dict[str, Any]
    """Versions, timings, command line, study name."""

    @property
    def seeds(self) -> tuple[int, ...]:
        return self.config.seeds

    def _labels(self) -> dict[str, Any]:
        c = self.config
        schedule = "none" if c.algorithm == "random" else c.schedule
        return {"study": self.meta.get("study", ""), "env": c.env, "algorithm": c.algorithm,
                "schedule": schedule}

    def episodes(self) -> pd.DataFrame:
        """Long table: one row per seed x episode."""
        return self._episodes_table().to_pandas()

    def evaluations(self) -> pd.DataFrame:
        """Long table: one row per seed x evaluation round x greedy episode."""
        return self._evaluations_table().to_pandas()

    def _episodes_table(self) -> pa.Table:
        runs, episodes = self.records.returns.shape
        return _with_labels({
            "seed": np.repeat(np.asarray(self.seeds, dtype=np.int64), episodes),
            "episode": np.tile(np.arange(episodes, dtype=np.int64), runs),
            "epsilon": np.tile(self.epsilons, runs),
            "return": self.records.returns.ravel(),
            "length": self.records.lengths.ravel(),
            "terminated": self.records.terminated.ravel(),
        }, self._labels(), runs * episodes)

    def _evaluations_table(self) -> pa.Table:
        runs, rounds, per_round = self.records.eval_returns.shape
        return _with_labels({
            "seed": np.repeat(np.asarray(self.seeds, dtype=np.int64), rounds * per_round),
            "round": np.tile(np.repeat(np.arange(rounds, dtype=np.int64), per_round), runs),
            "after_episode": np.tile(np.repeat((np.arange(rounds, dtype=np.int64) + 1)
                                               * self.config.eval_every, per_round), runs),
            "return": self.records.eval_returns.ravel(),
            "length": self.records.eval_lengths.ravel(),
            "terminated": self.records.eval_terminated.ravel(),
        }, self._labels(), runs * rounds * per_round)

    def q_table(self, seed: int, stage: str = "final") -> np.ndarray:
        """The Q-table of one seed at a named stage, ``(cells, actions)``."""
        stages = [name for name, _ in self.config.stages]
        if seed not in self.seeds:
            raise KeyError(f"seed {seed} is not in this run; seeds: {list(self.seeds)}")
        if stage not in stages:
            raise KeyError(f"stage {stage!r} is not in this run; stages: {stages}")
        return self.records.snapshots[self.seeds.index(seed), stages.index(stage)]

    def save(self, run_dir: Path) -> Path:
        """Write the run directory (:func:`~rlcompare.experiment.rundir.write_run`)."""
        return rundir.write_run(run_dir, self.config.to_dict(), {
            rundir.EPISODES_FILE: _parquet_bytes(self._episodes_table()),
            rundir.EVALUATIONS_FILE: _parquet_bytes(self._evaluations_table()),
            rundir.QTABLES_FILE: self._arrays_bytes(),
        }, self.meta, {
            "seeds": list(self.seeds),
            "rows": {"episodes": int(self.records.returns.size), "evaluations": int(self.records.eval_returns.size)},
            "arrays": {name: list(getattr(self.records, name).shape) for name in ("snapshots", "visits")},
        })

    def _arrays_bytes(self) -> bytes:
        buffer = io.BytesIO()
        np.savez_compressed(
            buffer, snapshots=self.records.snapshots, snapshot_episodes=self.records.snapshot_episodes,
            visits=self.records.visits, seeds=np.asarray(self.seeds), epsilons=self.epsilons,
        )
        return buffer.getvalue()

    @classmethod
    def load(cls, run_dir: Path, expected: ExperimentConfig | None = None) -> Results:
        """Read a finished run directory back, without training, after checking that its files belong together
        (and hold ``expected`` where given): anything else is a :class:`~rlcompare.experiment.store.StoreError`
        that names the file."""
        run_dir = Path(run_dir)
        meta, stored = rundir.read_run(run_dir, cls.content_files, None if expected is None else expected.to_dict())
        try:
            config = ExperimentConfig.from_dict(_tuples(stored))
        except ValueError as error:
            raise store.StoreError(f"{run_dir / rundir.CONFIG_FILE}: {error}") from None
        try:
            episodes = pd.read_parquet(run_dir / rundir.EPISODES_FILE)
            evaluations = pd.read_parquet(run_dir / rundir.EVALUATIONS_FILE)
            with np.load(run_dir / rundir.QTABLES_FILE, allow_pickle=False) as arrays:
                tables = {key: arrays[key] for key in arrays.files}
        except Exception as error:
            raise store.StoreError(f"{run_dir}: cannot read the stored records ({store.cut(str(error), 200)})"
                                   ) from None
        runs, n_episodes = len(config.seeds), config.episodes
        rounds, per_round = config.evaluation_rounds, config.eval_episodes
        if len(episodes) != runs * n_episodes or len(evaluations) != runs * rounds * per_round:
            raise store.StoreError(f"{run_dir}: the stored records do not match config.json "
                                   f"({len(episodes)} episode rows for {runs} seeds x {n_episodes} episodes)")
        stored_seeds = tables.get("seeds", np.array([])).tolist()
        if stored_seeds != list(config.seeds) or meta["contents"].get("seeds") != list(config.seeds):
            raise store.StoreError(f"{run_dir}: the seeds of {rundir.QTABLES_FILE} and {rundir.META_FILE} differ from "
                                   f"those of {rundir.CONFIG_FILE}")
        order = {seed: position for position, seed in enumerate(config.seeds)}
        episodes = episodes.assign(run=episodes["seed"].map(order)).sort_values(["run", "episode"])
        evaluations = evaluations.assign(run=evaluations["seed"].map(order)).sort_values(["run", "round"],
                                                                                         kind="stable")
        records = Records(
            returns=episodes["return"].to_numpy().reshape(runs, n_episodes),
            lengths=episodes["length"].to_numpy().reshape(runs, n_episodes),
            terminated=episodes["terminated"].to_numpy().reshape(runs, n_episodes),
            eval_returns=evaluations["return"].to_numpy().reshape(runs, rounds, per_round),
            eval_lengths=evaluations["length"].to_numpy().reshape(runs, rounds, per_round),
            eval_terminated=evaluations["terminated"].to_numpy().reshape(runs, rounds, per_round),
            snapshots=tables["snapshots"],
            snapshot_episodes=tables["snapshot_episodes"],
            visits=tables["visits"],
        )
        return cls(config=config, epsilons=tables["epsilons"], records=records, meta=meta)


def _parquet_bytes(table: pa.Table) -> bytes:
    buffer = io.BytesIO()
    pq.write_table(table, buffer)
    return buffer.getvalue()


def _with_labels(columns: dict[str, np.ndarray], labels: dict[str, Any], rows: int) -> pa.Table:
    """The columns after the labels, each label one dictionary-encoded (categorical) column."""
    label_columns = {name: pa.DictionaryArray.from_arrays(np.zeros(rows, dtype=np.int32), pa.array([str(value)]))
                     for name, value in labels.items()}
    return pa.table({**label_columns, **columns})


def _tuples(data: dict[str, Any]) -> dict[str, Any]:
    """JSON lists back to the tuples of the frozen config."""
    if "stages" in data:
        data["stages"] = tuple(tuple(pair) for pair in data["stages"])
    if "seeds" in data:
        data["seeds"] = tuple(data["seeds"])
    return data
