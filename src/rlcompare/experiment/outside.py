"""Runs other libraries made, read into one tidy table: a row per (method, environment, seed, step) and its value.

The files are found below the directories given and read by their format (:mod:`rlcompare.experiment.formats`:
Stable-Baselines3's Monitor files, RL Zoo's evaluations, TensorBoard event files, a tidy CSV or Parquet); rlcompare's
own run directories give their training episodes (:func:`episodes_table`), labelled by their own configuration.

Which method, environment and seed a file holds comes from a grouping rule over its path (:func:`grouping`), as
``{method}/{env}/seed_{seed}/*`` reads ``ppo/CartPole-v1/seed_3/0.monitor.csv``.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

import numpy as np
import pandas as pd

from rlcompare.experiment import store
from rlcompare.experiment.engines import load_run
from rlcompare.experiment.formats import (
    FILES,
    KINDS,
    TIDY,
    OutsideRunError,
    is_wandb_chart,
    read_in_parallel,
    read_monitor,
    read_monitors,
    read_tensorboard,
    read_tidy,
    reader_of,
    wandb_chart_runs,
)

FIELDS = ("method", "env", "seed")
"""What a grouping rule must name."""


@dataclass(frozen=True)
class Grouping:
    """A rule that names each file's method, environment and seed from its path relative to a root."""

    rule: str
    pattern: re.Pattern[str]

    def of(self, path: Path, root: Path) -> dict[str, str]:
        """``{method, env, seed}`` of ``path``; an :class:`OutsideRunError` where the rule does not match it."""
        try:
            relative = path.relative_to(root).as_posix()
        except ValueError:
            raise OutsideRunError(f"{path}: not below {root}; expected the files of the directories given") from None
        found = self.pattern.fullmatch(relative)
        if found is None:
            raise OutsideRunError(f"{path}: its path {relative!r} does not match the grouping rule {self.rule!r}")
        return found.groupdict()

    def of_name(self, name: str, source: Path) -> dict[str, str]:
        """``{method, env, seed}`` of a run named ``name`` in ``source`` (a W&B chart's run, its name as the rule's
        one level: ``{env}__{method}__{seed}__*`` reads CleanRL's ``CartPole-v1__ppo__3__1700000000``)."""
        found = self.pattern.fullmatch(name)
        if found is None:
            raise OutsideRunError(f"{source}: its run {name!r} does not match the grouping rule {self.rule!r}; "
                                  "expected a rule of the run names, as --group '{env}__{method}__{seed}__*' reads "
                                  "CleanRL's")
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


def hidden(relative: Path) -> bool:
    """Whether a path below a directory given lies in a hidden directory (``.git``, an interrupted export's
    scratch): not searched for runs."""
    return any(part.startswith(".") for part in relative.parts[:-1])


def walked(root: Path) -> Iterator[Path]:
    """Every entry below ``root``, by its path below it; a link to a directory is followed as a directory (runs kept
    elsewhere and linked in), each real directory once, so a link back up ends there instead of looping."""
    seen: set[str] = set()
    for directory, subdirectories, names in os.walk(root, followlinks=True):
        real = os.path.realpath(directory)
        if real in seen:
            subdirectories[:] = []
            continue
        seen.add(real)
        yield from (Path(directory) / name for name in (*subdirectories, *names))


def run_files(paths: Iterable[Path], kinds: Iterable[str] = tuple(FILES)) -> tuple[Path, list[Path]]:
    """The files ``paths`` name: each file itself, each directory's run files below it of ``kinds`` (of
    :data:`~rlcompare.experiment.formats.FILES`); and the root their grouping rule reads paths from (the directory
    given, or the deepest one common to all)."""
    files: list[Path] = []
    given = [Path(p) for p in paths]
    readers = [FILES[kind] for kind in kinds]
    for path in given:
        if path.is_dir() and store.owner_of(path) == store.RUN:
            files.append(path)
        elif path.is_dir():
            found = (f for f in walked(path) if not hidden(f.relative_to(path)))
            files += sorted(f for f in found if (f.is_file() and reader_of(f) in readers)
                            or (f.name == store.MARKER_FILE and store.owner_of(f.parent) == store.RUN))
            files = [f.parent if f.name == store.MARKER_FILE else f for f in files]
        elif path.is_file():
            files.append(path)
        else:
            raise OutsideRunError(f"{path}: no such file or directory; expected run files or directories of them")
    if not files:
        raise OutsideRunError(f"{', '.join(map(str, given))}: no run found; expected *.monitor.csv, evaluations.npz "
                              "or a tidy table")
    bases = [p if p.is_dir() else p.parent for p in given]  # absolute, not resolved: a link stays below its root
    return Path(os.path.commonpath([str(b.absolute()) for b in bases])), [f.absolute() for f in files]


