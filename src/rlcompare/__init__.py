"""rlcompare: run, measure and explain comparisons of reinforcement-learning algorithms.

The names below are imported when first used, so that ``import rlcompare.cli`` (``rlcompare --help``) stays
light.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from rlcompare.experiment.engines import load_agent
    from rlcompare.experiment.engines import load_run as load
    from rlcompare.experiment.runner import run
    from rlcompare.tabular.config import ExperimentConfig
    from rlcompare.tabular.results import Results
    from rlcompare.validation import ConfigError

__all__ = ["ConfigError", "ExperimentConfig", "Results", "load", "load_agent", "run"]

_EXPORTS = {"ConfigError": ("rlcompare.validation", "ConfigError"),
            "ExperimentConfig": ("rlcompare.tabular.config", "ExperimentConfig"),
            "Results": ("rlcompare.tabular.results", "Results"),
            "load": ("rlcompare.experiment.engines", "load_run"),
            "load_agent": ("rlcompare.experiment.engines", "load_agent"),
            "run": ("rlcompare.experiment.runner", "run")}


def __getattr__(name: str) -> Any:
    if name not in _EXPORTS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    module, attribute = _EXPORTS[name]
    value = getattr(importlib.import_module(module), attribute)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})
