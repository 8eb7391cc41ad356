"""rlcompare: run, measure and explain comparisons of reinforcement-learning algorithms."""

from rlcompare.experiment.agent import load_agent
from rlcompare.experiment.config import ConfigError, ExperimentConfig
from rlcompare.experiment.results import Results
from rlcompare.experiment.runner import load, run

__all__ = ["ConfigError", "ExperimentConfig", "Results", "load", "load_agent", "run"]
