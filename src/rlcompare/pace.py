"""How fast each training ran on this machine, kept so that a plan can say how long a study will take before it
trains (``rlcompare reproduce STUDY --plan``).

Every training that finishes enters a measurement here (:func:`record`) under a key naming its engine, environment,
configuration and settings but its amounts (:func:`key`): the units each seed trained (episodes, environment
steps), the seconds one seed took for them on one thread, and the seconds its compile took, with whether it
compiled afresh or loaded its compiled code from the cache. They are kept in ``pace.json`` in rlcompare's cache
directory (:func:`rlcompare.machine.cache_root`), up to :data:`KEPT_SIZES` sizes a key, a measurement replacing the
one of about its size (within :data:`SAME_SIZE`). A plan's estimate of a training of ``seeds`` seeds x ``M`` units
on ``threads`` threads (:meth:`Pace.seconds`) is its compile plus ``seeds / threads`` times one seed's seconds at
``M`` units, read from the sizes measured:

- between two sizes measured, on the straight line between them in log(seconds) against log(units): a seed's
  time is not proportional to its units, since episodes shorten (or lengthen) as agents learn and a short run is
  mostly its early episodes;
- beyond them, in proportion to the units from the nearest size, which a plan names where it is more than
  :data:`FAR` times off ("from a run of N units; this one is M");
- the compile: that of a measurement that loaded from the cache; where every one compiled afresh (the code is in
  the cache now), at most :data:`LOAD_SECONDS`.

What a study spends beside its trainings' loops (starting, building environments, saving, the report and its
videos, trainings run side by side unevenly) is kept under ``rest STUDY`` (:func:`rest_key`, apart without the
videos): its last run's
time less what its trainings' paces account for. Paces kept before sizes were (a file of the older form) are not
read. A pace is a measurement on a machine others may share; an estimate is for planning, not a promise.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
from dataclasses import asdict, dataclass, fields
from datetime import date
from pathlib import Path
from typing import Any

from rlcompare import machine
from rlcompare.atomic import atomic_file

PACE_FILE = "pace.json"
AMOUNTS = ("seeds", "episodes", "total_steps", "eval_every", "vmap_width")
"""What a training's settings say of how much it trains, not how: left out of its pace's key (the studies evaluate
a fixed number of times, so the episodes between evaluations grow with the episodes; a deep training vmaps as many
seeds as it has, up to its width, as a tabular one spreads them over threads)."""
KEPT_SIZES = 4
"""Sizes (units a seed) kept a key: the newest measurements' of distinct sizes."""
SAME_SIZE = 1.5
"""Sizes within this factor of each other are one size: the newer measurement replaces the older."""
FAR = 4.0
"""A training this many times longer or shorter than every size measured is named in its plan's time."""
LOAD_SECONDS = 2.0
"""The most that loading a training's compiled code from the cache is counted where only a compile afresh was
measured: numba's kernels loaded in under a second here, JAX's programs traced and loaded in 2-4 s."""


@dataclass(frozen=True)
class Measure:
    """One training's measurement: the units each seed trained, one seed's seconds for them on one thread, its
    compile's seconds and whether it compiled afresh (else it loaded its compiled code)."""

    units: int
    seconds: float
    compile_seconds: float
    compiled: bool
    unit: str
    measured: str
    """The day it was measured (ISO)."""


@dataclass(frozen=True)
class Pace:
    """What is kept of one key: its measurements, the newest last."""

    measures: tuple[Measure, ...]

    @property
    def measured(self) -> str:
        """The day of its newest measurement."""
        return max(m.measured for m in self.measures)

    def nearest(self, units: int) -> Measure:
        """The measurement of the size nearest ``units`` (by ratio)."""
        return min(self.measures, key=lambda m: abs(math.log(max(units, 1) / m.units)))

    def far(self, units: int) -> bool:
        """Whether ``units`` lies more than :data:`FAR` times beyond the sizes measured."""
        sizes = [m.units for m in self.measures]
        return units > FAR * max(sizes) or units * FAR < min(sizes)

    def per_seed(self, units: int) -> float:
        """One seed's seconds for ``units`` units on one thread: on the log-log line between the sizes measured
        around it, else in proportion from the nearest."""
        units = max(units, 1)
        by_size = sorted(self.measures, key=lambda m: m.units)
        below = [m for m in by_size if m.units <= units]
        above = [m for m in by_size if m.units >= units]
        if below and above and below[-1].units != above[0].units:
            low, high = below[-1], above[0]
            along = math.log(units / low.units) / math.log(high.units / low.units)
            return math.exp((1 - along) * math.log(low.seconds) + along * math.log(high.seconds))
        nearest = self.nearest(units)
        return nearest.seconds * units / nearest.units

    def compile(self) -> float:
        """Its compile's seconds next time: the newest load measured, else at most :data:`LOAD_SECONDS`."""
        loads = [m.compile_seconds for m in self.measures if not m.compiled]
        return loads[-1] if loads else min(self.measures[-1].compile_seconds, LOAD_SECONDS)

    def seconds(self, seeds: int, amount: int, threads: int, as_run: bool = False) -> float:
        """The time ``seeds`` seeds of ``amount`` units each take with ``threads`` threads, compile included
        (``as_run``: the compile as the newest measurement took it, for what a run just spent)."""
        compiling = self.measures[-1].compile_seconds if as_run else self.compile()
        return compiling + self.per_seed(amount) * seeds / max(1, min(threads, seeds))


