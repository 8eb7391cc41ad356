"""Every deep method, one entry each, and the named presets of their hyperparameters (sources in ``docs/deep.md``).

A method is a module that offers :class:`MethodModule` (:mod:`~rlcompare.deep.pqn`, :mod:`~rlcompare.deep.dqn`,
:mod:`~rlcompare.deep.ppo`), and the settings that make it that method (:class:`DeepMethod`). Adding one is a module
and an entry in :data:`DEEP_METHODS`; nothing else lists the methods (``docs/extending.md``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Protocol

import flax.linen as nn
import jax

from rlcompare.deep import dqn, munchausen, ppo, pqn
from rlcompare.deep.envs import Environment
from rlcompare.deep.rollout import Act, TrainOutput
from rlcompare.validation import ConfigError, UnknownKey, is_flag, is_integer, plain, require


class MethodModule(Protocol):
    """What a deep method's module offers; a type checker holds every module in :data:`DEEP_METHODS` to it."""

    @property
    def Config(self) -> type[Any]:
        """Its frozen settings, validated on creation (a :class:`~rlcompare.validation.ConfigError` names a bad
        one)."""
        ...

    @property
    def PRESETS(self) -> Mapping[str, Mapping[str, Any]]:
        """Preset name -> environment -> settings, each with its source."""
        ...

    def make_train(self, config: Any, env: Environment, rounds: int, eval_episodes: int
                   ) -> Callable[[jax.Array], TrainOutput]:
        """``key -> TrainOutput``: one seed's whole training in ``rounds`` rounds, each ended by a greedy evaluation
        of ``eval_episodes`` episodes; jit-able and vmap-able over keys. Building it validates the settings against
        the environment and cheaply (closures only)."""
        ...

    def act(self, config: Any, env: Environment) -> Act:
        """``(params, observations) -> actions``: the greedy policy of trained parameters."""
        ...

    def scores(self, config: Any, env: Environment) -> Callable[..., jax.Array]:
        """``(params, observations) -> (batch, n_actions)``: what the greedy policy maximises (Q-values, or the
        policy's logits)."""
        ...

    def network(self, config: Any, env: Environment) -> nn.Module:
        """The network whose parameters it learns."""
        ...


@dataclass(frozen=True)
class DeepMethod:
    """A deep method: which engine trains it, with which settings fixed."""

    name: str
    label: str
    module: MethodModule
    fixed: dict[str, Any]
    """Settings that make the module this method (PQN's bootstrap target, DQN's double estimator)."""
    policy: str
    """``off-policy`` or ``on-policy``: the side of the paper's question the method stands on."""
    tabular: str
    """The tabular method it asks the paper's question again for (``""`` if none)."""


DEEP_METHODS = {m.name: m for m in (
    DeepMethod("pqn_q_lambda", "Q(λ), network", pqn, {"target": "max"}, "off-policy", "q_lambda"),
    DeepMethod("pqn_sarsa_lambda", "SARSA(λ), network", pqn, {"target": "sample"}, "on-policy", "sarsa_lambda"),
    DeepMethod("pqn_watkins_q_lambda", "Watkins's Q(λ), network", pqn, {"target": "watkins"}, "off-policy",
               "q_lambda"),
    DeepMethod("pqn_q_learning", "Q-learning (λ = 0), network", pqn, {"target": "max", "lam": 0.0}, "off-policy",
               "q_learning"),
    DeepMethod("pqn_sarsa", "SARSA (λ = 0), network", pqn, {"target": "sample", "lam": 0.0}, "on-policy", "sarsa"),
    DeepMethod("pqn_expected_sarsa_lambda", "Expected SARSA(λ), network", pqn, {"target": "expected"}, "on-policy",
               "expected_sarsa"),
    DeepMethod("dqn", "DQN", dqn, {"double": False}, "off-policy", "q_learning"),
    DeepMethod("double_dqn", "Double DQN", dqn, {"double": True}, "off-policy", "double_q_learning"),
    DeepMethod("munchausen_dqn", "Munchausen DQN", munchausen, {"double": False}, "off-policy", "q_learning"),
    DeepMethod("ppo", "PPO", ppo, {}, "on-policy", ""),
)}


def deep_method(name: str) -> DeepMethod:
    if not isinstance(name, str) or name not in DEEP_METHODS:
        raise ConfigError("algorithm", name, ", ".join(DEEP_METHODS))
    return DEEP_METHODS[name]


def presets(name: str) -> tuple[str, ...]:
    """The preset names of a method."""
    return tuple(deep_method(name).module.PRESETS)


INT32_MAX = 2**31 - 1
"""The largest count a setting may give: steps, buffers and indices are JAX int32s."""
FLOAT32_MAX = 3.4028234663852886e38
"""The largest magnitude a setting may give: the networks and returns are float32 (``np.finfo(np.float32).max``)."""


def hyperparameters(name: str, env: str, preset: str, overrides: dict[str, Any]) -> Any:
    """The method's validated config: the preset for ``env``, the method's fixed settings, then ``overrides``."""
    chosen = deep_method(name)
    table = chosen.module.PRESETS
    if not isinstance(preset, str) or preset not in table:
        raise ConfigError("preset", preset, ", ".join(table))
    if env not in table[preset]:
        raise ConfigError("env", env, ", ".join(table[preset]))
    base = table[preset][env]
    fields = {f.name for f in dataclasses.fields(base)}
    unknown = sorted(set(overrides) - fields)
    if unknown:
        raise UnknownKey(f"hyperparameters.{unknown[0]}", f"the fields of {type(base).__name__}: "
                         f"{', '.join(sorted(fields - set(chosen.fixed)))}")
    fixed = sorted(set(overrides) & set(chosen.fixed))
    if fixed:
        raise ConfigError(f"hyperparameters.{fixed[0]}", overrides[fixed[0]],
                          f"{chosen.fixed[fixed[0]]!r} only: {name} is defined by it")
    return dataclasses.replace(base, **chosen.fixed, **{k: _typed(base, k, v) for k, v in overrides.items()})


def _typed(base: Any, field_name: str, value: Any) -> Any:
    """``value`` as the field's own type (JSON's lists as tuples, whole numbers as floats where a float is
    wanted, NumPy's scalars as Python's); a value of another kind is a :class:`ConfigError` naming the field."""
    current, value = getattr(base, field_name), plain(value)
    allowed = f"a value like {current!r} ({type(current).__name__})"
    if isinstance(current, bool):
        ok = is_flag(value)
    elif isinstance(current, int):
        ok = is_integer(value) and abs(value) <= INT32_MAX
        allowed = f"an integer of at most {INT32_MAX:,} in size (the engine counts in int32)"
    elif isinstance(current, float):
        ok = is_integer(value) or isinstance(value, float)
        ok = ok and (not math.isfinite(value) or abs(value) <= FLOAT32_MAX)  # NaN and infinities: the method's
        allowed = f"a number of at most {FLOAT32_MAX:.3g} in size (the engine computes in float32)"
        value = float(value) if ok else value
    elif isinstance(current, tuple):
        ok = isinstance(value, list | tuple) and all(is_integer(v) and abs(v) <= INT32_MAX for v in value)
        allowed = f"a list of integers of at most {INT32_MAX:,} in size (int32), like {list(current)}"
        value = tuple(plain(v) for v in value) if ok else value
    else:
        ok = isinstance(value, type(current))
    require(ok, f"hyperparameters.{field_name}", value, allowed)
    return value
