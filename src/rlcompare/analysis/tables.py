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
from rlcompare.analysis.explain import final_first_action_shares, on_position_velocity_grid
from rlcompare.analysis.stats import (
    equivalence_verdict,
    interval,
    paired_difference,
    probability_of_improvement,
    rank_test,
    ratio_of_means,
    ratio_verdict,
    verdict,
)
from rlcompare.experiment.results import Results

LEFT = 0


def seconds_per_step(results: Results) -> float:
    """CPU seconds one run spends per step: the run's wall time times its threads over all steps."""
    timings = results.meta["timings"]
    steps = timings["training_steps"] + timings["evaluation_steps"]
    return timings["wall_seconds"] * timings["threads"] / steps


def solved(rule: str, returns: np.ndarray, lengths: np.ndarray, terminated: np.ndarray, max_steps: int
           ) -> np.ndarray:
    """Which episodes solved the task, by the environment's rule: ``terminated`` (reached the goal),
    ``truncated`` (survived to the step limit, as on CartPole) or ``positive_return`` (FrozenLake)."""
    if rule == "truncated":
        return ~terminated & (lengths >= max_steps)
    if rule == "positive_return":
        return returns > 0
    return np.asarray(terminated, dtype=bool)


def per_seed_metrics(results: Results) -> pd.DataFrame:
    """One row per seed: the numbers every table, verdict and figure is built from. The first greedy
    action from the start states is Mountain Car's (NaN elsewhere)."""
    records, config = results.records, results.config
    rule = config.environment.success
    converged = convergence_episodes(records.returns, window=min(100, config.episodes), max_steps=config.max_steps,
                                     solved=solved(rule, records.returns, records.lengths, records.terminated,
                                                   config.max_steps))
    has_eval = records.eval_returns.shape[1] > 0
    greedy_solved = solved(rule, records.eval_returns[:, -1], records.eval_lengths[:, -1],
                           records.eval_terminated[:, -1], config.max_steps) if has_eval else None
    first_left = (final_first_action_shares(results)[:, LEFT] if on_position_velocity_grid(config)
                  else np.full(len(results.seeds), np.nan))
    return pd.DataFrame({
        "seed": np.asarray(results.seeds),
        "behaviour_return": records.returns.mean(axis=1),
        "greedy_return": records.eval_returns[:, -1].mean(axis=1) if has_eval else np.nan,
        "greedy_success": greedy_solved.mean(axis=1) if has_eval else np.nan,
        "convergence_episode": converged,
        "convergence_seconds": episodes_to_seconds(converged, records.lengths, seconds_per_step(results)),
        "first_action_left": first_left,
    })


def _fmt(estimate, digits: int = 1) -> str:
    return estimate.format(digits) if not np.isnan(estimate.value) else "n/a"


def _paper(paper: dict[str, float], name: str) -> str:
    return f"{paper[name]:g}" if name in paper else ""


def table_i(metrics: dict[str, pd.DataFrame], paper: dict[str, float], episodes: int) -> pd.DataFrame:
    """Time to converge: episodes and seconds, mean [95% CI] over converged seeds, how many never did, and
    the episodes with those counted at the last episode (a censored mean, free of the selection)."""
    rows = []
    for name, m in metrics.items():
        done = m.dropna(subset=["convergence_episode"])
        censored = m["convergence_episode"].fillna(episodes).to_numpy()
        rows.append({
            "configuration": name,
            "episodes to converge": _fmt(interval(done["convergence_episode"].to_numpy()), 0)
            if len(done) else "n/a",
            "censored at the last episode": _fmt(interval(censored), 0),
            "seconds to converge": _fmt(interval(done["convergence_seconds"].to_numpy()), 3) if len(done) else "n/a",
            "never converged": f"{len(m) - len(done)} of {len(m)}",
            "paper (Table I)": _paper(paper, name),
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
            "paper (Table II)": _paper(paper, name),
        })
    return pd.DataFrame(rows)


