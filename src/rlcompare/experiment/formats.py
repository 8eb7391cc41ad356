"""The files other libraries' runs are kept in, each read into ``(step, value)`` points and checked as it is read: a
file that is not what its name says is an :class:`OutsideRunError` naming it and what was expected, never a silent
result (:mod:`rlcompare.experiment.outside` finds the files and names their runs).

- Stable-Baselines3's ``Monitor`` files (``*.monitor.csv``): a ``#`` line of JSON, then ``r,l,t`` per episode. The
  step of an episode is the environment steps up to its end (the sum of ``l``), its value the return ``r``.
- RL Zoo's ``evaluations.npz`` (Stable-Baselines3's ``EvalCallback``): ``timesteps`` and ``results``
  ``(evaluations, episodes)``; the value at a step is the mean of its episodes.
- TensorBoard event files (``events.out.tfevents.*``): one scalar by its tag (:data:`TAGS`: CleanRL's and
  Stable-Baselines3's names), read with TensorBoard's own loader.
- A tidy CSV or Parquet with the columns :data:`TIDY`, one file holding many runs.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from functools import partial
from multiprocessing import get_context
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

TIDY = ("method", "env", "seed", "step", "value")
"""The columns of the tidy table every reader gives."""
MONITOR_COLUMNS = ("r", "l", "t")


class OutsideRunError(ValueError):
    """A file that cannot be read as the run it claims to be: its path and what was expected."""


def read_monitor(path: Path) -> pd.DataFrame:
    """``(step, value)`` of a Stable-Baselines3 ``Monitor`` file: each episode's return at the environment steps
    up to its end."""
    return read_monitors([path])


def read_monitors(paths: list[Path]) -> pd.DataFrame:
    """``(step, value)`` of one run's Monitor files (one a vectorised environment, in one directory), as
    Stable-Baselines3's ``load_results`` and ``ts2xy`` read them: every file's episodes in the order of their wall
    time (each file's ``t`` from its ``t_start``), each at the environment steps of all the episodes up to it."""
    episodes = pd.concat([monitor_episodes(path) for path in paths], ignore_index=True)
    episodes = episodes.sort_values("t", kind="stable")
    return pd.DataFrame({"step": np.cumsum(episodes["l"].to_numpy(np.int64)),
                         "value": episodes["r"].to_numpy(np.float64)})


def monitor_episodes(path: Path) -> pd.DataFrame:
    """A Monitor file's episodes: return ``r``, length ``l`` and wall time ``t`` (from its header's ``t_start``),
    each checked."""
    try:
        with open(path, encoding="utf-8") as file:
            first = file.readline()
            if not first.startswith("#"):
                raise OutsideRunError(f"{path}: not a Stable-Baselines3 Monitor file; expected a first line "
                                      "'#{...}' of JSON, then the columns r,l,t")
            header = json.loads(first[1:])
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
    if not (np.isfinite(lengths).all() and np.isfinite(returns).all()) or (lengths <= 0).any():
        raise OutsideRunError(f"{path}: a row whose r or l is not a finite number (or l not positive); expected a "
                              "return and a length per episode")
    start = header.get("t_start", 0.0) if isinstance(header, dict) else 0.0
    relative = pd.to_numeric(episodes["t"], errors="coerce").to_numpy(np.float64)
    back = np.flatnonzero(np.diff(relative) < 0)
    if back.size:
        raise OutsideRunError(f"{path}: its wall time t goes back from {relative[back[0]]:g} s to "
                              f"{relative[back[0] + 1]:g} s at episode {back[0] + 2}; expected one run a file (a "
                              "Monitor with override_existing=False appends a resumed run to the first: give them "
                              "apart)")
    return pd.DataFrame({"r": returns, "l": lengths.astype(np.int64), "t": relative + float(start or 0.0)})


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
    return checked_points(path, steps, results.mean(axis=1))


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
    steps = pd.to_numeric(frame["step"], errors="coerce").to_numpy(np.float64)
    values = pd.to_numeric(frame["value"], errors="coerce").to_numpy(np.float64)
    if np.isnan(steps).any() or np.isnan(values).any():
        raise OutsideRunError(f"{path}: a step or value that is not a number; expected numbers in both")
    points = checked_points(path, steps, values, ordered=False)
    return pd.DataFrame({"method": frame["method"].astype(str), "env": frame["env"].astype(str),
                         "seed": frame["seed"].astype(str), "step": points["step"], "value": points["value"]})


WANDB_BOUNDS = ("__MIN", "__MAX")
"""The suffixes of the columns of a W&B chart's export that hold a smoothed or grouped line's bounds, not a run."""


def is_wandb_chart(path: Path) -> bool:
    """Whether a CSV is a W&B line chart's export: a first column of steps, then ``<run> - <metric>`` columns
    (with their ``__MIN`` and ``__MAX``), and none of the tidy table's columns."""
    try:
        columns = pd.read_csv(path, nrows=0).columns
    except (OSError, ValueError, pd.errors.EmptyDataError):
        return False
    return len(columns) > 1 and not set(TIDY) & set(columns) and all(" - " in str(c) for c in columns[1:])


def wandb_chart_runs(path: Path) -> list[tuple[str, str, pd.DataFrame]]:
    """``(run, metric, points)`` of each run of a W&B line chart's CSV export ("Export panel data": a first column
    of steps, then a ``<run> - <metric>`` column per run and its ``__MIN`` and ``__MAX``, which are left out): each
    run's ``(step, value)`` where it has a value, checked as every reader's points are."""
    try:
        frame = pd.read_csv(path)
    except (OSError, ValueError, pd.errors.ParserError) as error:
        raise OutsideRunError(f"{path}: not a W&B chart's CSV ({error})") from None
    steps = pd.to_numeric(frame.iloc[:, 0], errors="coerce").to_numpy(np.float64)
    runs = []
    for column in frame.columns[1:]:
        if str(column).endswith(WANDB_BOUNDS):
            continue
        name, metric = str(column).rsplit(" - ", 1)
        values = pd.to_numeric(frame[column], errors="coerce").to_numpy(np.float64)
        present = ~np.isnan(values)
        if not present.any():
            raise OutsideRunError(f"{path}: the run {name!r} has no value of {metric}; expected at least one")
        runs.append((name, metric, checked_points(path, steps[present], values[present])))
    metrics = sorted({metric for _, metric, _ in runs})
    if len(metrics) > 1:
        raise OutsideRunError(f"{path}: the metrics {', '.join(metrics)}; expected one a chart (export one chart)")
    return runs


LARGEST_STEP = 2**53
"""Steps above this are refused: a float holds every integer up to it, and no training runs so long."""


def checked_points(path: Path, steps: Any, values: Any, *, ordered: bool = True) -> pd.DataFrame:
    """``(step, value)`` of a run's points, each step a whole number from 0 to :data:`LARGEST_STEP` and each value
    finite; where ``ordered``, steps that never go back (a file whose steps restart holds a resumed run, or two);
    else an :class:`OutsideRunError` naming the file and the first point refused."""
    steps, values = np.asarray(steps, np.float64), np.asarray(values, np.float64)
    bad = ~np.isfinite(values)
    if bad.any():
        raise OutsideRunError(f"{path}: the value at step {steps[bad][0]:g} is {values[bad][0]}; expected finite "
                              "values")
    bad = ~np.isfinite(steps) | (steps < 0) | (steps > LARGEST_STEP) | (steps != np.floor(steps))
    if bad.any():
        raise OutsideRunError(f"{path}: a step of {steps[bad][0]:g}; expected whole numbers from 0 to "
                              f"{LARGEST_STEP:,}")
    back = np.flatnonzero(np.diff(steps) < 0)
    if ordered and back.size:
        raise OutsideRunError(f"{path}: its steps go back from {steps[back[0]]:,.0f} to {steps[back[0] + 1]:,.0f}; "
                              "expected steps that never go back (a resumed run's file holds two runs: give one)")
    return pd.DataFrame({"step": steps.astype(np.int64), "value": values})


TAGS = ("charts/episodic_return", "eval/mean_reward", "rollout/ep_rew_mean")
"""The tags a TensorBoard file is read by where ``--tag`` names none, the first present: CleanRL's episode returns,
Stable-Baselines3's evaluations, then its training episodes' running mean."""


def scalar_series(path: Path) -> dict[str, tuple[list[int], list[float]]]:
    """Every scalar of a TensorBoard event file by tag: its steps and values, its records read by TensorBoard's own
    loader and parsed as its ``Event`` protocol buffers (``simple_value`` as PyTorch's writer and TensorFlow 1 write
    a scalar, or a one-number tensor as TensorBoard's and TensorFlow 2's writers do)."""
    try:
        from tensorboard.backend.event_processing.event_file_loader import RawEventFileLoader
        from tensorboard.compat.proto.event_pb2 import Event
    except ImportError:
        raise OutsideRunError(f"{path}: a TensorBoard file, and TensorBoard is not installed; pip install -e "
                              "'.[compare]'") from None
    series: dict[str, tuple[list[int], list[float]]] = {}
    try:
        for record in RawEventFileLoader(str(path)).Load():
            event = Event.FromString(record)
            for value in event.summary.value:
                number = scalar_of(value)
                if number is not None:
                    steps, values = series.setdefault(value.tag, ([], []))
                    steps.append(int(event.step))
                    values.append(number)
    except Exception as error:  # the loader's and the parser's own errors (a truncated or foreign file)
        raise OutsideRunError(f"{path}: not a TensorBoard event file ({type(error).__name__}: {error})") from None
    return series


def scalar_of(value: Any) -> float | None:
    """The number of a summary value that holds one scalar; None for any other (an image, a histogram)."""
    kind = value.WhichOneof("value")
    if kind == "simple_value":
        return float(value.simple_value)
    if kind != "tensor" or value.metadata.plugin_data.plugin_name != "scalars":
        return None
    tensor = value.tensor
    for field in ("float_val", "double_val", "int_val", "int64_val"):
        if len(getattr(tensor, field)):
            return float(getattr(tensor, field)[0])
    dtype = {1: np.float32, 2: np.float64, 3: np.int32, 9: np.int64}.get(tensor.dtype)  # TensorFlow's DataType
    return float(np.frombuffer(tensor.tensor_content, dtype)[0]) if dtype and tensor.tensor_content else None


def read_tensorboard(path: Path, tag: str | None = None) -> pd.DataFrame:
    """``(step, value)`` of one scalar of a TensorBoard event file: ``tag``, or the first of :data:`TAGS` there."""
    series = scalar_series(path)
    chosen = tag if tag is not None else next((t for t in TAGS if t in series), None)
    if chosen is None or chosen not in series:
        wanted = f"the tag {tag!r}" if tag is not None else f"one of the tags {', '.join(TAGS)} (or --tag)"
        raise OutsideRunError(f"{path}: scalars {', '.join(sorted(series)) or 'none'}; expected {wanted}")
    steps, values = series[chosen]
    return checked_points(path, steps, values).assign(kind=f"TensorBoard {chosen}")


def reader_of(path: Path) -> Callable[..., pd.DataFrame] | None:
    """The reader of a run's file, by its name: a Monitor file, RL Zoo's evaluations or a TensorBoard event file."""
    if path.name.endswith("monitor.csv"):  # monitor.csv, and 0.monitor.csv, 1.monitor.csv ... of one run
        return read_monitor
    if path.name == "evaluations.npz":
        return read_zoo_evaluations
    if "tfevents" in path.name:
        return read_tensorboard
    return None


PARALLEL_FROM = 16
"""TensorBoard files are read by a pool of processes, one a core, from this many on (the record reader is Python's,
so threads would wait on each other); fewer are read here."""


def read_in_parallel(paths: list[Path], tag: str | None) -> dict[Path, pd.DataFrame]:
    """Each of ``paths`` (TensorBoard files) read with :func:`read_tensorboard`, in a pool of processes where there
    are many; the first file that cannot be read is its :class:`OutsideRunError`."""
    read = partial(read_tensorboard, tag=tag)
    workers = min(os.cpu_count() or 1, len(paths))
    if len(paths) < PARALLEL_FROM or workers < 2:
        return {path: read(path) for path in paths}
    with ProcessPoolExecutor(workers, mp_context=get_context("spawn")) as pool:
        return dict(zip(paths, pool.map(read, paths, chunksize=max(1, len(paths) // (4 * workers))), strict=True))


KINDS = {read_monitor: "Monitor episodes", read_zoo_evaluations: "RL Zoo evaluations"}
"""What each reader's points are, for the table of what was read (a TensorBoard file's kind names its tag)."""


FILES = {"monitor": read_monitor, "evaluations": read_zoo_evaluations, "tensorboard": read_tensorboard}
"""The kinds of run file a directory is searched for, by the names ``compare --files`` gives them: RL Zoo keeps a
run's Monitor files and its evaluations in one directory, and one of them is read."""
