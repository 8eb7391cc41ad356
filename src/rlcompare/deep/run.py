"""``run(config) -> DeepResults``: train every seed of a deep configuration in one jitted program, and the run
directory it writes (the tabular engine's layout, :mod:`rlcompare.experiment.store`, with ``params.npz`` for the
Q-tables).

Seeds train ``vmap_width`` at a time, the last group padded with copies of its first seed: XLA batches the
matrix products of a vmap by its width, so a seed's numbers depend on the width (by about 1e-7 after twenty
updates) but not on which seeds train beside it or how many a user asks for.
"""

from __future__ import annotations

import dataclasses
import functools
import io
import json
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, ClassVar

import jax
import numpy as np
import pandas as pd

from rlcompare.deep import float64, rollout, use_compilation_cache
from rlcompare.deep.envs import DeepEnv, is_batched, jax_env
from rlcompare.deep.methods import deep_method, hyperparameters
from rlcompare.deep.rollout import TrainOutput
from rlcompare.experiment import rundir, store
from rlcompare.experiment.config import ConfigError, gib, physical_memory
from rlcompare.experiment.results import _parquet_bytes, _with_labels
from rlcompare.experiment.runner import package_version, versions


@dataclass(frozen=True)
class DeepConfig:
    """One deep configuration, run once per seed. Frozen and validated on creation."""

    engine: ClassVar[str] = "deep"
    """The engine that trains it (:mod:`rlcompare.experiment.engines`)."""

    algorithm: str = "pqn_q_lambda"
    """A deep method: ``pqn_q_lambda``, ``pqn_sarsa_lambda``, ``pqn_expected_sarsa_lambda``, ``dqn``,
    ``double_dqn`` or ``ppo`` (``docs/deep.md``)."""
    env: str = "CartPole-v1"
    """``CartPole-v1``, ``Acrobot-v1`` or ``MountainCar-v0`` at Gymnasium's registered limits, a MinAtar game, or an
    Atari game (``Breakout-Atari``: ``vmap_width`` 1)."""
    preset: str = "default"
    """A named set of the method's hyperparameters (``docs/deep.md``)."""
    hyperparameters: dict[str, Any] = field(default_factory=dict)
    """Overrides of the preset, by field name."""
    seeds: tuple[int, ...] = tuple(range(10))
    """One run per seed; seed ``s`` trains from ``jax.random.key(s)``."""
    eval_rounds: int = 20
    """Greedy evaluations, evenly spaced over the training, >= 1."""
    eval_episodes: int = 10
    """Episodes per evaluation, >= 1."""
    vmap_width: int = 10
    """Seeds trained side by side in one program (results depend on it; see the module's docstring), >= 1."""

    def __post_init__(self) -> None:
        deep_method(self.algorithm)
        jax_env(self.env)  # an environment without a JAX port is refused, naming those there are
        if not self.seeds or len(set(self.seeds)) != len(self.seeds) or any(
                not isinstance(s, int) or isinstance(s, bool) or not 0 <= s < 2**63 for s in self.seeds):
            raise ConfigError("seeds", self.seeds, "distinct integers in [0, 2**63), at least one")
        for name in ("eval_rounds", "eval_episodes", "vmap_width"):
            value = getattr(self, name)
            if not isinstance(value, int) or isinstance(value, bool) or value < 1:
                raise ConfigError(name, value, "a positive integer")
        if is_batched(self.environment) and self.vmap_width != 1:
            raise ConfigError("vmap_width", self.vmap_width,
                              "1 for an Atari game (its emulator plays one seed's games at a time)")
        if not isinstance(self.hyperparameters, dict):
            raise ConfigError("hyperparameters", self.hyperparameters, "a table of field names and values")
        object.__setattr__(self, "seeds", tuple(self.seeds))
        make_train = deep_method(self.algorithm).module.make_train  # builds closures only: cheap
        make_train(self.method_config(), self.environment, self.eval_rounds, self.eval_episodes)  # validates

    def method_config(self) -> Any:
        """The method's own config: preset, fixed settings and overrides, validated."""
        return hyperparameters(self.algorithm, self.env, self.preset, self.hyperparameters)

    @property
    def environment(self) -> DeepEnv:
        return jax_env(self.env)

    @property
    def name(self) -> str:
        return f"{self.algorithm}-{self.env}"

    @property
    def progress_total(self) -> int:
        """What a run's ``progress`` callback counts to: seeds (trained ``vmap_width`` at a time)."""
        return len(self.seeds)

    def to_dict(self) -> dict[str, Any]:
        """What ``config.json`` holds: the fields, and every hyperparameter the run used."""
        data = dataclasses.asdict(self)
        data["engine"] = self.engine
        data["seeds"] = list(self.seeds)
        data["resolved"] = _jsonable(dataclasses.asdict(self.method_config()))
        return data

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> DeepConfig:
        known = {f.name for f in dataclasses.fields(cls)}
        return cls(**{k: (tuple(v) if k == "seeds" else v) for k, v in data.items() if k in known})


