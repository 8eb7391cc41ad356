"""Every deep method, one entry each, and the named presets of their hyperparameters (sources in ``docs/deep.md``).

A method is a module (:mod:`~rlcompare.deep.pqn`, :mod:`~rlcompare.deep.dqn`, :mod:`~rlcompare.deep.ppo`) and the
settings that make it that method; each module has a frozen config class, ``PRESETS`` (preset name -> environment
-> config), ``make_train(config, env, rounds, eval_episodes)``, ``act(config, env)`` and ``network(config, env)``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from types import ModuleType
from typing import Any

from rlcompare.deep import dqn, ppo, pqn
from rlcompare.validation import ConfigError


@dataclass(frozen=True)
class DeepMethod:
    """A deep method: which engine trains it, with which settings fixed."""

    name: str
    label: str
    module: ModuleType
    fixed: dict[str, Any]
    """Settings that make the module this method (PQN's bootstrap target, DQN's double estimator)."""
    policy: str
    """``off-policy`` or ``on-policy``: the side of the paper's question the method stands on."""
    tabular: str
    """The tabular method it asks the paper's question again for (``""`` if none)."""


DEEP_METHODS = {m.name: m for m in (
    DeepMethod("pqn_q_lambda", "Q(λ), network", pqn, {"target": "max"}, "off-policy", "q_lambda"),
    DeepMethod("pqn_sarsa_lambda", "SARSA(λ), network", pqn, {"target": "sample"}, "on-policy", "sarsa_lambda"),
    DeepMethod("pqn_expected_sarsa_lambda", "Expected SARSA(λ), network", pqn, {"target": "expected"}, "on-policy",
               "expected_sarsa"),
    DeepMethod("dqn", "DQN", dqn, {"double": False}, "off-policy", "q_learning"),
    DeepMethod("double_dqn", "Double DQN", dqn, {"double": True}, "off-policy", "double_q_learning"),
    DeepMethod("ppo", "PPO", ppo, {}, "on-policy", ""),
)}


def deep_method(name: str) -> DeepMethod:
    if not isinstance(name, str) or name not in DEEP_METHODS:
        raise ConfigError("algorithm", name, ", ".join(DEEP_METHODS))
    return DEEP_METHODS[name]


def presets(name: str) -> tuple[str, ...]:
    """The preset names of a method."""
    return tuple(deep_method(name).module.PRESETS)


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
        raise ConfigError(f"hyperparameters.{unknown[0]}", overrides[unknown[0]],
                          f"the fields of {type(base).__name__}: {', '.join(sorted(fields - set(chosen.fixed)))}")
    fixed = sorted(set(overrides) & set(chosen.fixed))
    if fixed:
        raise ConfigError(f"hyperparameters.{fixed[0]}", overrides[fixed[0]],
                          f"{chosen.fixed[fixed[0]]!r} only: {name} is defined by it")
    return dataclasses.replace(base, **chosen.fixed, **{k: _typed(base, k, v) for k, v in overrides.items()})


def _typed(base: Any, field_name: str, value: Any) -> Any:
    """``value`` as the field's own type (JSON's lists as tuples, whole numbers as floats where a float is
    wanted); a value of another kind is a :class:`ConfigError` naming the field."""
    current = getattr(base, field_name)
    name = f"hyperparameters.{field_name}"
    if isinstance(current, bool):
        ok = isinstance(value, bool)
    elif isinstance(current, int):
        ok = isinstance(value, int) and not isinstance(value, bool)
    elif isinstance(current, float):
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
        value = float(value) if ok else value
    elif isinstance(current, tuple):
        ok = isinstance(value, (list, tuple)) and all(isinstance(v, int) and not isinstance(v, bool) for v in value)
        value = tuple(value) if ok else value
    else:
        ok = isinstance(value, type(current))
    if not ok:
        raise ConfigError(name, value, f"a value like {current!r} ({type(current).__name__})")
    return value
