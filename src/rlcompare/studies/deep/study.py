"""``rlcompare reproduce deep``: the paper's question asked again with neural networks, as its future work asks.

A configuration of the paired study (:mod:`rlcompare.studies.paired`). On CartPole-v1, Acrobot-v1 and
MountainCar-v0 (Gymnasium's limits), every deep method trains on paired seeds: Q(λ), SARSA(λ) and Expected
SARSA(λ) in one PQN-style engine whose only switch is the bootstrap, DQN and Double DQN, PPO. Beside them, the
tabular pair (Q-Learning, SARSA) on the same environments with the paper's settings. The report draws learning
curves against environment steps and against seconds, tabulates the final greedy return in Gymnasium's own
environment and in the port and the area under the curve (mean and IQM with 95% intervals), the probability of
improvement on paired seeds, and judges "on-policy against off-policy target" per environment, with and without a
network. Over two or more environments it adds rliable's aggregates of the deep methods, and it sets published
numbers (rl-baselines3-zoo, cleanrl) beside its own.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from rlcompare.deep.agent import gymnasium_returns
from rlcompare.deep.methods import DEEP_METHODS
from rlcompare.deep.results import DeepResults
from rlcompare.experiment import store
from rlcompare.report.page import Section, write_report, write_table
from rlcompare.stats import intervals as stats
from rlcompare.studies.deep.plan import DEEP, MARGIN, STUDY, plan_of
from rlcompare.studies.deep.plan import study_plan as study_plan
from rlcompare.studies.interface import UI, Report
from rlcompare.studies.paired import eval_curves, per_seed, seconds_per_step, train
from rlcompare.studies.paired_plan import RANDOM_EPISODES
from rlcompare.studies.paired_report import PQN_PAIR, Findings, curves_drawn, findings
from rlcompare.studies.registry import DeepOptions

SCORE = {"CartPole-v1": 475.0, "Acrobot-v1": -100.0, "MountainCar-v0": -130.0}
"""The score whose first reaching, in environment steps and seconds, the report times."""
GOAL = {"CartPole-v1": 490.0, "Acrobot-v1": -85.0, "MountainCar-v0": -115.0}
"""The greedy return in Gymnasium's own environment that the study sets out to reach with the best method."""
GYMNASIUM_EPISODES = 10
"""Episodes of each seed's final greedy policy in Gymnasium's own environment, from the same start states."""


@dataclass(frozen=True)
class Anchor:
    """A published number to read ours against, with what it is."""

    env: str
    method: str
    value: float
    source: str


ANCHORS = (
    Anchor("CartPole-v1", "dqn", 500.0, "rl-baselines3-zoo benchmark: one trained agent"),
    Anchor("CartPole-v1", "ppo", 500.0, "rl-baselines3-zoo benchmark: one trained agent"),
    Anchor("Acrobot-v1", "dqn", -76.6, "rl-baselines3-zoo benchmark: one trained agent"),
    Anchor("Acrobot-v1", "ppo", -73.5, "rl-baselines3-zoo benchmark: one trained agent"),
    Anchor("MountainCar-v0", "dqn", -100.8, "rl-baselines3-zoo benchmark: one trained agent"),
    Anchor("MountainCar-v0", "ppo", -110.4, "rl-baselines3-zoo benchmark: one trained agent"),
    *(Anchor(env, method, value, f"cleanrl {method}.py docs: episodic return at the end of training, 3 seeds")
      for env, method, value in (("CartPole-v1", "dqn", 488.69), ("Acrobot-v1", "dqn", -91.54),
                                 ("MountainCar-v0", "dqn", -194.95), ("CartPole-v1", "ppo", 490.04),
                                 ("Acrobot-v1", "ppo", -86.36), ("MountainCar-v0", "ppo", -200.0))),
)



def run(out: Path, options: DeepOptions, ui: UI, *, study: str = STUDY, force: bool = False) -> dict[str, Any]:
    """The tabular pair, then every deep configuration, trained (or loaded) into ``out``."""
    plan = plan_of(options)
    ui.say(f"Training {len(plan.configs())} deep configurations x {len(plan.seeds)} seeds; each compiles its program "
           "first (10-40 s, once per machine).")
    return train(out, STUDY, plan, ui, force=force)


def to_score(results: DeepResults) -> pd.DataFrame:
    """:func:`~rlcompare.studies.paired.per_seed`, with the environment steps and seconds at which each seed's
    greedy curve first reached the environment's score."""
    steps, curves = eval_curves(results)
    reached = curves >= SCORE[results.config.env]
    first = np.where(reached.any(axis=1), steps[reached.argmax(axis=1)], np.nan)
    return per_seed(results).assign(steps_to_score=first, seconds_to_score=first * seconds_per_step(results))


def summary_table(deep: dict[str, DeepResults], gymnasium: dict[str, np.ndarray]) -> pd.DataFrame:
    """Per environment and method: the final greedy return in Gymnasium's own environment and in the port's
    evaluation, the area under the curve (mean and IQM, 95% intervals), the seeds that reached the score, and
    the median steps and seconds to reach it."""
    rows = []
    for name, results in deep.items():
        metrics = to_score(results)
        reached = metrics["steps_to_score"].notna()
        in_gymnasium = gymnasium[name].mean(axis=1)
        rows.append({
            "env": results.config.env, "method": DEEP_METHODS[results.config.algorithm].label,
            "Gymnasium, IQM": stats.interval(in_gymnasium, "iqm").format(1),
            "Gymnasium, mean": stats.interval(in_gymnasium).format(1),
            "seeds at the goal": f"{int((in_gymnasium >= GOAL[results.config.env]).sum())}/{len(in_gymnasium)}",
            "final, IQM": stats.interval(metrics["greedy_return"].to_numpy(), "iqm").format(1),
            "AUC, mean": stats.interval(metrics["greedy_auc"].to_numpy()).format(1),
            "reached score": f"{int(reached.sum())}/{len(metrics)}",
            "median steps to score": float(metrics["steps_to_score"].median()) if reached.any() else np.nan,
            "median seconds to score": float(metrics["seconds_to_score"].median()) if reached.any() else np.nan,
            "steps/s": results.meta["timings"]["steps_per_second"],
        })
    return pd.DataFrame(rows)


