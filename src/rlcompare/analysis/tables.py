"""The paper's tables and claims, answered over seeds.

Table I (time to converge) and Table II (mean cumulative reward) get one row per configuration, with
95% bootstrap intervals over seeds and the paper's printed value beside ours. Each claim of the paper
becomes a paired comparison of SARSA against Q-Learning on the same seeds, which share start states
(common random numbers), with a verdict: the claims of one report form a family corrected with Holm's
procedure, equivalence claims are two one-sided tests against a margin, a claim read below its noise
floor is undecidable here, and a convergence verdict is read under several rules and marked fragile where
they disagree (``docs/why.md``, "Verdicts").
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from functools import partial
from typing import NamedTuple

import numpy as np
import pandas as pd

from rlcompare.algorithms.registry import label as method_label
from rlcompare.analysis.compare import compare_paired
from rlcompare.analysis.convergence import (
    DEFAULT_RULE,
    RULES,
    Rule,
    convergence_episodes,
    convergence_on_rounds,
    episodes_to_seconds,
)
from rlcompare.analysis.explain import final_first_action_shares, has_start_region, start_cells
from rlcompare.analysis.metrics import returns_per_seed
from rlcompare.analysis.power import provable_margin
from rlcompare.analysis.stats import (
    ALPHA,
    CONTRADICTED,
    NO_DATA,
    NOT_RESOLVED,
    SUPPORTED,
    UNDECIDABLE,
    NoiseFloor,
    Verdict,
    equivalence_verdict,
    holm,
    holm_factors,
    interval,
    noise_floor,
    paired_difference,
    probability_of_improvement,
    rank_test,
    ratio_tost,
    robust_to_censoring,
    tost,
    verdict,
    worst_case_sign_p,
)
from rlcompare.envs.discretize import make_grid
from rlcompare.envs.features import grid_bounds
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


def _readable(results: Results, rule: Rule) -> bool:
    """Whether the runs hold the curve ``rule`` reads: behaviour always, greedy when rounds fill a window."""
    if rule.curve == "behaviour":
        return True
    rounds, config = results.records.eval_returns.shape[1], results.config
    return rounds > 0 and rounds >= max(1, round(min(rule.window, config.episodes) / config.eval_every))


def convergence(results: Results, rule: Rule = DEFAULT_RULE) -> np.ndarray:
    """``(seeds,)`` episodes to converge under ``rule`` (window capped at the episodes run), NaN for never;
    all NaN when the rule reads a greedy curve the runs did not record or that is shorter than its window.
    The greedy curve is each round's mean greedy return; a round counts as solved when most of its episodes are."""
    records, config = results.records, results.config
    window = min(rule.window, config.episodes)
    if not _readable(results, rule):
        return np.full(len(results.seeds), np.nan)
    if rule.curve == "behaviour":
        return convergence_episodes(records.returns, window=window, tolerance=rule.tolerance,
                                    max_steps=config.max_steps,
                                    solved=solved(config.environment.success, records.returns, records.lengths,
                                                  records.terminated, config.max_steps))
    greedy_solved = solved(config.environment.success, records.eval_returns, records.eval_lengths,
                           records.eval_terminated, config.max_steps).mean(axis=2) >= 0.5
    return convergence_on_rounds(records.eval_returns.mean(axis=2), config.eval_every, window=window,
                                 tolerance=rule.tolerance, max_steps=config.max_steps, solved=greedy_solved)


def convergence_by_rule(results: Results, rules: tuple[Rule, ...] = RULES) -> pd.DataFrame:
    """One row per seed (``seed``), one column per rule (its name): episodes to converge, NaN for never.
    A rule the runs cannot be read under (no greedy curve) has no column."""
    return pd.DataFrame({"seed": np.asarray(results.seeds)}
                        | {rule.name: convergence(results, rule) for rule in rules if _readable(results, rule)})


def first_action_floor(results: Results) -> NoiseFloor:
    """The noise floor of the first greedy action: final action values in the cells of the start region,
    each cell weighted by its share of start states (:func:`~rlcompare.analysis.stats.noise_floor`)."""
    c = results.config
    cells = start_cells(make_grid(*grid_bounds(c.environment, c.bounds), c.bins), c.environment.start_box)
    return noise_floor(results.records.snapshots[:, -1][:, cells])


def noise_floors(runs: dict[str, Results]) -> dict[str, NoiseFloor]:
    """:func:`first_action_floor` of each learning configuration with a start region, by name."""
    return {name: first_action_floor(r) for name, r in runs.items()
            if has_start_region(r.config) and r.config.algorithm != "random"}


