"""rlcompare: run, measure and explain comparisons of reinforcement-learning algorithms."""

import rlcompare._numba_cache  # noqa: F401 - places numba's cache before any kernel module is imported
from rlcompare.experiment.config import ConfigError, ExperimentConfig
from rlcompare.experiment.engines import load_agent
from rlcompare.experiment.engines import load_run as load
from rlcompare.experiment.results import Results
from rlcompare.experiment.runner import run

__all__ = ["ConfigError", "ExperimentConfig", "Results", "load", "load_agent", "run"]
