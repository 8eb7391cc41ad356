"""``run(config) -> Results``: train every seed of a configuration in the fused engine."""

from __future__ import annotations

import contextlib
import functools
import json
import platform
import sys
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor, as_completed
from datetime import datetime, timezone
from importlib import metadata
from pathlib import Path
from typing import Any

import numba
import numpy as np

from rlcompare import _numba_cache as numba_cache
from rlcompare.algorithms.registry import rule_for
from rlcompare.algorithms.schedules import constant_epsilon, linear_decay_epsilon
from rlcompare.engine import run as engine
from rlcompare.engine.state import (
    ENV_STREAM,
    EVAL_ENV_STREAM,
    EVAL_TRANSITION_STREAM,
    TRANSITION_STREAM,
    RunState,
    Settings,
    allocate_records,
    initial_state,
)
from rlcompare.envs import gymnasium_env
from rlcompare.envs.features import make_features
from rlcompare.envs.registry import make_env
from rlcompare.experiment import engines, rundir, store
from rlcompare.experiment.config import ExperimentConfig, check_memory
from rlcompare.experiment.results import Results

CHUNK_EPISODES = 250
"""Episodes per kernel call; once every run has finished one, the progress bar moves. Results do not depend on
it."""


def epsilon_schedule(config: ExperimentConfig) -> np.ndarray:
    """ε of every episode under the configured schedule."""
    if config.schedule == "constant":
        return constant_epsilon(config.episodes, config.epsilon)
    return linear_decay_epsilon(config.episodes, config.epsilon_start, config.epsilon_end,
                                config.decay_fraction)


def run(
    config: ExperimentConfig,
    *,
    out: Path | None = None,
    study: str = "",
    progress: Callable[[int], None] | None = None,
) -> Results:
    """Train every seed of ``config``; write the run directory to ``out`` if given.

    ``progress`` is called with the number of episodes (per seed) finished since its last call. Records that
    would not fit in this machine's memory are refused first (:func:`~rlcompare.experiment.config.check_memory`).
    """
    check_memory(config)
    numba_cache.tend()
    if out is None:
        return _train(config, study, progress)
    with store.output_directory(Path(out), store.RUN):  # refused before training, locked while it lasts
        results = _train(config, study, progress)
        results.save(out)
    return results


def _train(config: ExperimentConfig, study: str, progress: Callable[[int], None] | None) -> Results:
    epsilons = epsilon_schedule(config)
    features = make_features(config.environment, config.features, config.bins, config.tilings, config.tiles,
                             config.hash_size, config.bounds)
    state = initial_state(list(config.seeds), features.n_features, config.environment.n_actions)
    stage_episodes = np.array(list(config.stage_episodes().values()), dtype=np.int64)
    records = allocate_records(len(config.seeds), config.episodes, config.evaluation_rounds,
                                      config.eval_episodes, stage_episodes, state.w.shape[1:])
    with stepped_env(config, state) as env:
        rule, settings = rule_for(config), kernel_settings(config)

        started = time.perf_counter()
        engine.train_runs(rule, settings, env, features, state, epsilons, 0, 0, records)  # compile or load it
        compile_seconds = time.perf_counter() - started
        chunks = [(first, min(first + CHUNK_EPISODES, config.episodes))
                  for first in range(0, config.episodes, CHUNK_EPISODES)]
        started = time.perf_counter()
        engine.train_chunks(rule, settings, env, features, state, epsilons, chunks, records, progress)
        wall = time.perf_counter() - started
    steps = int(records.lengths.sum())
    meta = _meta(config, study, wall, steps, int(records.eval_lengths.sum()))
    meta["timings"]["compile_seconds"] = compile_seconds
    return Results(config=config, epsilons=epsilons, records=records, meta=meta)


@contextlib.contextmanager
def stepped_env(config: ExperimentConfig, state: RunState) -> Iterator[tuple]:
    """The environment compiled code steps: a port, or Gymnasium environments opened for every run (their
    generators copies of the run's reset and transition streams) and closed afterwards."""
    if config.environment.is_ported:
        yield make_env(config.environment)
        return
    training = state.rng[:, [ENV_STREAM, TRANSITION_STREAM]]
    evaluation = state.rng[:, [EVAL_ENV_STREAM, EVAL_TRANSITION_STREAM]]
    with gymnasium_env.opened(config.env, training, evaluation, config.max_steps) as handle:
        yield make_env(config.environment, handle)


def kernel_settings(config: ExperimentConfig) -> Settings:
    """The scalars every method reads, as compiled code reads them."""
    return Settings(alpha=float(config.alpha), gamma=float(config.gamma), max_steps=int(config.max_steps),
                    truncation_is_terminal=bool(config.truncation_as_terminal), eval_every=int(config.eval_every))


