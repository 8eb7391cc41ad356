"""Runs other libraries made, read into one tidy table: a row per (method, environment, seed, step) and its value.

The formats read, each checked as it is read (a file that is not what its name says is an :class:`OutsideRunError`
naming it and what was expected, never a silent result):

- Stable-Baselines3's ``Monitor`` files (``*.monitor.csv``): a ``#`` line of JSON, then ``r,l,t`` per episode. The
  step of an episode is the environment steps up to its end (the sum of ``l``), its value the return ``r``.
- RL Zoo's ``evaluations.npz`` (Stable-Baselines3's ``EvalCallback``): ``timesteps`` and ``results``
  ``(evaluations, episodes)``; the value at a step is the mean of its episodes.
- A tidy CSV or Parquet with the columns :data:`TIDY`, one file holding many runs.

Which method, environment and seed a file holds comes from a grouping rule over its path (:func:`grouping`), as
``{method}/{env}/seed_{seed}/*`` reads ``ppo/CartPole-v1/seed_3/0.monitor.csv``.
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

TIDY = ("method", "env", "seed", "step", "value")
"""The columns of the tidy table every reader gives."""
FIELDS = ("method", "env", "seed")
"""What a grouping rule must name."""
MONITOR_COLUMNS = ("r", "l", "t")


class OutsideRunError(ValueError):
    """A file that cannot be read as the run it claims to be: its path and what was expected."""


@dataclass(frozen=True)
class Grouping:
    """A rule that names each file's method, environment and seed from its path relative to a root."""

    rule: str
    pattern: re.Pattern[str]

    def of(self, path: Path, root: Path) -> dict[str, str]:
        """``{method, env, seed}`` of ``path``; an :class:`OutsideRunError` where the rule does not match it."""
        relative = path.relative_to(root).as_posix()
        found = self.pattern.fullmatch(relative)
        if found is None:
            raise OutsideRunError(f"{path}: its path {relative!r} does not match the grouping rule {self.rule!r}")
        return found.groupdict()


def grouping(rule: str) -> Grouping:
    """A rule of path parts with ``{method}``, ``{env}`` and ``{seed}`` (each within one directory or file name)
    and ``*`` (any name, or within a name any characters); a :class:`ValueError` naming what a rule needs."""
    missing = [name for name in FIELDS if "{" + name + "}" not in rule]
    unknown = set(re.findall(r"\{(\w*)\}", rule)) - set(FIELDS)
    if missing or unknown or any(rule.count("{" + name + "}") > 1 for name in FIELDS):
        raise ValueError(f"group: {rule!r}; allowed: a path rule naming each of {{method}}, {{env}} and {{seed}} "
                         "once, with * for any name (say '{method}/{env}/seed_{seed}/*')")
    pattern = ""
    for piece in re.split(r"(\{\w+\}|\*)", rule):
        if piece == "*":
            pattern += "[^/]*"
        elif piece.startswith("{") and piece.endswith("}"):
            pattern += f"(?P<{piece[1:-1]}>[^/]+?)"
        else:
            pattern += re.escape(piece)
    return Grouping(rule, re.compile(pattern))


