"""The paper's experiment: random baseline, Q-Learning and SARSA under ε constant and ε decaying.

"Comparative Analysis of On and Off Policy Reinforcement Learning", Sections IV and V: MountainCar-v0,
20 bins per dimension, α = 0.05, γ = 0.9, a 1000-step limit, ε = 0.5 constant or decaying from 1.
One run directory per configuration under the study's output directory.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rlcompare.stats.design import SIGNED_RANK
from rlcompare.studies.interface import UI, Report
from rlcompare.studies.plans import Question, StudyPlan, episodic
from rlcompare.studies.registry import PaperOptions
from rlcompare.tabular.config import ExperimentConfig

if TYPE_CHECKING:  # a plan imports this module: pandas and the engine only once something trains
    import pandas as pd

    from rlcompare.tabular.results import Results

STUDY = "paper"
DEFAULT_EPISODES = 5000

PAPER_ALGORITHMS = ("q_learning", "sarsa")
ORDER_ABLATION = (("q_learning", "before_update"), ("sarsa", "after_update"))
"""Q-Learning drawing A' before its update and SARSA drawing it after: with the paper's two boxes, the four
cells of target x order that split SARSA minus Q-Learning into order, target and interaction
(:mod:`rlcompare.studies.paper.why`)."""


def paper_configs(
    seeds: tuple[int, ...], episodes: int = DEFAULT_EPISODES, algorithms: tuple[str, ...] = PAPER_ALGORITHMS,
    **overrides: Any,
) -> list[ExperimentConfig]:
    """The paper's configurations, in the order of its tables, baseline first: each algorithm under ε
    decaying and ε constant with the paper's settings (Q-Learning and SARSA by default; any other
    algorithm adds its row to Tables I and II). Then, where both are run, the two cells that separate
    SARSA's target from its order of choosing A' (:data:`ORDER_ABLATION`), for each schedule."""
    base = ExperimentConfig(seeds=seeds, episodes=episodes, **overrides)
    ablation = set(PAPER_ALGORITHMS) <= set(algorithms)
    return [
        replace(base, algorithm="random", schedule="constant"),
        *(replace(base, algorithm=algorithm, schedule=schedule)
          for algorithm in algorithms for schedule in ("decay", "constant")),
        *(replace(base, algorithm=algorithm, schedule=schedule, next_action=order)
          for algorithm, order in ORDER_ABLATION if ablation for schedule in ("decay", "constant")),
    ]


def reproduce(
    out: Path,
    configs: list[ExperimentConfig],
    *,
    progress: Callable[[int], None] | None = None,
    study: str = STUDY,
    force: bool = False,
) -> Iterator[tuple[Results, bool]]:
    """The paper's configurations into ``out``, one run directory each named after its configuration
    (:func:`rlcompare.experiment.runner.run_or_load`); yields ``(results, reused)``."""
    from rlcompare.experiment.runner import run_or_load

    for _, results, reused in run_or_load(Path(out), {c.name: c for c in configs}, study=study, progress=progress,
                                          force=force):
        yield results, reused


def summary(results: Iterable[Results], *, paper: bool) -> tuple[pd.DataFrame, str, str]:
    """Each configuration's mean behaviour and greedy return over seeds with 95% intervals (beside the paper's
    Table II where ``paper``): the table, its title and its caption."""
    from rlcompare.studies.measures import PAPER_TABLE_II, per_seed_metrics, table_ii  # scipy: after training

    frame = table_ii({r.config.name: per_seed_metrics(r) for r in results}, PAPER_TABLE_II if paper else {})
    columns = ["configuration", "behaviour mean", "greedy mean", "greedy success"]
    return (frame[[*columns, "paper (Table II)"] if paper else columns],
            "Mean cumulative reward over seeds [95% bootstrap interval]",
            "behaviour: ε-greedy return averaged over all training episodes; greedy: return of the final greedy "
            "policy; success: its episodes that reached the goal")


@dataclass(frozen=True)
class PaperStudy:
    """The paper's configurations on ``env`` (its own grid and step limit, ``docs/environments.md``), and their
    report: the ``paper``, ``cartpole`` and ``acrobot`` studies."""

    env: str

    def run(self, out: Path, options: PaperOptions, ui: UI, *, study: str, force: bool = False
            ) -> dict[str, Results]:
        configs = paper_configs(options.seed_range, options.episodes, options.learners, env=self.env)
        runs = {}
        with ui.tasks({self.env: sum(c.episodes for c in configs)}) as advance:
            for results, reused in reproduce(out, configs, progress=lambda n: advance(self.env, n), study=study,
                                             force=force):
                runs[results.config.name] = results
                ui.done(results.config.name, results, reused)
        ui.table(*summary(runs.values(), paper=self.env == "MountainCar-v0"))
        return runs

    def study_plan(self, options: PaperOptions) -> StudyPlan:
        """What the study trains and can decide: the paper's claims, one family on paired seeds."""
        from rlcompare.studies.paper.claims import claims_asked
        from rlcompare.studies.start_region import has_start_region

        configs = paper_configs(options.seed_range, options.episodes, options.learners, env=self.env)
        claims = claims_asked({c.name for c in configs}, has_start_region(configs[0]))
        questions = (Question(f"SARSA against Q-Learning on the paper's {len(claims)} claims", SIGNED_RANK,
                              options.seeds, len(claims)),) if claims else ()
        return StudyPlan(episodic({c.name: c for c in configs}), questions)

    def report(self, out: Path, ui: UI, *, runs: dict[str, Results] | None = None, videos: bool = True) -> Report:
        """Tables, verdicts, figures, videos and ``report.html`` (:mod:`rlcompare.studies.paper.report`)."""
        from rlcompare.studies.paper.report import build_report  # matplotlib: once the runs are trained

        with ui.working("Building the report"):
            return build_report(out, videos=videos)


MOUNTAIN_CAR, CARTPOLE, ACROBOT = PaperStudy("MountainCar-v0"), PaperStudy("CartPole-v1"), PaperStudy("Acrobot-v1")
