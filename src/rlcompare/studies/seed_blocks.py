"""A study's deep configurations trained as tasks of a backend (a Ray cluster), a block of seeds each.

A seed's numbers depend on the vmap width it trains at, not on the seeds beside it (``docs/deep.md``), so a
configuration cut into blocks of ``vmap_width`` seeds trains each block as it would in one program of the whole,
and the merged blocks equal the whole. A configuration is written when its last block is back, so a study
interrupted loses only the configurations it had not finished.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Protocol

from rlcompare.deep.config import DeepConfig
from rlcompare.deep.results import DeepResults, merge_seeds
from rlcompare.experiment import engines, rundir, store
from rlcompare.experiment.backends import OnDone
from rlcompare.experiment.sweep import Trial


class Backend(Protocol):
    """Where the tasks run (:mod:`rlcompare.experiment.backends`), connected."""

    def run(self, trials: Iterable[Trial], on_done: OnDone) -> None: ...


def seed_blocks(config: DeepConfig) -> list[DeepConfig]:
    """``config`` cut into blocks of ``vmap_width`` seeds."""
    width = config.vmap_width
    return [dataclasses.replace(config, seeds=config.seeds[first:first + width])
            for first in range(0, len(config.seeds), width)]


def trained_on(backend: Backend, out: Path, study: str, configs: dict[str, DeepConfig], *,
               progress: Callable[[int], None] | None = None, force: bool = False
               ) -> Iterator[tuple[str, DeepResults, bool]]:
    """Every configuration ``out`` lacks as tasks of ``backend``; ``(name, results, reused)`` for each, those
    ``out`` holds first."""
    with store.output_directory(out, store.Owner("study", study), force=force):
        yield from _trained_on(backend, out, configs, progress)


def _trained_on(backend: Backend, out: Path, configs: dict[str, DeepConfig], progress: Callable[[int], None] | None
                ) -> Iterator[tuple[str, DeepResults, bool]]:
    trials: list[Trial] = []
    blocks: dict[str, list[DeepResults | None]] = {}
    finished: list[tuple[str, DeepResults]] = []
    for name, config in configs.items():
        stored = engines.load_if_complete(out / name, config)
        if stored is not None:
            if progress is not None:
                progress(config.progress_total)
            rundir.enter_members(out, [name])
            yield name, stored, True
            continue
        parts = seed_blocks(config)
        blocks[name] = [None for _ in parts]
        trials += [Trial(part, name, index) for index, part in enumerate(parts)]

    def save(trial: Trial, results: DeepResults) -> None:
        parts = blocks[trial.config_hash]
        parts[trial.seed_index] = results
        if progress is not None:
            progress(len(results.seeds))
        if all(part is not None for part in parts):
            merged = merge_seeds([part for part in parts if part is not None])
            with store.output_directory(out / trial.config_hash, store.RUN):
                rundir.write_results(out / trial.config_hash, merged)
            rundir.enter_members(out, [trial.config_hash])
            finished.append((trial.config_hash, merged))

    backend.run(trials, save)
    for name, results in finished:
        yield name, results, False