def per_seed_metrics(results: Results) -> pd.DataFrame:
    """One row per seed: the numbers every table, verdict and figure is built from: the returns
    (:func:`~rlcompare.analysis.metrics.returns_per_seed`), the share of greedy episodes solved, when the run
    converged, and the first greedy action from the start region where the environment has one (NaN elsewhere)."""
    records, config = results.records, results.config
    rule = config.environment.success
    converged = convergence(results, DEFAULT_RULE)
    has_eval = records.eval_returns.shape[1] > 0
    greedy_solved = solved(rule, records.eval_returns[:, -1], records.eval_lengths[:, -1],
                           records.eval_terminated[:, -1], config.max_steps) if has_eval else None
    first_left = (final_first_action_shares(results)[:, LEFT] if has_start_region(config)
                  else np.full(len(results.seeds), np.nan))
    return returns_per_seed(results.seeds, records.returns, records.eval_returns).assign(
        greedy_success=greedy_solved.mean(axis=1) if has_eval else np.nan,
        convergence_episode=converged,
        convergence_seconds=episodes_to_seconds(converged, records.lengths, seconds_per_step(results)),
        first_action_left=first_left,
    )


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


CONVERGENCE = "convergence_episode"
RATIO_FACTOR = 1.25
""""About R times" means within ``[R / 1.25, R * 1.25]`` (the 80-125% band of bioequivalence)."""
FRAGILE = " (fragile)"
COLUMNS = ["claim", "metric", "SARSA", "Q-Learning", "test", "estimate", "P(claim holds for a random pair)", "p",
           "p (Holm)", "verdict", "fragile", "censored", "noise floor", "note"]
"""The columns of :func:`judge`'s table, stable for readers of ``verdicts.csv``."""


@dataclass(frozen=True)
class Claim:
    """A sentence of the paper, and the comparison over seeds that tests it.

    ``kind`` says what is tested on ``metric`` under ``schedule``:

    - ``direction``: SARSA minus Q-Learning on the same seeds has the sign ``sign`` (Wilcoxon signed-rank);
    - ``ratio``: Q-Learning over SARSA is about ``value``, within ``[value / 1.25, value * 1.25]`` (TOST on
      per-seed log ratios);
    - ``same``: SARSA and Q-Learning differ by less than ``value``, an equivalence margin (TOST, paired t);
    - ``level``: ``method``'s mean lies on side ``sign`` of ``value`` (Wilcoxon signed-rank).

    ``floor``: the claim reads a greedy choice, and is undecidable where the choice lies below its noise
    floor (``floors`` of :func:`judge`, by configuration).
    """

    text: str
    schedule: str
    metric: str
    kind: str = "direction"
    sign: int = 1
    value: float = 0.0
    method: str = "sarsa"
    floor: bool = False




class _Outcome(NamedTuple):
    """A claim tested, before the family's correction: display columns, the raw p-value, the label as a
    function of the adjusted p-value with the side it puts the claim's quantity on, and what censoring can do."""

    row: dict[str, object]
    p: float
    decide: Callable[[float], tuple[Verdict, int]]
    bias: frozenset[int] = frozenset()
    no_data: str = ""
    worst_case: Callable[[int], float] | None = None
    """``side -> p``: the claim's conclusion on that side tested with every censored seed at its worst
    (:func:`censored_at_worst`); None where nothing was censored."""
    power: str = ""
    """For a margin: that the seeds are too few to prove it (:func:`underpowered`), else empty."""


def _configurations(claim: Claim) -> list[str]:
    if claim.kind == "level":
        return [f"{claim.method}-{claim.schedule}"]
    return [f"sarsa-{claim.schedule}", f"q_learning-{claim.schedule}"]


def _paired(metrics: dict[str, pd.DataFrame], claim: Claim) -> tuple[np.ndarray, np.ndarray]:
    sarsa = metrics[f"sarsa-{claim.schedule}"].sort_values("seed")
    q = metrics[f"q_learning-{claim.schedule}"].sort_values("seed")
    if not np.array_equal(sarsa["seed"], q["seed"]):
        raise ValueError(f"{claim.schedule}: SARSA and Q-Learning were run on different seeds")
    return sarsa[claim.metric].to_numpy(dtype=np.float64), q[claim.metric].to_numpy(dtype=np.float64)