def read_monitor(path: Path) -> pd.DataFrame:
    """``(step, value)`` of a Stable-Baselines3 ``Monitor`` file: each episode's return at the environment steps
    up to its end."""
    try:
        with open(path, encoding="utf-8") as file:
            first = file.readline()
            if not first.startswith("#"):
                raise OutsideRunError(f"{path}: not a Stable-Baselines3 Monitor file; expected a first line "
                                      "'#{...}' of JSON, then the columns r,l,t")
            json.loads(first[1:])
            episodes = pd.read_csv(file)
    except (json.JSONDecodeError, pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as error:
        raise OutsideRunError(f"{path}: not a Stable-Baselines3 Monitor file ({error}); expected a first line "
                              "'#{...}' of JSON, then the columns r,l,t") from None
    if tuple(episodes.columns[:3]) != MONITOR_COLUMNS:
        raise OutsideRunError(f"{path}: columns {', '.join(map(str, episodes.columns))}; expected r,l,t first, as "
                              "Stable-Baselines3's Monitor writes them")
    if episodes.empty:
        raise OutsideRunError(f"{path}: no episode; expected at least one row of r,l,t")
    lengths = pd.to_numeric(episodes["l"], errors="coerce").to_numpy()
    returns = pd.to_numeric(episodes["r"], errors="coerce").to_numpy(dtype=np.float64)
    if np.isnan(lengths).any() or np.isnan(returns).any() or (lengths <= 0).any():
        raise OutsideRunError(f"{path}: a row whose r or l is not a number (or l not positive); expected a return "
                              "and a length per episode")
    return pd.DataFrame({"step": np.cumsum(lengths.astype(np.int64)), "value": returns})


def read_zoo_evaluations(path: Path) -> pd.DataFrame:
    """``(step, value)`` of RL Zoo's ``evaluations.npz``: each evaluation's mean return at its timestep."""
    try:
        with np.load(path) as stored:
            steps, results = np.asarray(stored["timesteps"]), np.asarray(stored["results"], dtype=np.float64)
    except (OSError, ValueError, KeyError) as error:
        raise OutsideRunError(f"{path}: not an RL Zoo evaluations.npz ({error}); expected the arrays timesteps and "
                              "results, as Stable-Baselines3's EvalCallback writes them") from None
    if results.ndim != 2 or steps.shape != results.shape[:1] or steps.size == 0:
        raise OutsideRunError(f"{path}: timesteps {steps.shape} and results {results.shape}; expected one row of "
                              "results, (episodes,), per timestep, and at least one")
    return pd.DataFrame({"step": steps.astype(np.int64), "value": results.mean(axis=1)})


def read_tidy(path: Path) -> pd.DataFrame:
    """A tidy table of many runs (:data:`TIDY`), from CSV or Parquet."""
    try:
        frame = pd.read_parquet(path) if path.suffix == ".parquet" else pd.read_csv(path)
    except (OSError, ValueError, pd.errors.EmptyDataError) as error:
        raise OutsideRunError(f"{path}: not a tidy table ({error}); expected the columns {', '.join(TIDY)}") from None
    missing = [column for column in TIDY if column not in frame.columns]
    if missing or frame.empty:
        raise OutsideRunError(f"{path}: {'no column ' + ', '.join(missing) if missing else 'no row'}; expected the "
                              f"columns {', '.join(TIDY)} and a row per method, environment, seed and step")
    steps = pd.to_numeric(frame["step"], errors="coerce")
    values = pd.to_numeric(frame["value"], errors="coerce")
    if steps.isna().any() or values.isna().any():
        raise OutsideRunError(f"{path}: a step or value that is not a number; expected numbers in both")
    return pd.DataFrame({"method": frame["method"].astype(str), "env": frame["env"].astype(str),
                         "seed": frame["seed"].astype(str), "step": steps.astype(np.int64),
                         "value": values.astype(np.float64)})


READERS = {".monitor.csv": read_monitor, "evaluations.npz": read_zoo_evaluations}
"""A run's file by how its name ends, and its reader."""


def run_files(paths: Iterable[Path]) -> tuple[Path, list[Path]]:
    """The files ``paths`` name: each file itself, each directory's run files (:data:`READERS`) below it; and the
    root their grouping rule reads paths from (the directory given, or the deepest one common to all)."""
    files: list[Path] = []
    given = [Path(p) for p in paths]
    for path in given:
        if path.is_dir():
            files += sorted(f for f in path.rglob("*") if f.is_file() and any(f.name.endswith(e) for e in READERS))
        elif path.is_file():
            files.append(path)
        else:
            raise OutsideRunError(f"{path}: no such file or directory; expected run files or directories of them")
    if not files:
        raise OutsideRunError(f"{', '.join(map(str, given))}: no run found; expected *.monitor.csv, evaluations.npz "
                              "or a tidy table")
    bases = [p if p.is_dir() else p.parent for p in given]
    return Path(os.path.commonpath([str(b.resolve()) for b in bases])), [f.resolve() for f in files]


def read_runs(paths: Iterable[Path], root: Path, rule: Grouping) -> pd.DataFrame:
    """Every file of ``paths`` as tidy rows (:data:`TIDY`, and the ``source`` file of each): a tidy table as it is,
    a run's file (:data:`READERS`) labelled by ``rule``; another file is an :class:`OutsideRunError` naming it. Two
    files of the same method, environment and seed are one too."""
    frames: list[pd.DataFrame] = []
    seen: dict[tuple[str, ...], Path] = {}
    for path in sorted(Path(p) for p in paths):
        reader = next((read for ending, read in READERS.items() if path.name.endswith(ending)), None)
        if reader is None and path.suffix in (".csv", ".parquet"):
            frames.append(read_tidy(path).assign(source=str(path)))
            continue
        if reader is None:
            raise OutsideRunError(f"{path}: not a run rlcompare reads; expected *.monitor.csv, evaluations.npz, or a "
                                  f"tidy .csv or .parquet of {', '.join(TIDY)}")
        labels = rule.of(path, root)
        key = tuple(labels[name] for name in FIELDS)
        if key in seen:
            raise OutsideRunError(f"{path}: method {key[0]}, environment {key[1]}, seed {key[2]} again (also "
                                  f"{seen[key]}); expected one file a run")
        seen[key] = path
        frames.append(reader(path).assign(**labels, source=str(path)))
    if not frames:
        raise OutsideRunError(f"{root}: no run found; expected *.monitor.csv, evaluations.npz or a tidy table")
    return pd.concat(frames, ignore_index=True)[[*TIDY, "source"]]
