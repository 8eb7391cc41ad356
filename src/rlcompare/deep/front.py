"""The deep engine's front (:mod:`rlcompare.experiment.engines`): JAX networks, one jitted program per
configuration that vmaps over seeds (:mod:`rlcompare.deep.train`)."""

from __future__ import annotations

import dataclasses
from typing import Any

from rlcompare.deep.agent import agent
from rlcompare.deep.config import DeepConfig as Config
from rlcompare.deep.methods import hyperparameters
from rlcompare.deep.results import DeepResults as Results
from rlcompare.deep.results import merge_seeds as merge
from rlcompare.deep.train import train
from rlcompare.validation import ConfigError

__all__ = ["FIXED_IN_SWEEP", "NESTED", "SWEEP_KEYS", "Config", "Results", "agent", "merge", "sweep_config", "train"]

SWEEP_KEYS = ("algorithm", "env", "preset", "eval_rounds", "eval_episodes")
"""What a sweep file may set, beside the method's hyperparameters (:data:`NESTED`)."""
NESTED = "hyperparameters"
"""The table of a sweep file whose keys are the method's hyperparameters: ``hyperparameters.lam = [0.0, 0.9]``."""
FIXED_IN_SWEEP = {"vmap_width": "fixed at 1 in a sweep (each trial trains one seed)"}
"""Fields a sweep may not set, with the reason."""
PREFIX = NESTED + "."


def sweep_config(values: dict[str, Any], seeds: tuple[int, ...]) -> Config:
    """One seed's configuration of a sweep, ``hyperparameters.NAME`` flat in ``values``; hyperparameters the preset
    already has are dropped, so that a configuration has one hash however it is written. A method's own check
    names its hyperparameter (``hyperparameters.lam``)."""
    fields = {f.name for f in dataclasses.fields(Config)}
    overrides = {key.removeprefix(PREFIX): value for key, value in values.items() if key.startswith(PREFIX)}
    given = {key: value for key, value in values.items() if not key.startswith(PREFIX)}
    try:
        config = Config(**given, hyperparameters=overrides, seeds=seeds, vmap_width=1)
    except ConfigError as error:  # a method's own checks name its field alone: lam, total_steps
        if error.field_name in fields or error.field_name.startswith(PREFIX):
            raise
        name = error.field_name
        raise ConfigError(PREFIX + name, overrides.get(name, error.value), error.allowed) from None
    resolved, preset = config.method_config(), hyperparameters(config.algorithm, config.env, config.preset, {})
    kept = {key: getattr(resolved, key) for key in overrides if getattr(resolved, key) != getattr(preset, key)}
    return dataclasses.replace(config, hyperparameters=kept)