def _censoring(claim: Claim, a: np.ndarray, b: np.ndarray) -> tuple[frozenset[int], str, str]:
    """How censoring can move the claim's quantity, the row's count of censored seeds, and why there is no data.

    For a difference SARSA - Q-Learning a censored SARSA seed can only raise it and a censored Q-Learning seed
    only lower it; for the ratio Q-Learning / SARSA the other way round."""
    if claim.metric != CONVERGENCE:
        return frozenset(), "", ""
    never_a, never_b = int(np.isnan(a).sum()), int(np.isnan(b).sum())
    text = f"SARSA {never_a} of {a.size}, Q-Learning {never_b} of {b.size}"
    up, down = (-1, 1) if claim.kind == "ratio" else (1, -1)
    bias = frozenset(({up} if never_a else set()) | ({down} if never_b else set()))
    if never_a == a.size and never_b == b.size:
        return bias, text, "nothing converged"
    if claim.kind == "ratio" and (never_a == a.size or never_b == b.size):
        side = "SARSA" if never_a == a.size else "Q-Learning"
        return bias, text, f"no seed of {side} converged: the ratio would be read from censored values alone"
    return bias, text, ""


def censored_at_worst(values: np.ndarray, lower: float, upper: float, up: np.ndarray, down: np.ndarray
                      ) -> Callable[[int], float]:
    """``side -> p``: the sign test (:func:`~rlcompare.analysis.stats.worst_case_sign_p`) of a conclusion that puts
    the claim's per-seed quantity below ``lower`` (side -1), above ``upper`` (+1) or inside both (0), with every
    censored seed on the side that would overturn it. ``up``/``down``: the seeds whose value censoring can only
    have lowered/raised."""

    def p(side: int) -> float:
        if side < 0:
            return worst_case_sign_p(values, lower, -1, up, down)
        if side > 0:
            return worst_case_sign_p(values, upper, 1, up, down)
        return max(worst_case_sign_p(values, lower, 1, up, down), worst_case_sign_p(values, upper, -1, up, down))

    return p


def underpowered(differences: np.ndarray, margin_value: float, scale: str = "") -> str:
    """A note where the seeds are too few to prove a margin: the smallest margin two one-sided tests prove four
    times in five at these seeds and this spread (:func:`~rlcompare.analysis.power.provable_margin`, at α before
    any correction, the most it could be) exceeds ``margin_value``, so "supported" is out of reach and the label
    can only be contradicted or not resolved. Empty otherwise."""
    provable = provable_margin(float(np.std(differences, ddof=1)), differences.size) if differences.size > 1 else np.nan
    if not provable > margin_value:
        return ""
    where = f" {scale}" if scale else ""
    return (f"underpowered for its margin: {differences.size} seeds prove ±{provable:.3g}{where} four times in five, "
            f"wider than ±{margin_value:.3g}")


def _direction(difference, p_value: float, sign: int) -> tuple[Verdict, int]:
    label = verdict(difference, p_value, sign)
    return label, (sign if label == SUPPORTED else -sign)


def _equivalence(test, p_value: float) -> tuple[Verdict, int]:
    label = equivalence_verdict(test, p_value)
    side = 0 if test.inside else (1 if test.estimate.value > test.upper else -1)
    return label, side


def _test_text(claim: Claim) -> str:
    """What is tested, in words."""
    side = ">" if claim.sign > 0 else "<"
    if claim.kind == "direction":
        return f"SARSA - Q-Learning {side} 0: Wilcoxon signed-rank"
    if claim.kind == "ratio":
        return (f"Q-Learning / SARSA in [{claim.value / RATIO_FACTOR:.2f}, {claim.value * RATIO_FACTOR:.2f}] "
                f"(about {claim.value:.2g} times): TOST on log ratios")
    if claim.kind == "same":
        return f"|SARSA - Q-Learning| < {claim.value:g}: TOST, paired t"
    return f"{method_label(claim.method)} {side} {claim.value:g}: Wilcoxon signed-rank"


