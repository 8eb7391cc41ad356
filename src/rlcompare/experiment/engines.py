"""The engines that train configurations into run directories: one record each, and the one function that finds a
configuration's engine (:func:`front`).

An engine's front is one module, imported only when a configuration of that engine is built, trained or loaded
(the deep one needs the ``deep`` extra). What it offers is :class:`EngineFront`; a type checker holds each front
to it. ``config.json`` names its engine (``"engine": "deep"``; a run written before engines were named is
tabular), so everything that reads a run directory, a sweep's trial or a trial shipped to a Ray worker asks this
registry which front reads it, and nothing in :mod:`rlcompare.experiment` imports an engine's internals.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, cast

import numpy as np

from rlcompare.experiment import rundir, store
from rlcompare.validation import UNIT, ConfigError, is_integer


class EngineFront(Protocol):
    """What an engine's front module offers: its configuration and results types, how it trains, merges seeds,
    makes an agent, and what a sweep file may set of its configurations."""

    @property
    def Config(self) -> type[Any]:
        """Its frozen configuration: ``to_dict()``, ``from_dict(data)``, ``seeds``, ``name``, ``progress_total``."""
        ...

    @property
    def Results(self) -> type[rundir.RunResults]:
        """What a run produces (:class:`~rlcompare.experiment.rundir.RunResults`)."""
        ...

    @property
    def SWEEP_KEYS(self) -> tuple[str, ...]:
        """What a sweep file may set."""
        ...

    @property
    def NESTED(self) -> str | None:
        """The table of a sweep file whose keys are nested settings (the deep engine's ``hyperparameters``)."""
        ...

    @property
    def FIXED_IN_SWEEP(self) -> Mapping[str, str]:
        """Fields a sweep may not set, with the reason."""
        ...

    def train(self, config: Any, *, study: str = "", progress: Callable[[int], None] | None = None) -> Any:
        """Every seed of ``config`` trained, in memory."""
        ...

    def merge(self, parts: list[Any]) -> Any:
        """One results of runs of one configuration on other seeds (a sweep's trials)."""
        ...

    def agent(self, results: Any, seed: int, stage: str = "final", env: Any = None) -> Any:
        """The greedy agent of one seed, acting in Gymnasium's environment (``env``'s actions, where given)."""
        ...

    def sweep_config(self, values: dict[str, Any], seeds: tuple[int, ...]) -> Any:
        """One configuration of a sweep from the values its sections give and its seeds."""
        ...


@dataclass(frozen=True)
class Engine:
    """One engine: its name (``config.json``'s ``engine``), its front's module, the extra that front needs."""

    name: str
    summary: str
    module: str
    extra: str = ""

    def front(self) -> EngineFront:
        """The engine's front, imported now; an :class:`ImportError` saying how to install a missing extra."""
        return cast(EngineFront, importlib.import_module(self.module))


ENGINES = {engine.name: engine for engine in (
    Engine("tabular", "numba kernels over tables, tiles and linear features", "rlcompare.tabular.front"),
    Engine("deep", "JAX networks: PQN Q(λ), SARSA(λ), DQN, PPO", "rlcompare.deep.front", extra="deep"),
)}
DEFAULT = "tabular"
"""The engine of a configuration that names none (every run written before the deep engine)."""


def engine(name: Any) -> Engine:
    """The engine called ``name``; a :class:`ConfigError` naming the engines there are."""
    if not isinstance(name, str) or name not in ENGINES:
        raise ConfigError("engine", name, ", ".join(ENGINES))
    return ENGINES[name]


def front(config: Any) -> EngineFront:
    """The front of the engine of ``config``: a configuration (its class names the engine) or the dictionary of
    one (its ``engine`` key; none: :data:`DEFAULT`)."""
    name = config.get("engine", DEFAULT) if isinstance(config, dict) else type(config).engine
    return engine(name).front()


def config_from_dict(data: dict[str, Any]) -> Any:
    """The configuration a ``config.json`` (or a trial shipped to a worker) holds, in its engine's class."""
    return front(data).Config.from_dict(data)


def load_run(run_dir: Path, expected: Any = None) -> Any:
    """A finished run directory of any engine, checked on load (:func:`~rlcompare.experiment.rundir.read_run`):
    a file that does not belong to the run is a :class:`~rlcompare.experiment.store.StoreError` naming it."""
    config = store.read_json(Path(run_dir) / rundir.CONFIG_FILE) if expected is None else expected.to_dict()
    if not isinstance(config, dict):
        raise store.StoreError(f"{Path(run_dir) / rundir.CONFIG_FILE}: not a configuration rlcompare wrote")
    try:
        results = front(config).Results
    except ConfigError as error:
        raise store.StoreError(f"{Path(run_dir) / rundir.CONFIG_FILE}: {error}") from None
    return rundir.read_results(Path(run_dir), results, expected)


def load_if_complete(run_dir: Path, config: Any, load: Callable[..., Any] | None = None) -> Any | None:
    """The stored results of ``config`` in ``run_dir`` if that run finished and its files belong together, else
    None (so it is trained again). ``load``: a study's own reader (``load(run_dir, expected=config)``) in place of
    the engine's."""
    reader = load or load_run
    if not (Path(run_dir) / rundir.META_FILE).is_file():  # written last: no meta.json, no finished run
        return None
    try:
        return reader(run_dir, expected=config)
    except store.StoreError:
        return None


def load_agent(run_dir: Path, seed: int | None = None, stage: str = "final", epsilon: float = 0.0,
               exploration_seed: int = 0, env: Any = None) -> Any:
    """The agent of ``seed`` (default: the run's first) at ``stage`` of a finished run directory of any engine,
    ready for ``gymnasium.make`` of the run's environment: ``agent.act(observation) -> action``. Greedy where
    ``epsilon`` is 0; otherwise ε-greedy as an evaluation plays (:class:`EpsilonGreedy`, Mnih et al. 2015's
    ε = 0.05 on the Atari 2600), its draws from ``exploration_seed``. Given ``env`` (a Gymnasium environment), its
    actions are ``env``'s, checked: an Atari agent plays an ``ALE/<Game>-v5`` on Gymnasium's minimal action set."""
    owner = store.owner_of(Path(run_dir))
    if owner is not None and owner != store.RUN:
        runs = sorted(p.name for p in Path(run_dir).iterdir() if store.owner_of(p) == store.RUN)
        raise store.StoreError(f"{run_dir}: holds {owner}, not one run; allowed: one of its run directories "
                               f"({', '.join(runs) or 'none finished'})")
    if seed is not None and not is_integer(seed):
        raise ConfigError("seed", seed, "an integer, one of the run's seeds")
    if not UNIT.holds(epsilon):
        raise ConfigError("epsilon", epsilon, UNIT.allowed)
    if not is_integer(exploration_seed) or exploration_seed < 0:
        raise ConfigError("exploration_seed", exploration_seed, "an integer >= 0")
    results = load_run(Path(run_dir))
    try:
        greedy = front(results.config).agent(results, results.seeds[0] if seed is None else int(seed), stage, env)
    except ConfigError:  # an ``env`` the agent cannot act in
        raise
    except ValueError as error:  # stored arrays that are not the method's (a run of another version)
        raise store.StoreError(f"{Path(run_dir)}: {error}") from None
    if epsilon == 0:
        return greedy
    if not hasattr(greedy, "act"):
        raise ConfigError("epsilon", epsilon, "0 for an agent that plays chess boards (its move is the greedy one)")
    n_actions = results.config.environment.n_actions if env is None else int(env.action_space.n)
    return EpsilonGreedy(greedy, float(epsilon), n_actions, np.random.default_rng(int(exploration_seed)))


@dataclass
class EpsilonGreedy:
    """``greedy``'s policy with a uniform random action at probability ``epsilon``. Each step draws ``u`` and then
    a uniform action from ``rng``, whether it explores or not, and takes that action where ``u < epsilon``: one
    episode's actions depend on its seed, not on the network's choices (Mnih et al. 2015's ε-greedy evaluation)."""

    greedy: Any
    epsilon: float
    n_actions: int
    rng: np.random.Generator

    def act(self, observation: Any) -> int:
        explore, random_action = self.rng.random(), int(self.rng.integers(self.n_actions))
        return random_action if explore < self.epsilon else int(self.greedy.act(observation))


if TYPE_CHECKING:  # each front satisfies the contract (checked by the type checker, imported by nothing)
    from rlcompare.deep import front as _deep_front
    from rlcompare.tabular import front as _tabular_front

    _FRONTS: tuple[EngineFront, ...] = (_tabular_front, _deep_front)
