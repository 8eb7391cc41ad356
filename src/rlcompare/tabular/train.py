"""``train(config) -> Results``: every seed of a tabular configuration trained in the fused kernels."""

from __future__ import annotations

import contextlib
import sys
import time
from collections.abc import Callable, Iterator
from datetime import datetime, timezone
from typing import Any

import numba
import numpy as np
from numba.core import event

from rlcompare import compiled, machine, pace
from rlcompare.algorithms.registry import rule_for
from rlcompare.algorithms.schedules import constant_epsilon, linear_decay_epsilon
from rlcompare.envs import gymnasium_env
from rlcompare.envs.features import make_features
from rlcompare.envs.registry import make_env
from rlcompare.tabular import runs as engine
from rlcompare.tabular.config import ExperimentConfig
from rlcompare.tabular.memory import check_memory
from rlcompare.tabular.results import Results
from rlcompare.tabular.state import (
    ENV_STREAM,
    EVAL_ENV_STREAM,
    EVAL_TRANSITION_STREAM,
    TRANSITION_STREAM,
    RunState,
    Settings,
    allocate_records,
    initial_state,
)

CHUNK_EPISODES = 250
"""Episodes per kernel call where a run's weights fit a core's cache; once every run has finished a chunk, the
progress bar moves. Results do not depend on it."""
CACHED_BYTES = 2**20
"""Weights of one run a core keeps in its cache, about (half of this machine's 2 MiB of L2 per core)."""


def chunk_episodes(weights_bytes: int) -> int:
    """Episodes per chunk for runs whose weights take ``weights_bytes`` each: :data:`CHUNK_EPISODES`, times the
    weights' size in :data:`CACHED_BYTES`. A thread takes its runs in turn, a chunk each, and a run whose table
    outgrew the cache reloads it after every turn: Q-Learning on KRK (a 6.3 MB table), 8 seeds on one thread, ran at
    0.51-0.62 of a plain kernel that trains run after run with chunks of 250 episodes, 0.72-0.87 with 5,000."""
    return CHUNK_EPISODES * max(1, -(-weights_bytes // CACHED_BYTES))


def epsilon_schedule(config: ExperimentConfig) -> np.ndarray:
    """ε of every episode under the configured schedule."""
    if config.schedule == "constant":
        return constant_epsilon(config.episodes, config.epsilon)
    return linear_decay_epsilon(config.episodes, config.epsilon_start, config.epsilon_end,
                                config.decay_fraction)


def train(config: ExperimentConfig, *, study: str = "", progress: Callable[[int], None] | None = None) -> Results:
    """Train every seed of ``config`` in the fused kernels, seeds spread over threads.

    ``progress`` is called with the number of episodes (per seed) finished since its last call. Records that
    would not fit in this machine's memory are refused first (:func:`~rlcompare.tabular.memory.check_memory`).
    """
    check_memory(config)
    compiled.tend()
    epsilons = epsilon_schedule(config)
    features = make_features(config.environment, config.features, config.grid_bins, config.tilings, config.tiles,
                             config.hash_size, config.bounds)
    state = initial_state(list(config.seeds), features.n_features, config.environment.n_actions,
                          config.environment.legal_moves)
    stage_episodes = np.array(list(config.stage_episodes().values()), dtype=np.int64)
    records = allocate_records(len(config.seeds), config.episodes, config.evaluation_rounds,
                                      config.eval_episodes, stage_episodes, state.w.shape[1:])
    with stepped_env(config, state) as env:
        rule, settings = rule_for(config), kernel_settings(config)

        started = time.perf_counter()
        with event.install_recorder("numba:compile") as compiles:  # a load from the cache compiles nothing
            engine.train_runs(rule, settings, env, features, state, epsilons, 0, 0, records)  # compile or load it
        compile_seconds = time.perf_counter() - started
        size = chunk_episodes(state.w[0].nbytes if len(config.seeds) else 0)
        chunks = [(first, min(first + size, config.episodes)) for first in range(0, config.episodes, size)]
        started = time.perf_counter()
        engine.train_chunks(rule, settings, env, features, state, epsilons, chunks, records, progress)
        wall = time.perf_counter() - started
    threads = min(numba.get_num_threads(), len(config.seeds))
    pace.record(pace.key("tabular", config), wall_seconds=wall, compile_seconds=compile_seconds,
                seeds=len(config.seeds), amount=config.episodes, unit="episodes", threads=threads,
                compiled=bool(compiles.buffer))
    steps = int(records.lengths.sum())
    meta = _meta(config, study, wall, steps, int(records.eval_lengths.sum()))
    meta["timings"]["compile_seconds"] = compile_seconds
    return Results(config=config, epsilons=epsilons, records=records, meta=meta)


@contextlib.contextmanager
def stepped_env(config: ExperimentConfig, state: RunState) -> Iterator[Any]:
    """The environment compiled code steps: a port, or Gymnasium environments opened for every run (their
    generators copies of the run's reset and transition streams) and closed afterwards."""
    if config.environment.is_ported:
        yield make_env(config.environment)
        return
    training = state.rng[:, [ENV_STREAM, TRANSITION_STREAM]]
    evaluation = state.rng[:, [EVAL_ENV_STREAM, EVAL_TRANSITION_STREAM]]
    with gymnasium_env.opened(config.env, training, evaluation, config.step_limit) as handle:
        yield make_env(config.environment, handle)


def kernel_settings(config: ExperimentConfig) -> Settings:
    """The scalars every method reads, as compiled code reads them."""
    return Settings(alpha=float(config.alpha), gamma=float(config.gamma), max_steps=int(config.step_limit),
                    truncation_as_terminal=bool(config.truncation_as_terminal), eval_every=int(config.eval_every),
                    legal_moves=config.environment.legal_moves is not None)


def _meta(config: ExperimentConfig, study: str, wall: float, steps: int, eval_steps: int) -> dict[str, Any]:
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
        "versions": dict(machine.versions()),
    }
