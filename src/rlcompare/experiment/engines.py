"""The engines that train configurations into run directories: one record each.

An engine's front is one module, imported only when a configuration of that engine is built, trained or loaded
(the deep one needs the ``deep`` extra). It offers:

| name | what |
|---|---|
| ``Config`` | its frozen configuration: ``to_dict()``, ``from_dict(data)``, ``seeds``, ``name``, ``progress_total`` |
| ``Results`` | what a run produces: ``save(run_dir)``, ``load(run_dir, expected=None)``, ``seeds``, ``meta`` |
| ``run(config, *, out=None, study="", progress=None)`` | train every seed; write ``out`` where given |
| ``merge(parts)`` | one ``Results`` from runs of one configuration on other seeds (a sweep's trials) |
| ``agent(results, seed, stage)`` | the greedy agent of one seed, acting in Gymnasium's environment |
| ``SWEEP_KEYS``, ``NESTED``, ``FIXED_IN_SWEEP``, ``sweep_config(values, seeds)`` | what a sweep file may set |

``config.json`` names its engine (``"engine": "deep"``; a run written before engines were named is tabular), so
everything that reads a run directory, a sweep's trial or a trial shipped to a Ray worker asks this registry
which front reads it, and nothing in :mod:`rlcompare.experiment` imports an engine's internals.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any

from rlcompare.experiment import rundir, store
from rlcompare.experiment.config import ConfigError


@dataclass(frozen=True)
class Engine:
    """One engine: its name (``config.json``'s ``engine``), its front's module, the extra that front needs."""

    name: str
    summary: str
    module: str
    extra: str = ""

    def front(self) -> ModuleType:
        """The engine's front, imported now; an :class:`ImportError` saying how to install a missing extra."""
        return importlib.import_module(self.module)


ENGINES = {engine.name: engine for engine in (
    Engine("tabular", "numba kernels over tables, tiles and linear features", "rlcompare.experiment.tabular"),
    Engine("deep", "JAX networks: PQN Q(λ), SARSA(λ), DQN, PPO", "rlcompare.deep.engine", extra="deep"),
)}
DEFAULT = "tabular"
"""The engine of a configuration that names none (every run written before the deep engine)."""


def engine(name: Any) -> Engine:
    """The engine called ``name``; a :class:`ConfigError` naming the engines there are."""
    if not isinstance(name, str) or name not in ENGINES:
        raise ConfigError("engine", name, ", ".join(ENGINES))
    return ENGINES[name]


def front_of(data: dict) -> ModuleType:
    """The front of the engine a configuration's dictionary names."""
    return engine(data.get("engine", DEFAULT)).front()


def front_for(config: Any) -> ModuleType:
    """The front of the engine that trains ``config`` (its class says which)."""
    return engine(type(config).engine).front()


def config_from_dict(data: dict) -> Any:
    """The configuration a ``config.json`` (or a trial shipped to a worker) holds, in its engine's class."""
    return front_of(data).Config.from_dict(data)


def train(config: Any, *, out: Path | None = None, study: str = "", progress: Callable[[int], None] | None = None
          ) -> Any:
    """Train every seed of ``config`` on its engine; write the run directory ``out`` where given."""
    return front_for(config).run(config, out=out, study=study, progress=progress)


def load_run(run_dir: Path, expected: Any = None) -> Any:
    """A finished run directory of any engine, checked on load (:func:`~rlcompare.experiment.rundir.read_run`):
    a file that does not belong to the run is a :class:`~rlcompare.experiment.store.StoreError` naming it."""
    config = store.read_json(Path(run_dir) / rundir.CONFIG_FILE) if expected is None else expected.to_dict()
    if not isinstance(config, dict):
        raise store.StoreError(f"{Path(run_dir) / rundir.CONFIG_FILE}: not a configuration rlcompare wrote")
    try:
        results = front_of(config).Results
    except ConfigError as error:
        raise store.StoreError(f"{Path(run_dir) / rundir.CONFIG_FILE}: {error}") from None
    return results.load(run_dir, expected=expected)


def load_if_complete(run_dir: Path, config: Any, load: Callable[..., Any] | None = None) -> Any | None:
    """The stored results of ``config`` in ``run_dir`` if that run finished and its files belong together, else
    None (so it is trained again). ``load``: a study's own reader in place of the engine's ``Results.load``."""
    reader = load or front_for(config).Results.load
    if not (Path(run_dir) / rundir.META_FILE).is_file():  # written last: no meta.json, no finished run
        return None
    try:
        return reader(run_dir, expected=config)
    except store.StoreError:
        return None


def load_agent(run_dir: Path, seed: int | None = None, stage: str = "final") -> Any:
    """The greedy agent of ``seed`` (default: the run's first) at ``stage`` of a finished run directory of any
    engine, ready for ``gymnasium.make`` of the run's environment: ``agent.act(observation) -> action``."""
    results = load_run(Path(run_dir))
    return front_for(results.config).agent(results, results.seeds[0] if seed is None else seed, stage)