def _test(claim: Claim, metrics: dict[str, pd.DataFrame], episodes: int) -> _Outcome:
    """The claim's test on the seeds (a never-converged run counts at the last episode, ``episodes``)."""
    a, b = _paired(metrics, claim)
    bias, censored, no_data = _censoring(claim, a, b)
    never_a, never_b = np.isnan(a), np.isnan(b)
    if claim.metric == CONVERGENCE:
        a, b = np.nan_to_num(a, nan=episodes), np.nan_to_num(b, nan=episodes)
    row: dict[str, object] = {"claim": claim.text, "metric": claim.metric, "SARSA": float(np.mean(a)),
                              "Q-Learning": float(np.mean(b)), "test": _test_text(claim), "censored": censored}
    if no_data or not (np.isfinite(a).all() and np.isfinite(b).all()):
        return _Outcome(row, np.nan, lambda _: (NO_DATA, 0), bias, no_data or "no finite value to test")
    if claim.kind == "direction":
        paired = compare_paired(a, b)
        better = paired.improvement if claim.sign > 0 else probability_of_improvement(b, a)
        return _Outcome(row | {"estimate": _fmt(paired.difference, 2),
                               "P(claim holds for a random pair)": _fmt(better, 2)},
                        paired.p_value, partial(_direction, paired.difference, sign=claim.sign), bias,
                        worst_case=censored_at_worst(a - b, 0.0, 0.0, never_a, never_b) if bias else None)
    if claim.kind == "ratio":
        test = ratio_tost(b, a, claim.value, RATIO_FACTOR)
        logs = np.log(b / a)
        return _Outcome(row | {"estimate": _fmt(test.estimate, 2)}, test.p, partial(_equivalence, test), bias,
                        worst_case=censored_at_worst(logs, np.log(test.lower), np.log(test.upper), never_b, never_a)
                        if bias else None, power=underpowered(logs, np.log(RATIO_FACTOR), "on the log scale"))
    if claim.kind == "same":
        test = tost(a - b, -claim.value, claim.value)
        return _Outcome(row | {"estimate": _fmt(test.estimate, 2)}, test.p, partial(_equivalence, test), bias,
                        worst_case=censored_at_worst(a - b, -claim.value, claim.value, never_a, never_b)
                        if bias else None, power=underpowered(a - b, claim.value))
    values = a if claim.method == "sarsa" else b
    reference = np.full_like(values, claim.value)
    shift = paired_difference(values, reference)
    return _Outcome(row | {"estimate": _fmt(shift, 2)}, rank_test(values, reference, paired=True),
                    partial(_direction, shift, sign=claim.sign))


def _label(claim: Claim, outcome: _Outcome, p_adjusted: float, holm_factor: float,
           floors: dict[str, NoiseFloor]) -> tuple[Verdict, str, str]:
    """The claim's label, the noise floor it was read against, and a note on what decided it. A label read from
    censored values that censoring could overturn stands only if the sign test with every censored seed at its
    worst rejects too, at the claim's place in Holm's family (its p-value times ``holm_factor``)."""
    label, side = outcome.decide(p_adjusted)
    floor = [(name, floors[name]) for name in _configurations(claim) if claim.floor and name in floors]
    floor_text = "; ".join(f"{name}: {f.format()}" for name, f in floor)
    if label == NO_DATA:
        return NO_DATA, floor_text, outcome.no_data
    below = [name for name, f in floor if f.below]
    if below:
        return UNDECIDABLE, floor_text, f"below the noise floor in {', '.join(below)}: more seeds will not settle it"
    if label != NOT_RESOLVED and not robust_to_censoring(side, outcome.bias):
        worst = max(p_adjusted, min(1.0, holm_factor * outcome.worst_case(side)))
        if not worst < ALPHA:
            return (NOT_RESOLVED, floor_text,
                    f"{label} from censored values: seeds that never converged could overturn it")
        return label, floor_text, (f"{label} whatever the never-converged seeds' true times: the sign test with "
                                   f"each at its worst gives p (Holm) {worst:.2g}")
    return label, floor_text, ""


def _labels(claims: list[Claim], outcomes: list[_Outcome], floors: dict[str, NoiseFloor]
            ) -> tuple[np.ndarray, list[tuple[Verdict, str, str]]]:
    p_values = [o.p for o in outcomes]
    adjusted, factors = holm(p_values), holm_factors(p_values)
    return adjusted, [_label(c, o, p, factor, floors)
                      for c, o, p, factor in zip(claims, outcomes, adjusted, factors, strict=True)]


def _under_rule(metrics: dict[str, pd.DataFrame], rules: dict[str, pd.DataFrame], rule: str
                ) -> dict[str, pd.DataFrame]:
    """``metrics`` with each configuration's convergence episodes replaced by those under ``rule``."""
    replaced = dict(metrics)
    for name, by_rule in rules.items():
        if name in metrics:
            episodes = by_rule.set_index("seed")[rule]
            replaced[name] = metrics[name].assign(**{CONVERGENCE: metrics[name]["seed"].map(episodes).to_numpy()})
    return replaced


DECIDED = (SUPPORTED, CONTRADICTED)


def is_fragile(labels: Iterable[Verdict]) -> bool:
    """Whether a claim's labels under reasonable definitions of its quantity (the convergence rules) disagree: two
    of them decide it opposite ways. A definition under which the data cannot decide (not resolved, no data)
    adds no evidence either way, and is listed beside the label (:func:`labels_by_definition`) but does not make
    it fragile."""
    return len({label for label in labels if label in DECIDED}) > 1