def _meta(config: ExperimentConfig, study: str, wall: float, steps: int, eval_steps: int) -> dict:
    return {
        "study": study,
        "name": config.name,
        "seeds": list(config.seeds),
        "stepped_by": "compiled port" if config.environment.is_ported else "Gymnasium adapter (Python speed)",
        "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "command": sys.argv,
        "timings": {"wall_seconds": wall, "training_steps": steps, "evaluation_steps": eval_steps,
                    "threads": min(numba.get_num_threads(), len(config.seeds)),
                    "steps_per_second": (steps + eval_steps) / wall if wall > 0 else None},
        "versions": dict(versions()),
    }


@functools.cache
def versions() -> dict[str, str | None]:
    """Python, the platform and the packages a result depends on (read once: reading them costs milliseconds)."""
    return {"python": platform.python_version(), "platform": platform.platform(),
            **{pkg: package_version(pkg) for pkg in ("rlcompare", "numpy", "numba", "gymnasium", "pandas")}}


def package_version(package: str) -> str | None:
    try:
        return metadata.version(package)
    except metadata.PackageNotFoundError:
        return None


def changed_settings(run_dir: Path, config: Any) -> str:
    """How the finished run in ``run_dir`` was made differently from ``config``: ``seeds 0-29 there, 0-9 asked``
    for each setting that differs (the first three); empty where it holds no finished run, or one of ``config``."""
    if not (run_dir / rundir.META_FILE).is_file():
        return ""
    try:
        stored = store.read_json(run_dir / rundir.CONFIG_FILE)
    except store.StoreError:
        return ""
    asked = json.loads(json.dumps(config.to_dict()))
    if not isinstance(stored, dict) or stored == asked:
        return ""
    differing = [key for key in sorted(set(stored) | set(asked)) if stored.get(key) != asked.get(key)]
    shown = [f"{key} {_setting(stored.get(key))} there, {_setting(asked.get(key))} asked" for key in differing[:3]]
    return ", ".join(shown) + (f" and {len(differing) - 3} more" if len(differing) > 3 else "")


def _setting(value: Any) -> str:
    """A setting as a reader writes it; a run of consecutive seeds as ``0-29``."""
    if isinstance(value, list) and value and all(isinstance(v, int) for v in value):
        if len(value) > 2 and value == list(range(value[0], value[0] + len(value))):
            return f"{value[0]}-{value[-1]}"
        return ", ".join(map(str, value))
    return "none" if value is None else str(value)


def refuse_replacing(out: Path, configs: dict[str, Any]) -> None:
    """A :class:`~rlcompare.experiment.store.StoreError` where ``out`` holds finished runs made with other settings
    than ``configs`` asks for (name -> config; ``""``: ``out`` itself is the run): rlcompare does not replace a
    user's results without a word."""
    changed = {name: text for name, config in configs.items()
               if (text := changed_settings(Path(out) / name if name else Path(out), config))}
    if changed:
        name, text = next(iter(changed.items()))
        where = f"{name}: " if name else ""
        more = f" (and {len(changed) - 1} more runs)" if len(changed) > 1 else ""
        raise store.StoreError(f"{out}: holds finished runs made with other settings ({where}{text}){more}; choose "
                               "another --out, ask for the same settings to resume them, or pass --force to "
                               "replace them")


def run_or_load(
    out: Path, configs: dict[str, Any], *, study: str, progress: Callable[[int], None] | None = None,
    force: bool = False, train: Callable[..., Any] | None = None, load: Callable[..., Any] | None = None,
    workers: int = 1,
) -> Iterator[tuple[str, Any, bool]]:
    """Run each configuration into ``out / name`` on its engine (:mod:`rlcompare.experiment.engines`), or load
    it if that run already finished and its files belong together. A study that keeps a summary of its runs
    instead gives its own ``train`` and ``load`` (``Results.load``'s signature). ``workers`` configurations train
    at once (each run's results depend on its configuration alone).

    ``out`` is claimed as the study's directory (``force``: even beside files rlcompare did not write) and
    locked while this runs. Finished runs made with other settings are refused before anything is trained
    (:func:`refuse_replacing`; ``force``: replaced). Yields ``(name, results, reused)`` as each configuration
    completes, so an interrupted study resumes where it stopped and loses nothing finished.
    """

    def one(name: str, config: Any) -> tuple[str, Any, bool]:
        run_dir = Path(out) / name
        stored = engines.load_if_complete(run_dir, config, load)
        if stored is not None:
            if progress is not None:
                progress(config.progress_total)
            return name, stored, True
        return name, (train or engines.train)(config, out=run_dir, study=study, progress=progress), False

    with store.output_directory(Path(out), store.Owner("study", study), force=force):
        if not force:
            refuse_replacing(Path(out), configs)
        if workers <= 1:
            for name, config in configs.items():
                yield one(name, config)
            return
        with ThreadPoolExecutor(workers) as pool:
            pending = [pool.submit(one, name, config) for name, config in configs.items()]
            try:
                for future in as_completed(pending):
                    yield future.result()
            finally:
                for future in pending:
                    future.cancel()
