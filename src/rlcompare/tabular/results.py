"""What a tabular run produces: the records of every seed with its configuration, and the files its run directory
holds (written and read by :mod:`rlcompare.experiment.rundir`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
import pandas as pd

from rlcompare.tabular.config import ExperimentConfig
from rlcompare.tabular.state import Records

Columns = dict[str, np.ndarray]


@dataclass
class Results:
    """Records of every seed of one configuration, with the configuration and how the run went."""

    arrays_file: ClassVar[str] = "qtables.npz"
    """The run directory's file of arrays: Q-tables at the stages, visits, seeds and ε per episode."""

    config: ExperimentConfig
    epsilons: np.ndarray
    """(episodes,) ε of each episode."""
    records: Records
    meta: dict[str, Any]
    """Versions, timings, command line, study name."""

    @property
    def seeds(self) -> tuple[int, ...]:
        return self.config.seeds

    def labels(self) -> dict[str, str]:
        """The columns every row of its tables carries: study, environment, algorithm and schedule."""
        c = self.config
        schedule = "none" if c.algorithm == "random" else c.schedule
        return {"study": self.meta.get("study", ""), "env": c.env, "algorithm": c.algorithm, "schedule": schedule}

    def episodes(self) -> pd.DataFrame:
        """Long table: one row per seed x episode, as ``episodes.parquet`` holds it."""
        return _labelled(self.labels(), self.columns()["episodes"])

    def evaluations(self) -> pd.DataFrame:
        """Long table: one row per seed x evaluation round x greedy episode, as ``evaluations.parquet`` holds it."""
        return _labelled(self.labels(), self.columns()["evaluations"])

    def columns(self) -> dict[str, Columns]:
        """The columns of its tables beside the labels: ``episodes`` and ``evaluations``."""
        return {"episodes": self._episode_columns(), "evaluations": self._evaluation_columns()}

    def _episode_columns(self) -> Columns:
        runs, episodes = self.records.returns.shape
        return {
            "seed": np.repeat(np.asarray(self.seeds, dtype=np.int64), episodes),
            "episode": np.tile(np.arange(episodes, dtype=np.int64), runs),
            "epsilon": np.tile(self.epsilons, runs),
            "return": self.records.returns.ravel(),
            "length": self.records.lengths.ravel(),
            "terminated": self.records.terminated.ravel(),
        }

    def _evaluation_columns(self) -> Columns:
        runs, rounds, per_round = self.records.eval_returns.shape
        return {
            "seed": np.repeat(np.asarray(self.seeds, dtype=np.int64), rounds * per_round),
            "round": np.tile(np.repeat(np.arange(rounds, dtype=np.int64), per_round), runs),
            "after_episode": np.tile(np.repeat((np.arange(rounds, dtype=np.int64) + 1)
                                               * self.config.eval_every, per_round), runs),
            "return": self.records.eval_returns.ravel(),
            "length": self.records.eval_lengths.ravel(),
            "terminated": self.records.eval_terminated.ravel(),
        }

    def arrays(self) -> dict[str, np.ndarray]:
        """What :attr:`arrays_file` holds."""
        return {"snapshots": self.records.snapshots, "snapshot_episodes": self.records.snapshot_episodes,
                "visits": self.records.visits, "seeds": np.asarray(self.seeds), "epsilons": self.epsilons}

    def record(self) -> dict[str, Any]:
        """What the run holds, for ``meta.json``: its seeds, rows and the shapes of its arrays."""
        rows = {"episodes": int(self.records.returns.size), "evaluations": int(self.records.eval_returns.size)}
        return {"seeds": list(self.seeds), "rows": rows,
                "arrays": {name: list(getattr(self.records, name).shape) for name in ("snapshots", "visits")}}

    def q_table(self, seed: int, stage: str = "final") -> np.ndarray:
        """The Q-table of one seed at a named stage, ``(cells, actions)``."""
        stages = [name for name, _ in self.config.stages]
        if seed not in self.seeds:
            raise KeyError(f"seed {seed} is not in this run; seeds: {list(self.seeds)}")
        if stage not in stages:
            raise KeyError(f"stage {stage!r} is not in this run; stages: {stages}")
        table: np.ndarray = self.records.snapshots[self.seeds.index(seed), stages.index(stage)]
        return table

    @classmethod
    def read_config(cls, stored: dict[str, Any], expected: ExperimentConfig | None) -> ExperimentConfig:
        """The configuration ``config.json`` holds; a :class:`ValueError` where it is not one, or not
        ``expected``."""
        if expected is not None and stored != expected.to_dict():
            raise ValueError("another configuration than the one asked for")
        return ExperimentConfig.from_dict(_tuples(stored))

    @classmethod
    def from_files(cls, config: ExperimentConfig, episodes: pd.DataFrame, evaluations: pd.DataFrame,
                   arrays: dict[str, np.ndarray], meta: dict[str, Any]) -> Results:
        """The results a run directory's files hold, read back without training; a :class:`ValueError` where they
        do not belong to ``config``."""
        runs, n_episodes = len(config.seeds), config.episodes
        rounds, per_round = config.evaluation_rounds, config.eval_episodes
        if len(episodes) != runs * n_episodes or len(evaluations) != runs * rounds * per_round:
            raise ValueError(f"the stored records do not match config.json ({len(episodes)} episode rows for {runs} "
                             f"seeds x {n_episodes} episodes)")
        stored_seeds = arrays.get("seeds", np.array([])).tolist()
        if stored_seeds != list(config.seeds) or meta["contents"].get("seeds") != list(config.seeds):
            raise ValueError(f"the seeds of {cls.arrays_file} and meta.json differ from those of config.json")
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
            snapshots=arrays["snapshots"],
            snapshot_episodes=arrays["snapshot_episodes"],
            visits=arrays["visits"],
        )
        return cls(config=config, epsilons=arrays["epsilons"], records=records, meta=meta)


def _labelled(labels: dict[str, str], columns: Columns) -> pd.DataFrame:
    """The columns after the labels, each label a categorical column of one value."""
    rows = len(next(iter(columns.values())))
    return pd.DataFrame({**{name: pd.Categorical.from_codes(np.zeros(rows, np.int32), pd.Index([value]))
                            for name, value in labels.items()}, **columns})


def _tuples(data: dict[str, Any]) -> dict[str, Any]:
    """JSON lists back to the tuples of the frozen config."""
    data = dict(data)
    if "stages" in data:
        data["stages"] = tuple(tuple(pair) for pair in data["stages"])
    if "seeds" in data:
        data["seeds"] = tuple(data["seeds"])
    return data