def labels_by_definition(labels: dict[str, Verdict]) -> str:
    """Which definitions give which label, the most common first: ``supported under band 5%, window 50 and
    band 5%, window 100; not resolved under greedy curve, band 5%, window 100``; empty where all agree."""
    groups: dict[Verdict, list[str]] = {}
    for definition, label in labels.items():
        groups.setdefault(label, []).append(definition)
    if len(groups) < 2:
        return ""
    ordered = sorted(groups.items(), key=lambda item: -len(item[1]))
    return "; ".join(f"{label} under {' and '.join(names)}" for label, names in ordered)


class Judgement(NamedTuple):
    """The verdicts (columns :data:`COLUMNS`) and, for convergence claims, the label under each rule."""

    verdicts: pd.DataFrame
    rules: pd.DataFrame


def judge_by_rule(claims: list[Claim], metrics: dict[str, pd.DataFrame], episodes: int, *,
                  floors: dict[str, NoiseFloor] | None = None, rules: dict[str, pd.DataFrame] | None = None
                  ) -> Judgement:
    """Every claim tested on the same seeds of SARSA and Q-Learning, one family under Holm's correction.

    ``metrics``: :func:`per_seed_metrics` by configuration; a run that never converged counts as converging
    at the last episode, ``episodes`` (a censored value: a label it could overturn becomes not resolved, and
    a claim with nothing converged has no data). ``floors``: noise floors by configuration, read by claims
    with ``floor``. ``rules``: :func:`convergence_by_rule` by configuration; each convergence claim is judged
    again under every rule (the family recomputed with that rule's episodes) and marked fragile where its
    label changes.
    """
    floors = floors or {}
    outcomes = [_test(c, metrics, episodes) for c in claims]
    adjusted, labels = _labels(claims, outcomes, floors)
    convergence_claims = [i for i, c in enumerate(claims) if c.metric == CONVERGENCE]
    frames = list(rules.values()) if rules and convergence_claims else []
    names = [n for n in frames[0].columns if n != "seed" and all(n in f.columns for f in frames)] if frames else []
    by_rule = {}
    for name in names:
        varied = _under_rule(metrics, rules, name)
        redone = [_test(c, varied, episodes) if i in convergence_claims else o
                  for i, (c, o) in enumerate(zip(claims, outcomes, strict=True))]
        by_rule[name] = [label for label, _, _ in _labels(claims, redone, floors)[1]]
    rows = []
    for i, (outcome, p_adjusted, (label, floor_text, note)) in enumerate(zip(outcomes, adjusted, labels,
                                                                             strict=True)):
        under = {name: by_rule[name][i] for name in names} if i in convergence_claims else {}
        fragile = is_fragile([label, *under.values()])
        listing = labels_by_definition(under)
        parts = (note, outcome.power, listing and f"by rule: {listing}")
        rows.append(outcome.row | {"p": outcome.p, "p (Holm)": p_adjusted,
                                   "verdict": label + (FRAGILE if fragile else ""), "fragile": fragile,
                                   "noise floor": floor_text, "note": "; ".join(part for part in parts if part)})
    table = pd.DataFrame(rows, columns=COLUMNS)
    rule_table = pd.DataFrame([{"claim": claims[i].text, "verdict": table["verdict"].iloc[i]}
                               | {name: by_rule[name][i] for name in names} for i in convergence_claims],
                              columns=["claim", "verdict", *names])
    return Judgement(table, rule_table)


def judge(claims: list[Claim], metrics: dict[str, pd.DataFrame], episodes: int, *,
          floors: dict[str, NoiseFloor] | None = None, rules: dict[str, pd.DataFrame] | None = None) -> pd.DataFrame:
    """The verdicts of :func:`judge_by_rule`: one row per claim, columns :data:`COLUMNS` (among them ``claim``,
    ``estimate``, ``p``, ``p (Holm)``, ``verdict`` with " (fragile)" appended where the rules disagree, and
    ``fragile``)."""
    return judge_by_rule(claims, metrics, episodes, floors=floors, rules=rules).verdicts


def family(verdicts: pd.DataFrame) -> str:
    """The sentence naming Holm's family of a verdicts table: which claims, how many, at which level."""
    tested = verdicts[verdicts["p"].notna()]
    return (f"Holm's family: the {len(tested)} claims of this table that have data to test (of {len(verdicts)}), "
            f"family-wise α = {ALPHA:g}.")
