"""The tabular engine's front (:mod:`rlcompare.experiment.engines`): fused numba kernels over tables, tiles and
linear features, one :class:`~rlcompare.tabular.config.ExperimentConfig` at a time."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from rlcompare.tabular.agent import agent
from rlcompare.tabular.config import ExperimentConfig as Config
from rlcompare.tabular.memory import check_memory
from rlcompare.tabular.results import Results
from rlcompare.tabular.state import Records
from rlcompare.tabular.train import train

__all__ = ["FIXED_IN_SWEEP", "NESTED", "SWEEP_KEYS", "Config", "Results", "agent", "merge", "sweep_config", "train"]

SWEEP_KEYS = tuple(f.name for f in dataclasses.fields(Config) if f.name != "seeds")
"""What a sweep file may set: every field but the seeds, which the sweep sets once."""
NESTED = None
"""No table of its own in a sweep file (the deep engine's ``hyperparameters``)."""
FIXED_IN_SWEEP: dict[str, str] = {}
"""Fields a sweep may not set, with the reason."""


def sweep_config(values: dict[str, Any], seeds: tuple[int, ...]) -> Config:
    """One configuration of a sweep from the values its sections give and its seeds; records of all its seeds
    that would not fit in this machine's memory are refused here, where the sweep is about to run."""
    config = Config(**values, seeds=seeds)
    check_memory(config)
    return config


def merge(trials: list[Results]) -> Results:
    """One :class:`Results` from runs of one configuration on other seeds (a sweep's one-seed trials), the seeds
    in the order of ``trials``; timings summed."""
    first = trials[0]
    records = Records(*(np.concatenate([getattr(t.records, name) for t in trials])
                        if name != "snapshot_episodes" else first.records.snapshot_episodes
                        for name in Records._fields))
    seeds = tuple(seed for t in trials for seed in t.seeds)
    timings = {key: sum(t.meta["timings"][key] for t in trials)
               for key in ("wall_seconds", "training_steps", "evaluation_steps")}
    timings["threads"] = 1
    meta = {**first.meta, "seeds": list(seeds), "timings": timings}
    return Results(config=dataclasses.replace(first.config, seeds=seeds), epsilons=first.epsilons, records=records,
                   meta=meta)
