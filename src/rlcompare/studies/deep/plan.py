"""What ``rlcompare reproduce deep`` trains and can decide (its ``--plan``): classic control's environments, their
margins, the deep methods and the tabular pair beside them, read by the study (:mod:`rlcompare.studies.deep.study`)
and by ``--plan`` without the report's modules.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import TYPE_CHECKING

from rlcompare.deep.methods import DEEP_METHODS
from rlcompare.studies.interface import listed
from rlcompare.studies.margins import margin
from rlcompare.studies.paired_plan import Key, PairedStudy, Plan, checked, paired_plan
from rlcompare.studies.plans import StudyPlan
from rlcompare.studies.registry import DeepOptions
from rlcompare.tabular.config import ExperimentConfig

if TYPE_CHECKING:
    from rlcompare.stats.compare import Paired
    from rlcompare.tabular.results import Results

STUDY = "deep"
ENVS = ("CartPole-v1", "Acrobot-v1", "MountainCar-v0")
MARGIN = {env: margin("deep", f"{env} (final greedy return)") for env in ENVS}
"""Differences of mean return smaller than this count as no difference (5% of each environment's return range,
:data:`rlcompare.studies.margins.MARGINS`), declared before any run."""
DEFAULT_WORKERS = max(1, min(4, os.cpu_count() or 1))
"""Deep configurations trained at once: one compiled program keeps about 1.3 of 2 cores busy, and two at a time
finish a study in about half the time here (each one's results depend on its configuration alone)."""
TABULAR_PAIR = ("sarsa", "q_learning")
METRIC_NAMES = {"greedy_return": "final greedy return", "greedy_auc": "area under the greedy curve"}


def columns(key: Key) -> dict[str, str]:
    return {"env": key.env, "engine": key.engine, "metric": METRIC_NAMES[key.metric]}


def tabular_pair(env: str, tabular: Mapping[str, Results]) -> dict[Key, Paired]:
    """SARSA against Q-Learning in a table on ``env`` (final greedy return), where both ran on the same seeds."""
    from rlcompare.stats.compare import compare_paired  # where a report reads the runs: not for --plan
    from rlcompare.studies.measures import per_seed_metrics

    on, off = (tabular.get(f"tabular-{name}-{env}") for name in TABULAR_PAIR)
    if on is None or off is None or on.seeds != off.seeds:
        return {}
    a, b = (per_seed_metrics(results)["greedy_return"].to_numpy() for results in (on, off))
    return {Key(env, "table"): compare_paired(a, b, MARGIN[env])}


DEEP = PairedStudy(STUDY, ENVS, MARGIN, columns, label=lambda method: DEEP_METHODS[method].label,
                   method_order=tuple(DEEP_METHODS), tasks="environments", digits=1, metrics=tuple(METRIC_NAMES),
                   others=tabular_pair, others_per_env=1)
"""Classic control, each environment's margin, the network's two metrics and the tabular pair beside."""


def plan_of(options: DeepOptions) -> Plan:
    """The study's plan from its options; an unknown method or environment, or steps no method can train in, is a
    :class:`~rlcompare.validation.ConfigError` naming the option."""
    seeds, envs = options.seed_range, listed("envs", options.envs, ENVS)
    tabular = {f"tabular-{algorithm}-{env}": ExperimentConfig(algorithm=algorithm, env=env, seeds=seeds,
                                                              episodes=options.episodes)
               for env in envs for algorithm in TABULAR_PAIR}
    return checked(Plan(seeds, listed("methods", options.methods, tuple(DEEP_METHODS)), {env: env for env in envs},
                        options.steps, options.workers or DEFAULT_WORKERS, beside=tabular))


def study_plan(options: DeepOptions) -> StudyPlan:
    """What the study trains and can decide (``reproduce deep --plan``)."""
    return paired_plan(DEEP, plan_of(options))
