"""How fast each training ran on this machine, kept so that a plan can say how long a study will take before it
trains (``rlcompare reproduce STUDY --plan``).

Every training that finishes enters its pace here (:func:`record`): the seconds one seed took per unit it trained
(an episode, an environment step), on one thread, and the seconds its compile (or the load of its compiled code)
took, under a key naming its engine, environment, configuration and settings (:func:`key`). They are kept in
``pace.json`` in rlcompare's cache directory (:func:`rlcompare.machine.cache_root`), the newest measurement of a key
replacing the one before. A training whose key holds no pace has no estimate: a plan says so, and how many.

A pace is a measurement of one training; another number of episodes (whose lengths change as an agent learns) or
another load on the machine makes the next one differ. An estimate is for planning, not a promise.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
from dataclasses import asdict, dataclass, fields
from datetime import date
from pathlib import Path
from typing import Any

from rlcompare import machine
from rlcompare.atomic import atomic_file

PACE_FILE = "pace.json"
AMOUNTS = ("seeds", "episodes", "total_steps", "eval_every")
"""What a training's settings say of how much it trains, not how: left out of its pace's key (the studies evaluate
a fixed number of times, so the episodes between evaluations grow with the episodes)."""


@dataclass(frozen=True)
class Pace:
    """One training's measured pace: seconds per seed and unit on one thread, and its compile's seconds."""

    seconds_per_unit: float
    compile_seconds: float
    unit: str
    measured: str
    """The day it was measured (ISO)."""

    def seconds(self, seeds: int, amount: int, threads: int) -> float:
        """The time ``seeds`` seeds of ``amount`` units each take with ``threads`` threads, compile included."""
        return self.compile_seconds + self.seconds_per_unit * seeds * amount / max(1, min(threads, seeds))


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


def pace_file() -> Path:
    """``pace.json`` in rlcompare's cache directory, or the file ``RLCOMPARE_PACE_FILE`` names (the test suite keeps
    its tiny trainings' paces apart from a user's that way)."""
    return Path(os.environ.get("RLCOMPARE_PACE_FILE") or machine.cache_root() / PACE_FILE)


def threads_for(seeds: int) -> int:
    """The threads a tabular training spreads ``seeds`` over on this machine (one per core, at most one a seed)."""
    return max(1, min(seeds, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
                      or 1))


def stored() -> dict[str, Pace]:
    """Every pace kept on this machine; none where the file is missing or unreadable (nothing depends on it)."""
    try:
        entries = json.loads(pace_file().read_text())
        return {name: Pace(**entry) for name, entry in entries.items()}
    except (OSError, ValueError, TypeError):
        return {}


def record(name: str, *, wall_seconds: float, compile_seconds: float, seeds: int, amount: int, unit: str,
           threads: int = 1) -> None:
    """Keep the pace of a training that ran ``seeds`` seeds of ``amount`` units each in ``wall_seconds`` on
    ``threads`` threads. Where the cache cannot be written (a read-only home) nothing is kept: a pace is never
    worth failing a training for. Two processes recording at once may each keep only their own entry."""
    if seeds < 1 or amount < 1 or wall_seconds <= 0:
        return
    pace = Pace(wall_seconds * max(1, min(threads, seeds)) / (seeds * amount), compile_seconds, unit,
                date.today().isoformat())
    entries = {name: asdict(kept) for name, kept in stored().items()} | {name: asdict(pace)}
    with contextlib.suppress(OSError):
        pace_file().parent.mkdir(parents=True, exist_ok=True)
        with atomic_file(pace_file(), "w") as handle:
            json.dump(entries, handle, indent=1, sort_keys=True)