def read_runs(paths: Iterable[Path], root: Path, rule: Grouping, tag: str | None = None) -> pd.DataFrame:
    """Every file of ``paths`` as tidy rows (:data:`TIDY`, with the ``source`` file of each and its ``kind``): a
    tidy table as it is, one of rlcompare's run directories under its configuration's name, a run's file
    (:func:`reader_of`; a TensorBoard file's scalar ``tag``) labelled by ``rule``; another file is an
    :class:`OutsideRunError` naming it. So is a run (method, environment, seed) found in two sources, and an
    environment whose runs are of two kinds (episodes against evaluations, or two tags)."""
    frames: list[pd.DataFrame] = []
    ordered = sorted(Path(p) for p in paths)
    events = read_in_parallel([p for p in ordered if reader_of(p) is read_tensorboard], tag)
    monitors = one_runs_monitors([p for p in ordered if reader_of(p) is read_monitor], root, rule)
    for path in ordered:
        if path.is_dir():  # one of rlcompare's own run directories: its training episodes, under its own name
            results = load_run(path)
            frames.append(episodes_table(results, run_label(results)).astype({"seed": str})
                          .assign(source=str(path), kind="rlcompare training episodes"))
            continue
        reader = reader_of(path)
        if reader is None and path.suffix == ".csv" and is_wandb_chart(path):
            frames.append(read_wandb_chart(path, rule))
            continue
        if reader is None and path.suffix in (".csv", ".parquet"):
            frames.append(read_tidy(path).assign(source=str(path), kind="tidy table"))
            continue
        if reader is None:
            raise OutsideRunError(f"{path}: not a run rlcompare reads; expected *.monitor.csv, evaluations.npz, a "
                                  f"TensorBoard events file, or a tidy .csv or .parquet of {', '.join(TIDY)}")
        labels, source = rule.of(path, root), str(path)
        if reader is read_monitor:
            if path not in monitors:
                continue  # read with the first of its run's files
            read, source = read_monitors(monitors[path]), monitor_source(monitors[path])
        elif reader is read_tensorboard:
            read = events[path]
        else:
            read = reader(path)
        if read.empty:
            raise OutsideRunError(f"{path}: no points; expected at least one")
        kind = {"kind": KINDS[reader]} if reader in KINDS else {}  # a TensorBoard file's names its tag
        frames.append(read.assign(**kind, **labels, source=source))
    if not frames:
        raise OutsideRunError(f"{root}: no run found; expected *.monitor.csv, evaluations.npz or a tidy table")
    frame = pd.concat(frames, ignore_index=True)[[*TIDY, "source", "kind"]]
    one_source_a_run(frame)
    one_run_a_label(frame)
    one_kind_an_environment(frame)
    return frame


def read_wandb_chart(path: Path, rule: Grouping) -> pd.DataFrame:
    """A W&B line chart's CSV export (:func:`~rlcompare.experiment.formats.wandb_chart_runs`) as tidy rows, each
    run's method, environment and seed read from its name by ``rule``."""
    frames = [points.assign(**rule.of_name(name, path), source=str(path), kind=f"W&B chart {metric}")
              for name, metric, points in wandb_chart_runs(path)]
    return pd.concat(frames, ignore_index=True)


def one_runs_monitors(paths: list[Path], root: Path, rule: Grouping) -> dict[Path, list[Path]]:
    """Monitor files by run: those of one method, environment and seed in one directory (a vectorised
    environment's, ``0.monitor.csv``, ``1.monitor.csv`` ...) are one run, keyed by its first file."""
    runs: dict[tuple[Path, tuple[str, ...]], list[Path]] = {}
    for path in paths:
        labels = rule.of(path, root)
        runs.setdefault((path.parent, tuple(labels[name] for name in FIELDS)), []).append(path)
    return {files[0]: files for files in runs.values()}


