"""``train(config) -> DeepResults``: every seed of a deep configuration trained in one jitted program, ``vmap_width``
seeds side by side (:mod:`rlcompare.deep.config`)."""

from __future__ import annotations

import functools
import math
import sys
import time
from collections.abc import Callable, Iterator
from datetime import datetime, timezone
from typing import Any

import jax
import numpy as np
import pandas as pd

from rlcompare import machine, pace
from rlcompare.deep import float64, rollout, use_compilation_cache
from rlcompare.deep.config import DeepConfig
from rlcompare.deep.envs import is_batched, jax_env, playing
from rlcompare.deep.methods import deep_method
from rlcompare.deep.results import DeepResults
from rlcompare.deep.rollout import TrainOutput
from rlcompare.validation import ConfigError

CACHE_EVENTS = {"/jax/compilation_cache/compile_requests_use_cache": 0, "/jax/compilation_cache/cache_hits": 0}
"""How often this process asked JAX's persistent cache for a compiled program, and found it: a request that found
nothing compiled afresh."""


def count_cache_event(event: str, **_: str | int) -> None:
    if event in CACHE_EVENTS:
        CACHE_EVENTS[event] += 1


jax.monitoring.register_event_listener(count_cache_event)


def compiled_afresh(before: dict[str, int]) -> bool:
    """Whether a program was compiled, not loaded, since the counts ``before`` (:data:`CACHE_EVENTS`)."""
    requests, hits = (CACHE_EVENTS[event] - before[event] for event in CACHE_EVENTS)
    return requests > hits


def groups(seeds: tuple[int, ...], width: int) -> Iterator[tuple[tuple[int, ...], tuple[int, ...]]]:
    """``(seeds, padded)``: the seeds in groups of ``width``, the last padded with copies of its first seed."""
    for first in range(0, len(seeds), width):
        group = seeds[first:first + width]
        yield group, group + (group[0],) * (width - len(group))


def compiled_training(config: DeepConfig) -> Callable[[jax.Array], TrainOutput]:
    """The training of ``vmap_width`` seeds, compiled: once a process for each configuration, whatever its
    seeds, so the trials of a sweep that differ only in their seeds share it."""
    return compiled_program(config.algorithm, config.env, config.method_config(), config.eval_rounds,
                            config.eval_episodes, config.vmap_width)


@functools.lru_cache(maxsize=32)
@float64
def traced_program(algorithm: str, env: str, method_config: Any, eval_rounds: int, eval_episodes: int,
                   width: int) -> Any:
    """The jitted, vmapped training of ``width`` seeds, traced for ``width`` keys (shapes known, nothing
    compiled); kept for the process."""
    environment = jax_env(env)
    train = deep_method(algorithm).module.make_train(method_config, environment, eval_rounds, eval_episodes)
    if is_batched(environment):  # one seed, its emulator's callbacks outside any vmap
        return jax.jit(lambda keys: jax.tree.map(lambda x: x[None], train(keys[0]))).trace(seed_keys((0,)))
    return jax.jit(jax.vmap(train)).trace(seed_keys((0,) * width))


@functools.lru_cache(maxsize=32)
@float64
def compiled_program(algorithm: str, env: str, method_config: Any, eval_rounds: int, eval_episodes: int,
                     width: int) -> Callable[[jax.Array], TrainOutput]:
    """The traced program lowered and compiled; kept for the process (``cache_info()`` counts the runs that found
    it)."""
    traced = traced_program(algorithm, env, method_config, eval_rounds, eval_episodes, width)
    return traced.lower().compile()  # type: ignore[no-any-return]


def array_bytes(jaxpr: Any) -> Iterator[int]:
    """The size in bytes of every array a traced program makes, its loops' and branches' bodies included, in
    Python integers (no product overflows)."""
    for equation in jaxpr.eqns:
        for variable in equation.outvars:
            shape, dtype = getattr(variable.aval, "shape", ()), getattr(variable.aval, "dtype", None)
            yield math.prod(shape) * (dtype.itemsize if dtype is not None else 0)
        for param in equation.params.values():
            for inner in param if isinstance(param, (tuple, list)) else (param,):
                if isinstance(inner, (jax.extend.core.Jaxpr, jax.extend.core.ClosedJaxpr)):
                    yield from array_bytes(getattr(inner, "jaxpr", inner))


