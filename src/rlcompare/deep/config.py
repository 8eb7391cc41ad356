"""One deep configuration: a method, an environment, a preset of the method's hyperparameters and the seeds.

Seeds train ``vmap_width`` at a time, the last group padded with copies of its first seed: XLA batches the
matrix products of a vmap by its width, so a seed's numbers depend on the width (by about 1e-7 after twenty
updates) but not on which seeds train beside it or how many a user asks for.
"""

from __future__ import annotations

import dataclasses
import functools
import json
from dataclasses import dataclass, field
from typing import Any, ClassVar

from rlcompare import machine
from rlcompare.deep import pqn
from rlcompare.deep.envs import Environment, is_batched, is_game, jax_env
from rlcompare.deep.methods import DEEP_METHODS, deep_method, hyperparameters
from rlcompare.validation import COUNT, SEEDS_ALLOWED, ConfigError, check_fields, is_seeds, plain, require

FINISHED_BYTES_PER_STEP = 10
"""Bytes every method records per environment step: :class:`~rlcompare.deep.rollout.Finished`'s ``done``,
``returns`` (float32), ``lengths`` (int32) and ``terminated``."""
RECORD_COPIES = 2
"""The device's output and its copy on the host, joined over groups of seeds."""


@dataclass(frozen=True)
class DeepConfig:
    """One deep configuration, run once per seed. Frozen and validated on creation."""

    engine: ClassVar[str] = "deep"
    """The engine that trains it (:mod:`rlcompare.experiment.engines`)."""

    algorithm: str = "pqn_q_lambda"
    """A deep method of :data:`rlcompare.deep.methods.DEEP_METHODS` (``docs/deep.md`` lists them)."""
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
        require(is_seeds(self.seeds), "seeds", self.seeds, SEEDS_ALLOWED)
        object.__setattr__(self, "seeds", tuple(int(seed) for seed in self.seeds))
        for name in ("eval_rounds", "eval_episodes", "vmap_width"):
            object.__setattr__(self, name, plain(getattr(self, name)))
        check_fields(self, {"eval_rounds": COUNT, "eval_episodes": COUNT, "vmap_width": COUNT})
        require(not is_batched(self.environment) or self.vmap_width == 1, "vmap_width", self.vmap_width,
                "1 for an Atari game (its emulator plays one seed's games at a time)")
        require(not is_game(self.environment) or deep_method(self.algorithm).module is pqn, "algorithm",
                self.algorithm, "a PQN method for a two-player game (" + ", ".join(
                    name for name, method in DEEP_METHODS.items() if method.module is pqn) + "): self-play with "
                "legal-move masks is PQN's alone here")
        require(isinstance(self.hyperparameters, dict), "hyperparameters", self.hyperparameters,
                "a table of field names and values")
        try:
            method_config = self.method_config()
            make_train = deep_method(self.algorithm).module.make_train  # builds closures only: cheap
            make_train(method_config, self.environment, self.eval_rounds, self.eval_episodes)  # validates
        except ConfigError as error:
            least = self.least_total_steps() if error.field_name == "total_steps" else None
            if least is None or not isinstance(error.value, int) or error.value >= least:
                raise
            raise ConfigError("total_steps", error.value, f"at least {least:,}, the fewest that train in each of the "
                              f"{self.eval_rounds} evaluation rounds ({error.allowed})") from None
        self._check_records_fit(method_config.total_steps)

    def least_total_steps(self) -> int | None:
        """The fewest ``total_steps`` this configuration trains with, every other setting as it is: at least one
        update in each evaluation round (the method's own bounds are all lower bounds, so the answer is found by
        halving); None where no number up to 2**40 does, another setting being at fault."""
        def trains(steps: int) -> bool:
            try:
                config = hyperparameters(self.algorithm, self.env, self.preset,
                                         {**self.hyperparameters, "total_steps": steps})
                deep_method(self.algorithm).module.make_train(config, self.environment, self.eval_rounds,
                                                              self.eval_episodes)
                return bool(config.steps_trained(self.eval_rounds) > 0)
            except ConfigError:
                return False

        high = 1
        while not trains(high):
            high *= 2
            if high > 2**40:
                return None
        low = high // 2 + 1
        while low < high:
            middle = (low + high) // 2
            low, high = (low, middle) if trains(middle) else (middle + 1, high)
        return high

    def _check_records_fit(self, total_steps: int) -> None:
        """Refuse, before anything is traced or compiled, a ``total_steps`` whose per-step records alone (in Python
        integers, so no size overflows) exceed this machine's memory: XLA aborts the process on a dimension product
        past 2**63 instead of raising."""
        records = RECORD_COPIES * FINISHED_BYTES_PER_STEP * total_steps * len(self.seeds)
        memory = machine.physical_memory()
        require(records <= memory, "total_steps", total_steps,
                f"a training whose records fit in memory: {len(self.seeds)} seeds x {total_steps:,} steps keep at "
                f"least {machine.gib(records)}; this machine has {machine.gib(memory)}")

    def memory_before_running(self) -> int:
        """Bytes this training is known to hold before it is compiled: the records of every step (kept twice,
        joined over the groups of seeds) and, for a method with a replay buffer, a buffer for each seed trained side
        by side (its observations' shape and dtype traced from the environment, nothing run). The compiled
        program's own figure (:func:`rlcompare.deep.train.memory_needed`), checked before the first step, adds its
        networks and temporaries."""
        import jax
        import numpy as np

        from rlcompare.deep.replay import buffer_bytes

        records = RECORD_COPIES * FINISHED_BYTES_PER_STEP * self.steps_trained * len(self.seeds)
        capacity = getattr(self.method_config(), "buffer_size", 0)
        if not capacity:
            return records
        with jax.enable_x64(True):  # as a training traces its environment (rlcompare.deep.float64): no warning
            observation = _observation(self.env, jax.dtypes.canonicalize_dtype(np.float64))
        return records + min(self.vmap_width, len(self.seeds)) * buffer_bytes(capacity, observation)

    def method_config(self) -> Any:
        """The method's own config: preset, fixed settings and overrides, validated."""
        return hyperparameters(self.algorithm, self.env, self.preset, self.hyperparameters)

    @property
    def environment(self) -> Environment:
        return jax_env(self.env)

    @property
    def name(self) -> str:
        return f"{self.algorithm}-{self.env}"

    @property
    def steps_trained(self) -> int:
        """Environment steps each seed trains: whole batches in each evaluation round, which may be fewer or more
        than its ``total_steps``."""
        return int(self.method_config().steps_trained(self.eval_rounds))

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
        values: dict[str, Any] = {k: (tuple(v) if k == "seeds" else v) for k, v in data.items() if k in known}
        return cls(**values)


