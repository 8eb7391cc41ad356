"""rlcompare: run, measure and explain comparisons of reinforcement-learning algorithms.

The names below are imported when first used, so that ``import rlcompare.cli`` (``rlcompare --help``) stays
light. Numba's cache still points at this version's directory before any kernel module is compiled: the first
import of numba, whoever makes it, runs :mod:`rlcompare._numba_cache` as soon as numba is loaded.
"""

from __future__ import annotations

import contextlib
import importlib
import importlib.abc
import importlib.util
import sys
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from rlcompare.experiment.config import ConfigError, ExperimentConfig
    from rlcompare.experiment.engines import load_agent
    from rlcompare.experiment.engines import load_run as load
    from rlcompare.experiment.results import Results
    from rlcompare.experiment.runner import run

__all__ = ["ConfigError", "ExperimentConfig", "Results", "load", "load_agent", "run"]

_EXPORTS = {"ConfigError": ("rlcompare.experiment.config", "ConfigError"),
            "ExperimentConfig": ("rlcompare.experiment.config", "ExperimentConfig"),
            "Results": ("rlcompare.experiment.results", "Results"),
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


class _ThenNumbaCache(importlib.abc.Loader):
    """Numba's own loader, then :mod:`rlcompare._numba_cache` (which sets ``numba.config.CACHE_DIR``) before the
    module that imported numba goes on to define its kernels."""

    def __init__(self, loader: importlib.abc.Loader) -> None:
        self.loader = loader

    def create_module(self, spec: Any) -> Any:
        return self.loader.create_module(spec)

    def exec_module(self, module: Any) -> None:
        module.__loader__ = module.__spec__.loader = self.loader  # numba sees its own loader
        self.loader.exec_module(module)
        importlib.import_module("rlcompare._numba_cache")


class _NumbaCacheOnImport(importlib.abc.MetaPathFinder):
    """Finds nothing itself: on the first import of numba it steps aside and hands numba's spec back with
    :class:`_ThenNumbaCache` as its loader."""

    def find_spec(self, name: str, path: Any = None, target: Any = None) -> Any:
        if name != "numba":
            return None
        with contextlib.suppress(ValueError):
            sys.meta_path.remove(self)
        spec = importlib.util.find_spec(name)
        if spec is not None and spec.loader is not None:
            spec.loader = _ThenNumbaCache(spec.loader)
        return spec


if "numba" in sys.modules:
    importlib.import_module("rlcompare._numba_cache")
elif not any(isinstance(finder, _NumbaCacheOnImport) for finder in sys.meta_path):
    sys.meta_path.insert(0, _NumbaCacheOnImport())