def check_sizes(config: DeepConfig) -> None:
    """Refuse, after tracing and before compiling, a training one of whose arrays, or whose records, exceed this
    machine's memory, naming ``total_steps`` where the records are the larger part, else ``vmap_width``: XLA aborts
    the process on a size it cannot represent instead of raising."""
    traced = traced_program(config.algorithm, config.env, config.method_config(), config.eval_rounds,
                            config.eval_episodes, config.vmap_width)
    largest = max(array_bytes(traced.jaxpr.jaxpr), default=0)
    output = sum(math.prod(leaf.shape) * leaf.dtype.itemsize for leaf in jax.tree.leaves(traced.out_info))
    refuse_past_memory(config, largest, 2 * -(-len(config.seeds) // config.vmap_width) * output)


@float64
def params_template(config: DeepConfig) -> Any:
    """The shape of one seed's parameter tree, traced without training."""
    train = deep_method(config.algorithm).module.make_train(config.method_config(), config.environment,
                                                            config.eval_rounds, config.eval_episodes)
    return jax.eval_shape(train, jax.random.key(0)).params


def memory_needed(config: DeepConfig, compiled: Any) -> tuple[int, int]:
    """``(while training, records)``: bytes XLA allocates for one group of ``vmap_width`` seeds (its replay
    buffers, rollouts and outputs, as the compiled program reports them), and bytes of every group's records kept
    and joined after it. ``(0, 0)`` where the backend does not say."""
    stats = compiled.memory_analysis()
    if stats is None:
        return 0, 0
    output = stats.output_size_in_bytes
    groups = -(-len(config.seeds) // config.vmap_width)
    return stats.argument_size_in_bytes + output + stats.temp_size_in_bytes, 2 * groups * output


def check_memory(config: DeepConfig, compiled: Any) -> None:
    """A training that fits in this machine's memory, refused after compiling and before the first step."""
    refuse_past_memory(config, *memory_needed(config, compiled))


def refuse_past_memory(config: DeepConfig, training: int, records: int) -> None:
    """A :class:`ConfigError` where ``training + records`` bytes exceed this machine's memory, naming
    ``total_steps`` where the records are the larger part, else ``vmap_width``."""
    memory = machine.physical_memory()
    if training + records <= memory:
        return
    name, value = ("total_steps", config.method_config().total_steps) if records > training else (
        "vmap_width", config.vmap_width)
    raise ConfigError(name, value, f"a training that fits in memory: {config.name} on {len(config.seeds)} seeds, "
                      f"{config.vmap_width} side by side, needs {machine.gib(training)} while training and "
                      f"{machine.gib(records)} for its records; this machine has {machine.gib(memory)}")


def seed_keys(seeds: tuple[int, ...]) -> jax.Array:
    return jax.numpy.stack([jax.random.key(seed) for seed in seeds])


def episodes_frame(seeds: tuple[int, ...], output: TrainOutput) -> pd.DataFrame:
    """The training episodes of every seed, in the order they ended, with the step at which each did."""
    done = np.asarray(output.finished.done)
    n_envs = done.shape[-1]
    frames = []
    for index, seed in enumerate(seeds):
        flat_done = done[index].reshape(-1, n_envs)  # (vector steps, envs), in time order
        vector_step, _ = np.nonzero(flat_done)
        pick = {name: np.asarray(getattr(output.finished, name))[index].reshape(-1, n_envs)[flat_done]
                for name in ("returns", "lengths", "terminated")}
        frames.append(pd.DataFrame({
            "seed": np.full(len(vector_step), seed, np.int64),
            "episode": np.arange(len(vector_step), dtype=np.int64),
            "env_step": ((vector_step + 1) * n_envs).astype(np.int64),
            "return": pick["returns"].astype(np.float64),
            "length": pick["lengths"].astype(np.int64),
            "terminated": pick["terminated"].astype(bool),
        }))
    return pd.concat(frames, ignore_index=True)


def evaluations_frame(seeds: tuple[int, ...], output: TrainOutput, steps_per_round: int) -> pd.DataFrame:
    returns = np.asarray(output.eval_returns)
    _, rounds, per_round = returns.shape
    runs = len(seeds)
    return pd.DataFrame({
        "seed": np.repeat(np.asarray(seeds, np.int64), rounds * per_round),
        "round": np.tile(np.repeat(np.arange(rounds, dtype=np.int64), per_round), runs),
        "after_step": np.tile(np.repeat((np.arange(rounds, dtype=np.int64) + 1) * steps_per_round, per_round), runs),
        "return": returns.reshape(-1).astype(np.float64),
        "length": np.asarray(output.eval_lengths).reshape(-1).astype(np.int64),
        "terminated": np.asarray(output.eval_terminated).reshape(-1).astype(bool),
    })


@float64
def train(config: DeepConfig, *, study: str = "", progress: Callable[[int], None] | None = None) -> DeepResults:
    """Train every seed of ``config``, ``vmap_width`` at a time in one compiled program; ``progress`` is called
    with the number of seeds finished since its last call."""
    use_compilation_cache()
    started, before = time.perf_counter(), dict(CACHE_EVENTS)
    check_sizes(config)
    train = compiled_training(config)
    compile_seconds = time.perf_counter() - started
    check_memory(config, train)
    with playing(config.environment):  # an emulator's trainings take turns
        started = time.perf_counter()
        outputs = []
        for group, padded in groups(config.seeds, config.vmap_width):
            output = jax.device_get(jax.block_until_ready(train(seed_keys(padded))))
            kept = len(group)
            outputs.append(jax.tree.map(lambda x, kept=kept: x[:kept], output))
            if progress is not None:
                progress(len(group))
        wall = time.perf_counter() - started
    output = jax.tree.map(lambda *parts: np.concatenate(parts), *outputs)
    done = output.finished.done  # (seeds, rounds, updates per round, steps per update, environments)
    steps_per_round = int(np.prod(done.shape[2:]))
    steps = steps_per_round * done.shape[1]
    pace.record(pace.key("deep", config), wall_seconds=wall, compile_seconds=compile_seconds,
                seeds=len(config.seeds), amount=steps, unit="environment steps", compiled=compiled_afresh(before))
    meta = {
        "study": study, "name": config.name, "engine": "deep", "seeds": list(config.seeds),
        "created": datetime.now(timezone.utc).isoformat(timespec="seconds"), "command": sys.argv,
        "timings": {"compile_seconds": compile_seconds, "wall_seconds": wall, "training_steps": steps,
                    "steps_per_second": steps * len(config.seeds) / wall if wall > 0 else None,
                    "device": str(jax.devices()[0])},
        "versions": dict(machine.versions("jax", "flax", "optax")),
        "diverged": diverged_at(config.seeds, output.finite),
    }
    snapshots = {stage: _named_arrays(jax.tree.map(lambda leaf, i=index: leaf[:, i], output.snapshots))
                 for index, (stage, _) in enumerate(rollout.STAGES)}
    return DeepResults(config, episodes_frame(config.seeds, output),
                       evaluations_frame(config.seeds, output, steps_per_round), _named_arrays(output.params), meta,
                       snapshots)


def diverged_at(seeds: tuple[int, ...], finite: np.ndarray) -> dict[str, int]:
    """Each seed whose parameters became non-finite -> the first update after which they were (counted from 1 over
    the whole training); ``finite`` is :attr:`TrainOutput.finite` with a leading seed axis."""
    per_update = np.asarray(finite).reshape(len(seeds), -1)
    return {str(seed): int(np.argmin(row)) + 1 for seed, row in zip(seeds, per_update, strict=True) if not row.all()}


def _named_arrays(tree: Any) -> dict[str, np.ndarray]:
    """A parameter tree's leaves by their path (``jax.tree_util.keystr``)."""
    leaves = jax.tree_util.tree_flatten_with_path(tree)[0]
    return {jax.tree_util.keystr(path): np.asarray(leaf) for path, leaf in leaves}