def monitor_source(files: list[Path]) -> str:
    """A run's Monitor files as the table of what was read names them: the file, or its directory's several."""
    return str(files[0]) if len(files) == 1 else f"{files[0].parent}{os.sep}*monitor.csv ({len(files)} files)"


def one_source_a_run(frame: pd.DataFrame) -> None:
    """Refuse a run (method, environment, seed) read from two sources, naming both: the same runs given twice, or
    two runs given one name, would be merged into one."""
    sources = frame.groupby(list(FIELDS), sort=True)["source"].unique()
    for key, found in sources.items():
        method, env, seed = cast(tuple[str, str, str], key)  # a MultiIndex's key: one value per field
        if len(found) > 1:
            kinds = frame.loc[frame["source"].isin(found[:2]), "kind"].unique()
            remedy = ("one kind of file a directory with --files (RL Zoo keeps a run's Monitor files and "
                      "evaluations together)" if len(kinds) > 1 and same_directory(found[0], found[1])
                      else "name runs apart with --group, or give one of them")
            raise OutsideRunError(f"{found[1]}: method {method}, environment {env}, seed {seed} again (also "
                                  f"{found[0]}); expected one source a run ({remedy})")


def same_directory(first: str, second: str) -> bool:
    """Whether two sources (files, or a directory's Monitor files) lie in one directory."""
    return Path(first.split(" (")[0]).parent == Path(second.split(" (")[0]).parent


def one_run_a_label(frame: pd.DataFrame) -> None:
    """Refuse a run (method, environment, seed) whose every step holds two points or more, naming its source: the
    same rows given twice, or two runs under one label, would be interleaved into one. (Some steps holding two
    points are a vectorised environment's episodes that ended together, and pass.)"""
    for (method, env, seed), steps in frame.groupby(list(FIELDS), sort=True)["step"]:
        counts = steps.value_counts()
        if len(steps) > 1 and (counts > 1).all():
            source = frame.loc[steps.index[0], "source"]
            raise OutsideRunError(f"{source}: method {method}, environment {env}, seed {seed} has {counts.iloc[0]} "
                                  f"points at step {counts.index[0]:,} and at every other step; expected one run a "
                                  "label (the same rows twice, or two runs under one seed: give them apart)")


def one_kind_an_environment(frame: pd.DataFrame) -> None:
    """Refuse an environment whose runs are of two kinds (training episodes against evaluations, or two tags),
    naming a file of each: their numbers measure different things."""
    for env, rows in frame.groupby("env", sort=True):
        kinds = rows.groupby("kind", sort=True)["source"].first()
        if len(kinds) > 1:
            (first, a), (second, b) = list(kinds.items())[:2]
            raise OutsideRunError(f"{b}: {second} on {env}, where {a} holds {first}; expected one kind of points on "
                                  "an environment (give one kind, or --tag)")


# --- rlcompare's own runs, as the tidy table ---------------------------------------------------------------

def episodes_table(results: Any, method: str | None = None) -> pd.DataFrame:
    """A run's training episodes as the tidy table (:data:`TIDY`): each episode's return at the environment steps
    up to its end, as Stable-Baselines3's Monitor records them; the method is ``method``, by default the run's
    algorithm."""
    config = results.config
    episodes = results.episodes() if callable(results.episodes) else results.episodes
    if "env_step" in episodes:  # the deep engine's vectorised environments: the step at which each episode ended
        steps = episodes["env_step"].to_numpy(np.int64)
    else:
        steps = episodes.groupby("seed", sort=False)["length"].cumsum().to_numpy(np.int64)
    return pd.DataFrame({"method": method or config.algorithm, "env": config.env, "seed": episodes["seed"].to_numpy(),
                         "step": steps, "value": episodes["return"].to_numpy(np.float64)})


def run_label(results: Any) -> str:
    """What a run of rlcompare's is called where it is read beside others (``compare``) and where it is exported:
    its configuration's name (``sarsa-decay``; a deep run's algorithm), not its algorithm alone, so that runs of one
    algorithm under two settings stay apart or are refused as one."""
    return str(results.config.name).removesuffix(f"-{results.config.env}")  # the deep engine's names end in it