def _with_settings_added_since(stored: dict[str, Any], config: DeepConfig) -> dict[str, Any]:
    """``config.json`` of a run with the method's settings added since it was written, at their defaults: a
    setting is added with the default that keeps what the method did before (PPO's ``value_loss``, DQN's
    ``optimizer``), so an older run still reads as the configuration it was."""
    resolved = stored.get("resolved")
    if not isinstance(resolved, dict):
        return stored
    defaults = _json_round_trip(_jsonable(dataclasses.asdict(type(config.method_config())())))
    return {**stored, "resolved": {**{k: v for k, v in defaults.items() if k not in resolved}, **resolved}}


def _jsonable(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _jsonable(v) for k, v in value.items()}
    if isinstance(value, tuple):
        return list(value)
    return value


@dataclass
class DeepResults:
    """Every seed of one deep configuration: its episodes, evaluations, final parameters and how the run went."""

    content_files: ClassVar[tuple[str, ...]] = rundir.DEEP_CONTENT_FILES
    """The files of its run directory beside ``meta.json``."""

    config: DeepConfig
    episodes: pd.DataFrame
    """One row per seed x training episode, in the order they ended: ``env_step`` (environment steps of the
    seed's training when it ended, over all parallel environments), ``return``, ``length``, ``terminated``."""
    evaluations: pd.DataFrame
    """One row per seed x round x greedy episode; ``after_step``: the training steps before the round."""
    params: dict[str, np.ndarray]
    """Each parameter's path in the method's parameter tree (``jax.tree_util.keystr``) -> its array, with a
    leading seed axis."""
    meta: dict[str, Any]
    snapshots: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)
    """Each earlier stage of learning (:data:`~rlcompare.deep.rollout.STAGES`) -> its parameters, as ``params``
    (empty for a run written before deep runs kept them)."""

    @property
    def seeds(self) -> tuple[int, ...]:
        return self.config.seeds

    @property
    def stages(self) -> list[str]:
        """The stages of learning whose networks this run keeps, in order, ``final`` last."""
        return [*self.snapshots, "final"]

    def stacked_params(self, template: Any, stage: str = "final") -> Any:
        """Every seed's parameters at ``stage`` in the tree shape of ``template`` (the method's own,
        :func:`params_template`), with a leading seed axis; a name the stored file lacks is a
        :class:`~rlcompare.experiment.store.StoreError`, a stage the run lacks a :class:`KeyError`."""
        if stage not in self.stages:
            raise KeyError(f"stage {stage!r} is not in this run; stages: {self.stages}")
        stored = self.params if stage == "final" else self.snapshots[stage]
        paths, tree = jax.tree_util.tree_flatten_with_path(template)
        names = [jax.tree_util.keystr(path) for path, _ in paths]
        missing = [name for name in names if name not in stored]
        if missing or len(names) != len(stored):
            raise store.StoreError(f"{rundir.PARAMS_FILE}: its parameters are not those of {self.config.algorithm}'s "
                                   f"network (missing {missing[:3]}, {len(stored)} stored, {len(names)} expected)")
        return jax.tree_util.tree_unflatten(tree, [stored[name] for name in names])

    def seed_params(self, seed: int, template: Any, stage: str = "final") -> Any:
        """One seed's parameters (see :meth:`stacked_params`)."""
        if seed not in self.seeds:
            raise KeyError(f"seed {seed} is not in this run; seeds: {list(self.seeds)}")
        index = self.seeds.index(seed)
        return jax.tree.map(lambda leaf: leaf[index], self.stacked_params(template, stage))

    def save(self, run_dir: Path) -> Path:
        """Write the run directory (:func:`~rlcompare.experiment.rundir.write_run`)."""
        labels = {"study": self.meta.get("study", ""), "env": self.config.env, "algorithm": self.config.algorithm,
                  "schedule": self.config.preset}
        return rundir.write_run(run_dir, self.config.to_dict(), {
            rundir.EPISODES_FILE: _parquet_bytes(_table(self.episodes, labels)),
            rundir.EVALUATIONS_FILE: _parquet_bytes(_table(self.evaluations, labels)),
            rundir.PARAMS_FILE: _npz_bytes({**self.params, **_stage_arrays(self.snapshots),
                                             "seeds": np.asarray(self.seeds)}),
        }, self.meta, {"seeds": list(self.seeds)})

    @classmethod
    def load(cls, run_dir: Path, expected: DeepConfig | None = None) -> DeepResults:
        """Read a finished deep run directory after checking that its files belong together (and hold
        ``expected`` where given); anything else is a :class:`~rlcompare.experiment.store.StoreError`."""
        run_dir = Path(run_dir)
        meta, stored = rundir.read_run(run_dir, cls.content_files)
        try:
            config = DeepConfig.from_dict(stored)
        except (ValueError, TypeError) as error:
            raise store.StoreError(f"{run_dir / rundir.CONFIG_FILE}: {error}") from None
        stored = _with_settings_added_since(stored, config)
        if expected is not None and _json_round_trip(expected.to_dict()) != stored:
            raise store.StoreError(f"{run_dir / rundir.CONFIG_FILE}: another configuration than the one asked for")
        if _json_round_trip(config.to_dict()) != stored:
            raise store.StoreError(f"{run_dir / rundir.CONFIG_FILE}: its hyperparameters are not what its preset "
                                   "gives now (written by another version of rlcompare); run it again")
        try:
            episodes = pd.read_parquet(run_dir / rundir.EPISODES_FILE)
            evaluations = pd.read_parquet(run_dir / rundir.EVALUATIONS_FILE)
            with np.load(run_dir / rundir.PARAMS_FILE, allow_pickle=False) as arrays:
                params = {key: arrays[key] for key in arrays.files}
        except Exception as error:
            raise store.StoreError(f"{run_dir}: cannot read the stored records ({store.cut(str(error), 200)})"
                                   ) from None
        seeds = params.pop("seeds", np.array([])).tolist()
        params, snapshots = _split_stages(params)
        if seeds != list(config.seeds) or set(episodes["seed"]) - set(seeds):
            raise store.StoreError(f"{run_dir}: the seeds of {rundir.PARAMS_FILE} or {rundir.EPISODES_FILE} differ "
                                   f"from those of {rundir.CONFIG_FILE}")
        columns = ["seed", "episode", "env_step", "return", "length", "terminated"]
        return cls(config, episodes[columns].reset_index(drop=True),
                   evaluations[["seed", "round", "after_step", "return", "length", "terminated"]].reset_index(
                       drop=True), params, meta, snapshots)