@functools.cache
def _observation(env_name: str, widest: Any) -> Any:
    """The shape and dtype of one observation of ``env_name``, traced from its reset (nothing run), once per
    environment and widest float type (64 bits inside :func:`rlcompare.deep.float64`, 32 outside) in a process: a
    plan reads it for each method with a replay buffer."""
    import jax

    from rlcompare.deep.envs import observe_all, reset_all

    env = jax_env(env_name)
    return jax.eval_shape(lambda key: observe_all(env, reset_all(env, key[None]))[0], jax.random.key(0))


def with_settings_added_since(stored: dict[str, Any], config: DeepConfig) -> dict[str, Any]:
    """``config.json`` of a run with the method's settings added since it was written, at their defaults: a
    setting is added with the default that keeps what the method did before (PPO's ``value_loss``, DQN's
    ``optimizer``), so an older run still reads as the configuration it was."""
    resolved = stored.get("resolved")
    if not isinstance(resolved, dict):
        return stored
    defaults = json_round_trip(_jsonable(dataclasses.asdict(type(config.method_config())())))
    return {**stored, "resolved": {**{k: v for k, v in defaults.items() if k not in resolved}, **resolved}}


def _jsonable(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _jsonable(v) for k, v in value.items()}
    if isinstance(value, tuple):
        return list(value)
    return value


def json_round_trip(data: dict[str, Any]) -> dict[str, Any]:
    """``data`` as ``config.json`` gives it back: tuples as lists."""
    return dict(json.loads(json.dumps(data)))
