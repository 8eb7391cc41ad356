"""A sweep: a grid of configurations over many seeds, read from a TOML file and validated before anything runs.

The file's tables (``[sweep]``, ``[fixed]``, ``[grid]``, ``[[include]]``) and keys, for the tabular engine and
for ``engine = "deep"`` (whose JAX is imported only then), are in ``docs/sweeps.md``. A trial is one configuration
with one seed, the unit the backends run and the store keeps. The seeds are
``np.random.SeedSequence(root_seed).spawn(seeds)``, each child's first 63 bits: they depend on the root seed and
the seed's index alone, and every configuration gets the same ones, so configurations are compared on common random
numbers. Every mistake in the file is reported at once, each with the key's path and what is allowed
(:class:`SweepError`); nothing runs until the whole sweep is valid.
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
import math
import re
import sys
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

from rlcompare.experiment.engines import ENGINES
from rlcompare.formatting import cut, quote
from rlcompare.validation import ConfigError, Integer, UnknownKey

if TYPE_CHECKING:
    from rlcompare.experiment.engines import EngineFront

SECTIONS = ("sweep", "fixed", "grid", "include")
SWEEP_KEYS = ("name", "root_seed", "seeds", "engine")
MAX_TRIALS = 100_000
NAME = re.compile(r"[A-Za-z0-9_-][A-Za-z0-9._-]{0,99}")
"""A sweep's name: one directory name (the default store is runs/sweeps/NAME), never a path."""
HYPERPARAMETERS = "hyperparameters."


class SweepError(ValueError):
    """Every problem of a sweep file, one line each, naming the key's path and what is allowed."""

    def __init__(self, source: str, problems: list[str]) -> None:
        self.source, self.problems = source, problems
        super().__init__(f"{source}: {len(problems)} problem{'s' if len(problems) > 1 else ''}\n"
                         + "\n".join(f"  {p}" for p in problems))


@dataclass(frozen=True)
class Trial:
    """One configuration with one seed."""

    config: Any
    """The configuration, with ``seeds`` the one seed of this trial."""
    config_hash: str
    """Identifies the configuration apart from its seeds."""
    seed_index: int

    @property
    def seed(self) -> int:
        return int(self.config.seeds[0])

    @property
    def trial_id(self) -> str:
        return f"{self.config_hash}-{self.seed}"


@dataclass(frozen=True)
class _Built:
    """A valid configuration of the file, with where it came from."""

    config: Any
    where: str
    """``grid`` or ``include[k]``."""
    values: dict[str, Any]
    origin: dict[str, str]
    """The path of each value given: ``fixed.alpha``, ``grid.alpha[1]``, ``include[0].alpha``."""


@dataclass(frozen=True)
class Sweep:
    """The configurations of a sweep and the seeds each one runs."""

    name: str
    root_seed: int
    seeds: tuple[int, ...]
    configs: tuple[Any, ...]
    """Each with ``seeds`` set to the sweep's seeds, in the order of the file: [grid] then [[include]]."""
    swept: tuple[str, ...]
    """The keys whose value differs between configurations (:func:`swept_value`)."""
    engine: str = "tabular"
    """``tabular`` (configurations are ExperimentConfigs) or ``deep`` (DeepConfigs, ``vmap_width`` 1)."""

    def trials(self) -> list[Trial]:
        """Every configuration with every seed, seed by seed, so that the first finished trials already
        cover every configuration."""
        hashes = [config_hash(c) for c in self.configs]
        return [Trial(dataclasses.replace(c, seeds=(seed,)), h, k)
                for k, seed in enumerate(self.seeds) for c, h in zip(self.configs, hashes, strict=True)]


def config_hash(config: Any) -> str:
    """A short hash of every field of the configuration but its seeds (a deep one's ``engine`` and resolved
    hyperparameters included)."""
    fields = {k: v for k, v in config.to_dict().items() if k != "seeds"}
    return hashlib.sha256(json.dumps(fields, sort_keys=True).encode()).hexdigest()[:16]