def merge_seeds(parts: list[DeepResults]) -> DeepResults:
    """One :class:`DeepResults` from runs of one configuration on other seeds (a sweep's one-seed trials), the
    seeds in the order of ``parts``; wall-clock and compile seconds are summed."""
    first = parts[0]
    seeds = tuple(seed for part in parts for seed in part.seeds)
    timings = dict(first.meta["timings"])
    for key in ("wall_seconds", "compile_seconds"):
        timings[key] = sum(part.meta["timings"][key] for part in parts)
    wall = timings["wall_seconds"]
    timings["steps_per_second"] = timings["training_steps"] * len(seeds) / wall if wall > 0 else None
    return DeepResults(dataclasses.replace(first.config, seeds=seeds),
                       pd.concat([part.episodes for part in parts], ignore_index=True),
                       pd.concat([part.evaluations for part in parts], ignore_index=True),
                       _concatenated([part.params for part in parts]),
                       {**first.meta, "seeds": list(seeds), "timings": timings},
                       {stage: _concatenated([part.snapshots[stage] for part in parts]) for stage in first.snapshots
                        if all(stage in part.snapshots for part in parts)})


def _concatenated(arrays: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    return {name: np.concatenate([part[name] for part in arrays]) for name in arrays[0]}


STAGE_SEPARATOR = ":"
"""``params.npz`` names an earlier stage's array ``<stage>:<path>`` (a path starts with ``[``)."""


def _stage_arrays(snapshots: dict[str, dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    return {f"{stage}{STAGE_SEPARATOR}{name}": array for stage, arrays in snapshots.items()
            for name, array in arrays.items()}


def _split_stages(stored: dict[str, np.ndarray]) -> tuple[dict[str, np.ndarray], dict[str, dict[str, np.ndarray]]]:
    """``params.npz``'s arrays as ``(final parameters, {stage: parameters})``, in the order they were written."""
    final: dict[str, np.ndarray] = {}
    snapshots: dict[str, dict[str, np.ndarray]] = {}
    for name, array in stored.items():
        stage, separator, path = name.partition(STAGE_SEPARATOR)
        if separator and not stage.startswith("["):
            snapshots.setdefault(stage, {})[path] = array
        else:
            final[name] = array
    return final, snapshots


def _json_round_trip(data: dict) -> dict:
    return json.loads(json.dumps(data))


def _table(frame: pd.DataFrame, labels: dict[str, Any]):
    return _with_labels({name: frame[name].to_numpy() for name in frame.columns}, labels, len(frame))


def _npz_bytes(arrays: dict[str, np.ndarray]) -> bytes:
    buffer = io.BytesIO()
    np.savez_compressed(buffer, **arrays)
    return buffer.getvalue()


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
def compiled_program(algorithm: str, env: str, method_config: Any, eval_rounds: int, eval_episodes: int,
                     width: int) -> Callable[[jax.Array], TrainOutput]:
    """The jitted, vmapped training of ``width`` seeds, lowered and compiled for ``width`` keys; kept for the
    process (``cache_info()`` counts the runs that found it)."""
    environment = jax_env(env)
    train = deep_method(algorithm).module.make_train(method_config, environment, eval_rounds, eval_episodes)
    if is_batched(environment):  # one seed, its emulator's callbacks outside any vmap
        return jax.jit(lambda keys: jax.tree.map(lambda x: x[None], train(keys[0]))).lower(seed_keys((0,))).compile()
    return jax.jit(jax.vmap(train)).lower(seed_keys((0,) * width)).compile()


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
    """A training that fits in this machine's memory, refused after compiling and before the first step (a
    :class:`ConfigError` naming ``total_steps`` where the records are the larger part, else ``vmap_width``)."""
    training, records = memory_needed(config, compiled)
    memory = physical_memory()
    if training + records <= memory:
        return
    name, value = ("total_steps", config.method_config().total_steps) if records > training else (
        "vmap_width", config.vmap_width)
    raise ConfigError(name, value, f"a training that fits in memory: {config.name} on {len(config.seeds)} seeds, "
                      f"{config.vmap_width} side by side, needs {gib(training)} while training and "
                      f"{gib(records)} for its records; this machine has {gib(memory)}")


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


def run(config: DeepConfig, *, out: Path | None = None, study: str = "",
        progress: Callable[[int], None] | None = None) -> DeepResults:
    """Train every seed of ``config``; write the run directory to ``out`` if given. ``progress`` is called with
    the number of seeds finished since its last call."""
    if out is None:
        return _train(config, study, progress)
    with store.output_directory(Path(out), store.RUN):
        results = _train(config, study, progress)
        results.save(out)
    return results


@float64
def _train(config: DeepConfig, study: str, progress: Callable[[int], None] | None) -> DeepResults:
    use_compilation_cache()
    started = time.perf_counter()
    train = compiled_training(config)
    compile_seconds = time.perf_counter() - started
    check_memory(config, train)
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
    meta = {
        "study": study, "name": config.name, "engine": "deep", "seeds": list(config.seeds),
        "created": datetime.now(timezone.utc).isoformat(timespec="seconds"), "command": sys.argv,
        "timings": {"compile_seconds": compile_seconds, "wall_seconds": wall, "training_steps": steps,
                    "steps_per_second": steps * len(config.seeds) / wall if wall > 0 else None,
                    "device": str(jax.devices()[0])},
        "versions": {**versions(), **{pkg: package_version(pkg) for pkg in ("jax", "flax", "optax")}},
    }
    snapshots = {stage: _named_arrays(jax.tree.map(lambda leaf, i=index: leaf[:, i], output.snapshots))
                 for index, (stage, _) in enumerate(rollout.STAGES)}
    return DeepResults(config, episodes_frame(config.seeds, output),
                       evaluations_frame(config.seeds, output, steps_per_round), _named_arrays(output.params), meta,
                       snapshots)


def _named_arrays(tree: Any) -> dict[str, np.ndarray]:
    """A parameter tree's leaves by their path (``jax.tree_util.keystr``)."""
    leaves = jax.tree_util.tree_flatten_with_path(tree)[0]
    return {jax.tree_util.keystr(path): np.asarray(leaf) for path, leaf in leaves}
