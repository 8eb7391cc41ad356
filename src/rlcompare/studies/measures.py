"""The numbers every table, verdict and figure of a tabular study is built from, seed by seed: the returns, the
share of greedy episodes that solved the task, when a run converged and under which rule, the first greedy
action from the start region and its noise floor; and the paper's Tables I and II over them."""

from __future__ import annotations

import numpy as np
import pandas as pd

from rlcompare.stats.convergence import (
    DEFAULT_RULE,
    RULES,
    Rule,
    convergence_episodes,
    convergence_on_rounds,
    episodes_to_seconds,
)
from rlcompare.stats.intervals import interval
from rlcompare.stats.metrics import returns_per_seed
from rlcompare.stats.significance import NoiseFloor, noise_floor
from rlcompare.studies.start_region import final_first_action_shares, has_start_region, start_region_cells
from rlcompare.tabular.results import Results

PAPER_TABLE_I = {"q_learning-decay": 41.5, "q_learning-constant": 13.8, "sarsa-decay": 10.7,
                 "sarsa-constant": 11.5}
"""Table I, "time to converge", as printed (no unit or rule is given)."""
PAPER_TABLE_II = {"q_learning-decay": -191.0, "q_learning-constant": -262.0, "sarsa-decay": -174.0,
                  "sarsa-constant": -176.0}
"""Table II, mean cumulative reward, as printed."""
LEFT = 0


def seconds_per_step(results: Results) -> float:
    """CPU seconds one run spends per step: the run's wall time times its threads over all steps."""
    timings = results.meta["timings"]
    steps = timings["training_steps"] + timings["evaluation_steps"]
    return float(timings["wall_seconds"] * timings["threads"] / steps)


def solved(rule: str, returns: np.ndarray, lengths: np.ndarray, terminated: np.ndarray, max_steps: int
           ) -> np.ndarray:
    """Which episodes solved the task, by the environment's rule: ``terminated`` (reached the goal),
    ``truncated`` (survived to the step limit, as on CartPole), ``positive_return`` (FrozenLake) or ``won``
    (a chess endgame mated: terminated, without the cost of a lost piece)."""
    if rule == "won":
        return np.asarray(terminated, dtype=bool) & (returns >= -max_steps)
    if rule == "truncated":
        return ~terminated & (lengths >= max_steps)
    if rule == "positive_return":
        return returns > 0
    return np.asarray(terminated, dtype=bool)


def _readable(results: Results, rule: Rule) -> bool:
    """Whether the runs hold the curve ``rule`` reads: behaviour always, greedy when rounds fill a window."""
    if rule.curve == "behaviour":
        return True
    rounds, config = results.records.eval_returns.shape[1], results.config
    return bool(rounds > 0 and rounds >= max(1, round(min(rule.window, config.episodes) / config.eval_every)))


def convergence(results: Results, rule: Rule = DEFAULT_RULE) -> np.ndarray:
    """``(seeds,)`` episodes to converge under ``rule`` (window capped at the episodes run), NaN for never;
    all NaN when the rule reads a greedy curve the runs did not record or that is shorter than its window.
    The greedy curve is each round's mean greedy return; a round counts as solved when most of its episodes are."""
    records, config = results.records, results.config
    window, limit = min(rule.window, config.episodes), config.step_limit
    if not _readable(results, rule):
        return np.full(len(results.seeds), np.nan)
    if rule.curve == "behaviour":
        return convergence_episodes(records.returns, window=window, tolerance=rule.tolerance, max_steps=limit,
                                    solved=solved(config.environment.success, records.returns, records.lengths,
                                                  records.terminated, limit))
    greedy_solved = solved(config.environment.success, records.eval_returns, records.eval_lengths,
                           records.eval_terminated, limit).mean(axis=2) >= 0.5
    return convergence_on_rounds(records.eval_returns.mean(axis=2), config.eval_every, window=window,
                                 tolerance=rule.tolerance, max_steps=limit, solved=greedy_solved)


def convergence_by_rule(results: Results, rules: tuple[Rule, ...] = RULES) -> pd.DataFrame:
    """One row per seed (``seed``), one column per rule (its name): episodes to converge, NaN for never.
    A rule the runs cannot be read under (no greedy curve) has no column."""
    return pd.DataFrame({"seed": np.asarray(results.seeds)}
                        | {rule.name: convergence(results, rule) for rule in rules if _readable(results, rule)})


def first_action_floor(results: Results) -> NoiseFloor:
    """The noise floor of the first greedy action: final action values in the cells of the start region,
    each cell weighted by its share of start states (:func:`~rlcompare.stats.significance.noise_floor`)."""
    return noise_floor(results.records.snapshots[:, -1][:, start_region_cells(results.config)])


def noise_floors(runs: dict[str, Results]) -> dict[str, NoiseFloor]:
    """:func:`first_action_floor` of each learning configuration with a start region, by name."""
    return {name: first_action_floor(r) for name, r in runs.items()
            if has_start_region(r.config) and r.config.algorithm != "random"}


def per_seed_metrics(results: Results) -> pd.DataFrame:
    """One row per seed: the numbers every table, verdict and figure is built from: the returns
    (:func:`~rlcompare.stats.metrics.returns_per_seed`), the share of greedy episodes solved, when the run
    converged, and the first greedy action from the start region where the environment has one (NaN elsewhere)."""
    records, config = results.records, results.config
    rule = config.environment.success
    converged = convergence(results, DEFAULT_RULE)
    has_eval = records.eval_returns.shape[1] > 0
    greedy_success = solved(rule, records.eval_returns[:, -1], records.eval_lengths[:, -1],
                            records.eval_terminated[:, -1], config.step_limit).mean(axis=1) if has_eval else np.nan
    first_left = (final_first_action_shares(results)[:, LEFT] if has_start_region(config)
                  else np.full(len(results.seeds), np.nan))
    return returns_per_seed(results.seeds, records.returns, records.eval_returns).assign(
        greedy_success=greedy_success,
        convergence_episode=converged,
        convergence_seconds=episodes_to_seconds(converged, records.lengths, seconds_per_step(results)),
        first_action_left=first_left,
    )


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
            "episodes to converge": interval(done["convergence_episode"].to_numpy()).format(0)
            if len(done) else "n/a",
            "censored at the last episode": interval(censored).format(0),
            "seconds to converge": interval(done["convergence_seconds"].to_numpy()).format(3) if len(done) else "n/a",
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
            "behaviour mean": interval(behaviour).format(),
            "behaviour IQM": interval(behaviour, statistic="iqm").format(),
            "greedy mean": interval(greedy).format() if np.isfinite(greedy).all() else "n/a",
            "greedy IQM": interval(greedy, statistic="iqm").format() if np.isfinite(greedy).all() else "n/a",
            "greedy success": f"{np.mean(m['greedy_success']):.0%}" if np.isfinite(greedy).all() else "n/a",
            "paper (Table II)": _paper(paper, name),
        })
    return pd.DataFrame(rows)