def config_dict(config: Any) -> dict[str, Any]:
    """The configuration as its trial's ``config.json`` holds it (JSON's lists for tuples)."""
    data: dict[str, Any] = json.loads(json.dumps(config.to_dict()))
    return data


def swept_value(config: Any, key: str) -> Any:
    """A configuration's value of a sweep key: its field, or for ``hyperparameters.NAME`` the value the deep method
    runs with (the preset's where the sweep does not set it; None where the method has no such field)."""
    if key.startswith(HYPERPARAMETERS):
        return getattr(config.method_config(), key.removeprefix(HYPERPARAMETERS), None)
    return getattr(config, key)


def derive_seeds(root_seed: int, count: int) -> tuple[int, ...]:
    """``count`` run seeds from ``SeedSequence(root_seed).spawn(count)``, each below 2**63."""
    import numpy as np

    children = np.random.SeedSequence(root_seed).spawn(count)
    return tuple(int(child.generate_state(1, np.uint64)[0] >> np.uint64(1)) for child in children)


def load_sweep(path: Path) -> Sweep:
    """Read and validate a sweep file."""
    path = Path(path)
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as error:
        raise SweepError(str(path), [f"cannot read the file ({error})"]) from None
    return parse_sweep(text, str(path))


def parse_sweep(text: str, source: str = "<sweep>") -> Sweep:
    """Validate a sweep given as TOML text; :class:`SweepError` lists every problem."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise SweepError(source, [f"not valid TOML: {error}"]) from None
    problems: list[str] = []
    for section in data:
        if section not in SECTIONS:
            problems.append(f"{cut(section, 80)}: unknown section; allowed: {', '.join(SECTIONS)}")
    if not data.get("grid") and not data.get("include"):
        problems.append("grid: empty; allowed: at least one [grid] list or one [[include]] table")
    name, root_seed, count, engine_name = _header(_table(data, "sweep", problems), problems)
    engine = _engine(engine_name, problems)
    if engine is None or engine_name is None:  # the keys of an unknown or unavailable engine cannot be checked
        raise SweepError(source, problems)
    fixed = _known("fixed", _table(data, "fixed", problems), engine, problems)
    grid = _known("grid", _table(data, "grid", problems), engine, problems)
    includes = [_known(f"include[{k}]", include, engine, problems)
                for k, include in enumerate(_includes(data, problems))]
    for key in list(grid):
        if not isinstance(grid[key], list) or not grid[key]:
            problems.append(f"grid.{cut(key, 80)}: got {quote(grid.pop(key))}; allowed: a non-empty list of values")
        elif key in fixed:
            problems.append(f"grid.{cut(key, 80)}: also in [fixed]; allowed: one place for each key")
            del grid[key]
    n_configs = (math.prod(len(values) for values in grid.values()) if grid or not includes else 0) + len(includes)
    if n_configs * count > MAX_TRIALS:
        problems.append(f"grid: {n_configs:,} configurations x {count:,} seeds; allowed: at most {MAX_TRIALS:,} "
                        "trials")
        raise SweepError(source, problems)
    seeds = derive_seeds(root_seed, count)
    at_fixed = {key: f"fixed.{key}" for key in fixed}
    sources = [_combinations(fixed, grid)] if grid or not includes else []
    sources.append([(f"include[{k}]", {**fixed, **include},
                     {**at_fixed, **{key: f"include[{k}].{key}" for key in include}})
                    for k, include in enumerate(includes)])
    built = _configs(itertools.chain.from_iterable(sources), seeds, engine.sweep_config, problems)
    problems.extend(_duplicates(built))
    configs = [b.config for b in built]
    if problems:
        raise SweepError(source, list(dict.fromkeys(problems)))
    given = dict.fromkeys([*grid, *(key for include in includes for key in include)])
    order = [*engine.SWEEP_KEYS, *(key for key in given if key not in engine.SWEEP_KEYS)]  # then nested keys
    swept = tuple(key for key in order
                  if key in given and len({json.dumps(swept_value(c, key)) for c in configs}) > 1)
    return Sweep(name, root_seed, seeds, tuple(configs), swept, engine_name)


def _engine(name: str | None, problems: list[str]) -> EngineFront | None:
    """The front of the engine named in [sweep] (:mod:`rlcompare.experiment.engines`); None, with the problem
    reported, where it is unknown or not installed."""
    if name not in ENGINES:
        return None
    try:
        return ENGINES[name].front()
    except ImportError as error:  # rlcompare.deep.DeepUnavailable: JAX, flax or optax is missing
        problems.append(f"sweep.engine: {error}")
    return None


def _known(section: str, table: dict[str, Any], engine: EngineFront, problems: list[str]) -> dict[str, Any]:
    """The table's configuration keys (the engine's nested table, a deep sweep's ``hyperparameters``, flattened
    to ``hyperparameters.NAME``); every other key reported."""
    nested = engine.NESTED
    known: dict[str, Any] = {}
    for key, value in table.items():
        if key == "seeds":
            problems.append(f"{section}.seeds: the seeds are set once, in [sweep] (seeds = N)")
        elif key in engine.FIXED_IN_SWEEP:
            problems.append(f"{section}.{key}: {engine.FIXED_IN_SWEEP[key]}")
        elif nested and key == nested:
            if isinstance(value, dict):
                known.update({f"{nested}.{name}": item for name, item in value.items()})
            else:
                problems.append(f"{section}.{nested}: got {quote(value)}; allowed: a table of the method's "
                                f"{nested} ({nested}.NAME = ...)")
        elif key in engine.SWEEP_KEYS:
            known[key] = value
        else:
            allowed = ", ".join([*engine.SWEEP_KEYS, *([f"{nested}.NAME"] if nested else [])])
            problems.append(f"{section}.{cut(key, 80)}: unknown key; allowed: {allowed}")
    return known


def _table(data: dict[str, Any], section: str, problems: list[str]) -> dict[str, Any]:
    value = data.get(section, {})
    if not isinstance(value, dict):
        problems.append(f"{section}: got {quote(value)}; allowed: a table ([{section}])")
        return {}
    return value


def _includes(data: dict[str, Any], problems: list[str]) -> list[dict[str, Any]]:
    value = data.get("include", [])
    if not isinstance(value, list) or not all(isinstance(item, dict) for item in value):
        problems.append(f"include: got {quote(value)}; allowed: tables ([[include]])")
        return []
    return value


def _header(header: dict[str, Any], problems: list[str]) -> tuple[str, int, int, str | None]:
    """Name, root seed, seeds per configuration and engine; a bad value is reported and replaced by its default
    (an unknown engine by None)."""
    for key in header:
        if key not in SWEEP_KEYS:
            problems.append(f"sweep.{cut(key, 80)}: unknown key; allowed: {', '.join(SWEEP_KEYS)}")
    name = header.get("name", "sweep")
    if not is_sweep_name(name):
        problems.append(f"sweep.name: got {quote(name)}; allowed: a single directory name of letters, digits, "
                        "'.', '_' and '-' (at most 100 characters, not starting with '.')")
        name = "sweep"
    root_seed = header.get("root_seed", 0)
    if not Integer(0, 2**63 - 1).holds(root_seed):
        problems.append(f"sweep.root_seed: got {quote(root_seed)}; allowed: an integer in [0, 2**63)")
        root_seed = 0
    count = header.get("seeds", 10)
    if not Integer(1, MAX_TRIALS).holds(count):
        problems.append(f"sweep.seeds: got {quote(count)}; allowed: an integer in [1, {MAX_TRIALS:,}] (seeds per "
                        "configuration)")
        count = 1
    engine = header.get("engine", "tabular")
    if engine not in ENGINES:
        problems.append(f"sweep.engine: got {quote(engine)}; allowed: {', '.join(ENGINES)}")
        engine = None
    return name, root_seed, count, engine


def is_sweep_name(name: Any) -> bool:
    """Whether ``name`` is one safe directory name: ASCII letters, digits, '.', '_', '-', at most 100
    characters, not starting with '.' (so neither '.' nor '..', and never a path)."""
    return isinstance(name, str) and NAME.fullmatch(name) is not None


def _combinations(fixed: dict[str, Any], grid: dict[str, Any]) -> list[tuple[str, dict[str, Any], dict[str, str]]]:
    """Every combination of the grid over the fixed values, with the path each value came from."""
    keys = list(grid)
    out = []
    for indices in itertools.product(*(range(len(grid[key])) for key in keys)):
        values = {key: grid[key][i] for key, i in zip(keys, indices, strict=True)}
        origin = {**{key: f"fixed.{key}" for key in fixed},
                  **{key: f"grid.{key}[{i}]" for key, i in zip(keys, indices, strict=True)}}
        out.append(("grid", {**fixed, **values}, origin))
    return out


def _configs(sources: Iterable[tuple[str, dict[str, Any], dict[str, str]]], seeds: tuple[int, ...],
             build: Callable[[dict[str, Any], tuple[int, ...]], Any], problems: list[str]) -> list[_Built]:
    """The valid configurations; every problem of the others, each reported once.

    A configuration stops at its first bad value, so each bad value is set back to its default and the rest
    checked again, until none is left. A problem that a value has in every configuration it is part of is
    reported at its path alone; one that depends on the other values names the first combination it has.
    Configurations valid only with a value set back are not returned."""
    built: list[_Built] = []
    failures: dict[str, tuple[str, list[str]]] = {}  # problem -> its path, and the other values of each that had it
    appearances: dict[str, int] = {}
    for where_from, given, origin in sources:
        for path in origin.values():
            appearances[path] = appearances.get(path, 0) + 1
        values = dict(given)
        for _ in range(len(values) + 1):
            try:
                config = build(values, seeds)
                if values == given:
                    built.append(_Built(config, where_from, given, origin))
                break
            except ConfigError as error:
                where = origin.get(error.field_name, f"{error.field_name} (default)")
                message = (f"{cut(where.split('[')[0], 200)}: unknown key; allowed: {error.allowed}"
                           if isinstance(error, UnknownKey) else
                           f"{cut(where, 200)}: got {quote(error.value)}; allowed: {error.allowed}")
                context = ", ".join(f"{cut(k, 80)} = {quote(values[k])}" for k, path in origin.items()
                                    if k != error.field_name and not path.startswith("fixed.") and k in values)
                failures.setdefault(message, (where, []))[1].append(context)
                if error.field_name not in values:
                    break
                del values[error.field_name]
    for message, (where, contexts) in failures.items():
        everywhere = len(contexts) >= appearances.get(where, 0) or not contexts[0]
        problems.append(message if everywhere else f"{message} (with {contexts[0]})")
    return built


def _duplicates(built: list[_Built]) -> list[str]:
    """One problem for each configuration equal (the same hash) to an earlier one, naming both."""
    first: dict[str, _Built] = {}
    problems = []
    for item in built:
        earlier = first.setdefault(config_hash(item.config), item)
        if earlier is not item:
            problems.append(f"{_label(item, earlier)}: the same configuration as {_label(earlier, item)}; "
                            "allowed: each configuration once")
    return problems


def _label(item: _Built, other: _Built) -> str:
    """Where a configuration comes from, told apart from ``other``: its grid paths that ``other`` lacks, or
    ``grid (key = value, ...)`` beside an include, or ``include[k]``."""
    if item.where != "grid":
        return item.where
    at_grid = {key: path for key, path in item.origin.items() if path.startswith("grid.")}
    if other.where == "grid":
        differing = [path for path in at_grid.values() if path not in other.origin.values()]
        return ", ".join(differing) or "grid"
    return f"grid ({', '.join(f'{key} = {quote(item.values[key])}' for key in at_grid)})" if at_grid else "grid"
