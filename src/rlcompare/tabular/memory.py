"""What a tabular run's records take in memory, and the check that they fit before a run allocates them."""

from __future__ import annotations

import dataclasses

from rlcompare import machine
from rlcompare.tabular.config import ExperimentConfig, feature_count_of
from rlcompare.tabular.state import STREAMS
from rlcompare.validation import ConfigError


def records_parts(c: ExperimentConfig) -> dict[str, int]:
    """Bytes of the records a run of ``c`` allocates (:func:`rlcompare.tabular.state.allocate_records`, and the ε
    schedule), by what they grow with: ``episodes`` (returns float64, lengths int64, terminated bool per seed and
    episode; ε per episode), ``eval_episodes`` (the same per seed, evaluation round and evaluation episode) and
    ``features`` (snapshots float64 per seed, stage, feature and action; visits int64 per seed and feature; the
    snapshots' episodes)."""
    runs, per_episode = len(c.seeds), 8 + 8 + 1
    stages = len(c.stage_episodes())
    features = feature_count_of(c)
    return {
        "episodes": runs * c.episodes * per_episode + c.episodes * 8,
        "eval_episodes": runs * c.evaluation_rounds * c.eval_episodes * per_episode,
        "features": runs * stages * features * c.environment.n_actions * 8 + runs * features * 8 + stages * 8,
    }


def records_bytes(c: ExperimentConfig) -> int:
    """Bytes of the records a run of ``c`` allocates before its first episode."""
    return sum(records_parts(c).values())


def weights_bytes(c: ExperimentConfig) -> int:
    """Bytes of one seed's weights: a float64 a feature and action."""
    return feature_count_of(c) * c.environment.n_actions * 8


def training_bytes(c: ExperimentConfig) -> int:
    """Bytes a training of ``c`` takes: its records (:func:`records_bytes`), and each seed's weights and second
    estimates (:func:`rlcompare.tabular.state.initial_state`) and random streams."""
    return records_bytes(c) + len(c.seeds) * (2 * weights_bytes(c) + STREAMS * 4 * 8)


def run_bytes(c: ExperimentConfig) -> int:
    """Bytes the training of one seed of ``c`` takes."""
    return training_bytes(dataclasses.replace(c, seeds=c.seeds[:1]))


SEEDS_SHARE = 0.01
"""Where one seed's training takes less than this share of memory and all of them do not fit, the seeds are what
is too large, and the refusal names them."""


def check_memory(c: ExperimentConfig) -> None:
    """A training that fits in this machine's memory, refused before anything is allocated, naming the seeds where
    each is small and their number is what is too large, else the count that grows the records most. Called where
    a run starts (:func:`rlcompare.experiment.runner.run`) and where a study plans it, never when a configuration
    is made or loaded: validation reads nothing of the machine, so a run made on a bigger machine still loads
    here."""
    memory, needed = machine.physical_memory(), training_bytes(c)
    if needed <= memory:
        return
    one = run_bytes(c)
    if one < SEEDS_SHARE * memory:
        raise ConfigError("seeds", len(c.seeds), f"at most {memory // one:,} seeds, whose training fits in memory: "
                          f"{len(c.seeds):,} seeds need {machine.gib(needed)}; this machine has "
                          f"{machine.gib(memory)}")
    parts = records_parts(c)
    runs = f"{len(c.seeds):,} seeds"
    largest = max(parts, key=parts.__getitem__)
    value: int | tuple[int, ...]  # the field that grows the records most: a count, or the grid's bins
    if largest == "episodes":
        name, value, shape = "episodes", c.episodes, f"{runs} x {c.episodes:,} episodes"
    elif largest == "eval_episodes":
        name, value = "eval_episodes", c.eval_episodes
        shape = f"{runs} x {c.evaluation_rounds:,} evaluations x {c.eval_episodes:,} episodes"
    else:
        name, value = ("bins", c.grid_bins) if c.features == "grid" else ("tiles", c.tiles)
        features = feature_count_of(c)
        shape = (f"{runs} x {len(c.stage_episodes())} snapshots x {features:,} features x "
                 f"{c.environment.n_actions} actions")
    raise ConfigError(name, value, f"a run whose records fit in memory: {shape} need {machine.gib(needed)}; this "
                      f"machine has {machine.gib(memory)}")