@dataclass(frozen=True)
class Claim:
    """A sentence of the paper, and the comparison over seeds that tests it.

    ``kind`` says what is tested on ``metric`` under ``schedule``:

    - ``direction``: SARSA minus Q-Learning on the same seeds has the sign ``sign``;
    - ``ratio``: Q-Learning's mean over SARSA's is about ``value``;
    - ``same``: SARSA and Q-Learning differ by less than ``value`` (an equivalence margin);
    - ``level``: ``method``'s mean lies on side ``sign`` of ``value``.
    """

    text: str
    schedule: str
    metric: str
    kind: str = "direction"
    sign: int = 1
    value: float = 0.0
    method: str = "sarsa"


def _paired(metrics: dict[str, pd.DataFrame], claim: Claim, episodes: int) -> tuple[np.ndarray, np.ndarray]:
    sarsa = metrics[f"sarsa-{claim.schedule}"].sort_values("seed")
    q = metrics[f"q_learning-{claim.schedule}"].sort_values("seed")
    if not np.array_equal(sarsa["seed"], q["seed"]):
        raise ValueError(f"{claim.schedule}: SARSA and Q-Learning were run on different seeds")
    a, b = sarsa[claim.metric].to_numpy(), q[claim.metric].to_numpy()
    if claim.metric == "convergence_episode":
        a, b = np.nan_to_num(a, nan=episodes), np.nan_to_num(b, nan=episodes)
    return a, b


def _judge_one(claim: Claim, metrics: dict[str, pd.DataFrame], episodes: int) -> dict[str, object]:
    a, b = _paired(metrics, claim, episodes)
    row: dict[str, object] = {"claim": claim.text, "metric": claim.metric, "SARSA": float(np.mean(a)),
                              "Q-Learning": float(np.mean(b))}
    if claim.kind == "direction":
        difference, p_value = paired_difference(a, b), rank_test(a, b, paired=True)
        better = probability_of_improvement(a, b) if claim.sign > 0 else probability_of_improvement(b, a)
        return row | {"test": "SARSA - Q-Learning", "estimate": _fmt(difference, 2),
                      "P(claim holds for a random pair)": _fmt(better, 2), "Wilcoxon p": p_value,
                      "verdict": verdict(difference, p_value, claim.sign)}
    if claim.kind == "ratio":
        ratio = ratio_of_means(b, a)
        return row | {"test": f"Q-Learning / SARSA, about {claim.value:.2g}?", "estimate": _fmt(ratio, 2),
                      "Wilcoxon p": rank_test(a, b, paired=True), "verdict": ratio_verdict(ratio, claim.value)}
    if claim.kind == "same":
        difference = paired_difference(a, b)
        return row | {"test": f"|SARSA - Q-Learning| < {claim.value:g}", "estimate": _fmt(difference, 2),
                      "verdict": equivalence_verdict(difference, claim.value)}
    values = a if claim.method == "sarsa" else b
    reference = np.full_like(values, claim.value)
    shift = paired_difference(values, reference)
    p_value = rank_test(values, reference, paired=True)
    side = ">" if claim.sign > 0 else "<"
    return row | {"test": f"{LABEL[claim.method]} {side} {claim.value:g}", "estimate": _fmt(shift, 2),
                  "Wilcoxon p": p_value, "verdict": verdict(shift, p_value, claim.sign)}


LABEL = {"sarsa": "SARSA", "q_learning": "Q-Learning"}


def judge(claims: list[Claim], metrics: dict[str, pd.DataFrame], episodes: int) -> pd.DataFrame:
    """Every claim tested on the same seeds of SARSA and Q-Learning, with its verdict.

    A run that never converged counts as converging at the last episode (a censored value, which can
    only understate the gap in favour of the method that converged).
    """
    columns = ["claim", "metric", "SARSA", "Q-Learning", "test", "estimate", "P(claim holds for a random pair)",
               "Wilcoxon p", "verdict"]
    return pd.DataFrame([_judge_one(c, metrics, episodes) for c in claims], columns=columns)
