"""The paper's tables and claims, answered over seeds.

Table I (time to converge) and Table II (mean cumulative reward) get one row per configuration, with
95% bootstrap intervals over seeds and the paper's printed value beside ours. Each claim of the paper
becomes a paired comparison of SARSA against Q-Learning on the same seeds, which share start states
(common random numbers), with a verdict.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from rlcompare.analysis.convergence import convergence_episodes, episodes_to_seconds
from rlcompare.analysis.explain import first_action_shares
from rlcompare.analysis.stats import (
    interval,
    paired_difference,
    probability_of_improvement,
    rank_test,
    verdict,
)
from rlcompare.envs import mountain_car
from rlcompare.envs.discretize import make_grid
from rlcompare.experiment.results import Results

LEFT = 0


def seconds_per_step(results: Results) -> float:
    """CPU seconds one run spends per step: the run's wall time times its threads over all steps."""
    timings = results.meta["timings"]
    steps = timings["training_steps"] + timings["evaluation_steps"]
    return timings["wall_seconds"] * timings["threads"] / steps


def per_seed_metrics(results: Results) -> pd.DataFrame:
    """One row per seed: the numbers every table, verdict and figure is built from."""
    records, config = results.records, results.config
    converged = convergence_episodes(records.returns, window=min(100, config.episodes), max_steps=config.max_steps)
    has_eval = records.eval_returns.shape[1] > 0
    final_q = results.records.snapshots[:, -1]
    grid = make_grid(mountain_car.OBSERVATION_LOW, mountain_car.OBSERVATION_HIGH, config.bins)
    return pd.DataFrame({
        "seed": np.asarray(results.seeds),
        "behaviour_return": records.returns.mean(axis=1),
        "greedy_return": records.eval_returns[:, -1].mean(axis=1) if has_eval else np.nan,
        "greedy_success": records.eval_terminated[:, -1].mean(axis=1) if has_eval else np.nan,
        "convergence_episode": converged,
        "convergence_seconds": episodes_to_seconds(converged, records.lengths, seconds_per_step(results)),
        "first_action_left": first_action_shares(final_q, grid)[:, LEFT],
    })


def _fmt(estimate, digits: int = 1) -> str:
    return estimate.format(digits) if not np.isnan(estimate.value) else "n/a"


def table_i(metrics: dict[str, pd.DataFrame], paper: dict[str, float]) -> pd.DataFrame:
    """Time to converge: episodes and seconds, mean [95% CI] over converged seeds, and how many never did."""
    rows = []
    for name, m in metrics.items():
        done = m.dropna(subset=["convergence_episode"])
        rows.append({
            "configuration": name,
            "episodes to converge": _fmt(interval(done["convergence_episode"].to_numpy()), 0)
            if len(done) else "n/a",
            "seconds to converge": _fmt(interval(done["convergence_seconds"].to_numpy()), 3) if len(done) else "n/a",
            "never converged": f"{len(m) - len(done)} of {len(m)}",
            "paper (Table I)": paper.get(name, ""),
        })
    return pd.DataFrame(rows)


def table_ii(metrics: dict[str, pd.DataFrame], paper: dict[str, float]) -> pd.DataFrame:
    """Mean cumulative reward: behaviour and greedy returns, mean and IQM with 95% intervals."""
    rows = []
    for name, m in metrics.items():
        behaviour, greedy = m["behaviour_return"].to_numpy(), m["greedy_return"].to_numpy()
        rows.append({
            "configuration": name,
            "behaviour mean": _fmt(interval(behaviour)),
            "behaviour IQM": _fmt(interval(behaviour, statistic="iqm")),
            "greedy mean": _fmt(interval(greedy)) if np.isfinite(greedy).all() else "n/a",
            "greedy IQM": _fmt(interval(greedy, statistic="iqm")) if np.isfinite(greedy).all() else "n/a",
            "greedy success": f"{np.mean(m['greedy_success']):.0%}" if np.isfinite(greedy).all() else "n/a",
            "paper (Table II)": paper.get(name, ""),
        })
    return pd.DataFrame(rows)


@dataclass(frozen=True)
class Claim:
    """A sentence of the paper, and the paired comparison that tests it."""

    text: str
    schedule: str
    metric: str
    sarsa_higher: bool
    """Whether the claim says SARSA's value of ``metric`` is the higher one."""


def judge(claims: list[Claim], metrics: dict[str, pd.DataFrame], episodes: int) -> pd.DataFrame:
    """SARSA minus Q-Learning on the same seeds, for every claim: difference, P(improvement), p, verdict.

    A run that never converged counts as converging at the last episode (a censored value, which only
    understates the gap when the faster method is the one that converged).
    """
    rows = []
    for claim in claims:
        sarsa = metrics[f"sarsa-{claim.schedule}"].sort_values("seed")
        q = metrics[f"q_learning-{claim.schedule}"].sort_values("seed")
        if not np.array_equal(sarsa["seed"], q["seed"]):
            raise ValueError(f"{claim.schedule}: SARSA and Q-Learning were run on different seeds")
        a, b = sarsa[claim.metric].to_numpy(), q[claim.metric].to_numpy()
        if claim.metric == "convergence_episode":
            a, b = np.nan_to_num(a, nan=episodes), np.nan_to_num(b, nan=episodes)
        sign = 1 if claim.sarsa_higher else -1
        difference = paired_difference(a, b)
        p_value = rank_test(a, b, paired=True)
        better = probability_of_improvement(a, b) if claim.sarsa_higher else probability_of_improvement(b, a)
        rows.append({
            "claim": claim.text,
            "metric": claim.metric,
            "SARSA": float(np.mean(a)),
            "Q-Learning": float(np.mean(b)),
            "SARSA - Q-Learning": _fmt(difference, 2),
            "P(claim holds for a random pair of seeds)": _fmt(better, 2),
            "Wilcoxon p": p_value,
            "verdict": verdict(difference, p_value, sign),
        })
    return pd.DataFrame(rows)