def key(engine: str, config: Any) -> str:
    """What the pace of a training of ``config`` (either engine's configuration) is kept under: its engine,
    environment and name, and a digest of its settings but its amounts (seeds, episodes, total steps), which a
    pace is divided by: ``tabular MountainCar-v0 q_learning-decay 3f2a...``."""
    settings = json.dumps(settings_of(config), sort_keys=True, default=str)
    return f"{engine} {config.env} {config.name} {hashlib.sha256(settings.encode()).hexdigest()[:12]}"


def settings_of(config: Any) -> dict[str, Any]:
    """A configuration's fields but its amounts (:data:`AMOUNTS`), and a deep one's resolved hyperparameters but its
    total steps (read without copying its seeds: a plan of a million is read in a blink)."""
    settings = {item.name: getattr(config, item.name) for item in fields(config)}
    if hasattr(config, "method_config"):
        settings["resolved"] = asdict(config.method_config())
    return without_amounts(settings)


def without_amounts(settings: dict[str, Any]) -> dict[str, Any]:
    """``settings`` without the keys of :data:`AMOUNTS`, in tables within it too (a deep configuration's
    hyperparameters)."""
    return {name: without_amounts(value) if isinstance(value, dict) else value for name, value in settings.items()
            if name not in AMOUNTS}


REST = "rest "
"""The prefix of the key a study's rest is kept under: ``rest paper``."""


def pace_file() -> Path:
    """``pace.json`` in rlcompare's cache directory, or the file ``RLCOMPARE_PACE_FILE`` names (the test suite keeps
    its tiny trainings' paces apart from a user's that way)."""
    return Path(os.environ.get("RLCOMPARE_PACE_FILE") or machine.cache_root() / PACE_FILE)


def threads_for(seeds: int) -> int:
    """The threads a tabular training spreads ``seeds`` over on this machine (one per core, at most one a seed)."""
    return max(1, min(seeds, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
                      or 1))


def stored() -> dict[str, Pace]:
    """Every pace kept on this machine; none where the file is missing or unreadable (nothing depends on it), and
    none of a key kept in the older form (no sizes)."""
    try:
        entries = json.loads(pace_file().read_text())
    except (OSError, ValueError):
        return {}
    if not isinstance(entries, dict):
        return {}
    paces = {}
    for name, kept in entries.items():
        with contextlib.suppress(TypeError, ValueError, ZeroDivisionError):
            measures = tuple(Measure(**m) for m in kept)
            if measures and all(m.units >= 1 and m.seconds > 0 for m in measures):
                paces[name] = Pace(measures)
    return paces


def record(name: str, *, wall_seconds: float, compile_seconds: float, seeds: int, amount: int, unit: str,
           threads: int = 1, compiled: bool = False) -> None:
    """Keep the measurement of a training that ran ``seeds`` seeds of ``amount`` units each in ``wall_seconds`` on
    ``threads`` threads, after a compile of ``compile_seconds`` (``compiled``: afresh, not loaded from the cache).
    Where the cache cannot be written (a read-only home) nothing is kept: a pace is never worth failing a training
    for. Two processes recording at once may each keep only their own entry."""
    if seeds < 1 or amount < 1 or wall_seconds <= 0:
        return
    new = Measure(amount, wall_seconds * max(1, min(threads, seeds)) / seeds, compile_seconds, compiled, unit,
                  date.today().isoformat())
    kept = stored()
    others = [m for m in kept[name].measures if abs(math.log(m.units / amount)) > math.log(SAME_SIZE)
              ] if name in kept else []
    entries = {key: [asdict(m) for m in pace.measures] for key, pace in kept.items()}
    entries[name] = [asdict(m) for m in [*others, new][-KEPT_SIZES:]]
    with contextlib.suppress(OSError):
        pace_file().parent.mkdir(parents=True, exist_ok=True)
        with atomic_file(pace_file(), "w") as handle:
            json.dump(entries, handle, indent=1, sort_keys=True)


def rest_key(study: str, videos: bool = True) -> str:
    """The key of what a study's run spends beside its trainings' loops, apart with and without its videos:
    ``rest paper``, ``rest paper no-videos``."""
    return f"{REST}{study}{'' if videos else ' no-videos'}"


def record_rest(name: str, seconds: float) -> None:
    """Keep what a study's run spent beside what its trainings' paces account for, under ``name``
    (:func:`rest_key`)."""
    record(name, wall_seconds=max(seconds, 1e-3), compile_seconds=0.0, seeds=1, amount=1, unit="rest")