def anchor_table(deep: dict[str, DeepResults], gymnasium: dict[str, np.ndarray]) -> pd.DataFrame:
    """The published numbers beside ours: each seed's final greedy policy in Gymnasium, IQM over seeds."""
    rows = []
    for anchor in ANCHORS:
        name = f"{anchor.method}-{anchor.env}"
        results = deep.get(name)
        ours = stats.interval(gymnasium[name].mean(axis=1), "iqm").format(1) if results else "not run"
        hidden = " x ".join(map(str, results.config.method_config().hidden)) if results else ""
        rows.append({"env": anchor.env, "method": DEEP_METHODS[anchor.method].label, "published": anchor.value,
                     "what it is": anchor.source, "ours: greedy in Gymnasium, IQM [95% CI]": ours,
                     "our network": hidden})
    return pd.DataFrame(rows)


def aggregate_section(found: Findings) -> Section:
    """rliable's aggregates of the deep methods over the environments (``deep_aggregates.csv``,
    ``deep_improvement.csv`` and the figures), or why there are none: they need two or more environments."""
    title = "Across environments"
    across, drawn = found.across, found.aggregates
    if across is None:
        return Section(title, [f"The aggregates over environments (rliable's) need two or more; this study ran "
                               f"{', '.join(sorted(found.envs)) or 'none'}."])
    if drawn is None:
        return Section(title, ["The aggregates need two or more methods run on two or more environments alike."])
    seeds = next(iter(across.scores.values())).shape[1]
    return Section(title, [
        f"The deep methods over {len(across.envs)} environments ({', '.join(across.envs)}) x {seeds} seeds, as "
        "rliable defines its aggregates (Agarwal et al. 2021, \"Deep Reinforcement Learning at the Edge of the "
        "Statistical Precipice\"), drawn here. Each seed's final greedy return (the last evaluation round, in the "
        "port) is normalised environment by environment between a uniformly random policy's mean return (0; "
        f"{RANDOM_EPISODES} episodes in the port: "
        + ", ".join(f"{env} {floor:.1f}" for env, floor in across.floors.items())
        + ") and the best deep method's mean here (1), so 1 is the best this study reached, not the environment's "
        "best. Median and mean are of each environment's mean over seeds; IQM, optimality gap (γ = 1) and the "
        "profiles pool every seed of every environment; intervals and bands are 95% stratified bootstrap ones "
        "(seeds resampled within each environment). The tabular pair is left out: its runs count episodes, not "
        "environment steps. "
        + (f"Sample efficiency: the IQM at each evaluation round, against the {across.xlabel}." if across.curves else
           "No sample-efficiency curves: the trainings were evaluated at different shares of their steps.")],
        [("Aggregates of normalised final returns", drawn.intervals, found.files["aggregates"]),
         ("Probability of improvement", drawn.improvements, found.files["improvement"])], drawn.figures)


def report(out: Path, ui: UI | None = None, *, runs: dict[str, Any] | None = None, videos: bool = True) -> Report:
    """Tables, verdicts, figures and ``report.html`` of a deep study directory, from its run directories (it draws
    no videos)."""
    with store.rewriting(Path(out), "study"):
        return _build_report(Path(out))


def _build_report(out: Path) -> Report:
    found = findings(out, DEEP)
    gymnasium = {name: gymnasium_returns(results, GYMNASIUM_EPISODES) for name, results in found.runs.items()}
    summary, anchors = summary_table(found.runs, gymnasium), anchor_table(found.runs, gymnasium)
    for name, frame in (("deep_summary", summary), ("deep_anchors", anchors)):
        write_table(frame, out / "tables", name)
    curve_figures = [curves_drawn(found.runs, env, against, out / "figures" / f"curves-{env}-{against}.png", against)
                     for env in found.envs for against in ("steps", "seconds")]
    lines = [f"{row.env}, {row.engine}, {row.metric}: {row.verdict}" for row in found.verdicts.itertuples()]
    sections = [
        Section("On-policy or off-policy target, with a network and in a table",
                [f"{PQN_PAIR}; SARSA against Q-Learning in a table with the paper's settings. Margins of no "
                 f"difference, declared before the runs: {', '.join(f'{e} ±{m:g}' for e, m in MARGIN.items())}. "
                 "p-values Holm-adjusted over the whole table."], [("Verdicts", found.verdicts)]),
        Section("Every method", [
            f"Gymnasium: each seed's final greedy policy in Gymnasium's own environment (gym.make), "
            f"{GYMNASIUM_EPISODES} episodes from the same start states for every seed and method; at the goal: seeds "
            f"whose mean reaches {', '.join(f'{e} {g:g}' for e, g in GOAL.items())}. Final: the greedy return of "
            "the last evaluation round in the port; AUC: its mean over all rounds. Seeds that failed count in "
            "every number."], [("Summary", summary)]),
        aggregate_section(found),
        Section("Published anchors", ["The zoo's numbers are one trained agent each; ours are IQMs over seeds."],
                [("Anchors", anchors)]),
        Section("Learning curves", figures=curve_figures),
    ]
    path = write_report(out / "report.html", "On- vs off-policy with neural networks", sections, found.problems)
    return Report(path, lines, found.problems)
