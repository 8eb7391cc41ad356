"""What a tabular run's records take in memory, and the check that they fit before a run allocates them."""

from __future__ import annotations

from rlcompare import machine
from rlcompare.tabular.config import ExperimentConfig, feature_count_of
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


def check_memory(c: ExperimentConfig) -> None:
    """Records that fit in this machine's memory, refused before anything is allocated. Called where a run
    starts (:func:`rlcompare.experiment.runner.run`), never when a configuration is made or loaded: validation
    reads nothing of the machine, so a run made on a bigger machine still loads here."""
    parts, memory = records_parts(c), machine.physical_memory()
    needed = sum(parts.values())
    if needed <= memory:
        return
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
