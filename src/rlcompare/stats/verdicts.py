"""Claims judged over paired seeds: the verdict engine every study's claims go through.

A claim (:class:`Claim`) is a sentence and the comparison that tests it: configuration A against B on the same
seeds, which share start states (common random numbers). The claims of one report form a family corrected with
Holm's procedure; a margin is tested with two one-sided tests; a claim read below its noise floor is undecidable
here; a label censoring could overturn stands only if the worst case agrees; and a convergence verdict is read
under several rules and marked fragile where they disagree (``docs/why.md``, "Verdicts").
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from functools import partial
from typing import NamedTuple

import numpy as np
import pandas as pd

from rlcompare.formatting import number
from rlcompare.stats.claims import RATIO_FACTOR as RATIO_FACTOR
from rlcompare.stats.claims import Claim as Claim
from rlcompare.stats.compare import compare_paired
from rlcompare.stats.design import SIGNED_RANK, T_TEST, Test, detectable_difference, smallest_p
from rlcompare.stats.intervals import Estimate, paired_difference, probability_of_improvement
from rlcompare.stats.power import provable_margin
from rlcompare.stats.significance import (
    ALPHA,
    CONTRADICTED,
    NO_DATA,
    NOT_RESOLVED,
    SUPPORTED,
    UNDECIDABLE,
    Equivalence,
    NoiseFloor,
    Verdict,
    equivalence_verdict,
    holm,
    holm_factors,
    rank_test,
    ratio_tost,
    robust_to_censoring,
    tost,
    verdict,
    worst_case_sign_p,
)

CONVERGENCE = "convergence_episode"
FRAGILE = " (fragile)"


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
    design: tuple[Test, int, float] = (T_TEST, 0, math.nan)
    """The test's kind, its seeds and the spread of the numbers it reads (:func:`power_columns`)."""


def _configurations(claim: Claim) -> list[str]:
    if claim.kind == "level":
        return [claim.a if claim.reads == "a" else claim.b]
    return [claim.a, claim.b]


def _paired(metrics: dict[str, pd.DataFrame], claim: Claim) -> tuple[np.ndarray, np.ndarray]:
    a = metrics[claim.a].sort_values("seed")
    b = metrics[claim.b].sort_values("seed")
    if not np.array_equal(a["seed"], b["seed"]):
        raise ValueError(f"{claim.a} and {claim.b} were run on different seeds")
    return a[claim.metric].to_numpy(dtype=np.float64), b[claim.metric].to_numpy(dtype=np.float64)


def _censoring(claim: Claim, a: np.ndarray, b: np.ndarray, names: tuple[str, str]
               ) -> tuple[frozenset[int], str, str]:
    """How censoring can move the claim's quantity, the row's count of censored seeds, and why there is no data.

    For a difference A - B a censored seed of A can only raise it and a censored seed of B only lower it; for the
    ratio B / A the other way round."""
    if claim.metric != CONVERGENCE:
        return frozenset(), "", ""
    never_a, never_b = int(np.isnan(a).sum()), int(np.isnan(b).sum())
    text = f"{names[0]} {never_a} of {a.size}, {names[1]} {never_b} of {b.size}"
    up, down = (-1, 1) if claim.kind == "ratio" else (1, -1)
    bias = frozenset(({up} if never_a else set()) | ({down} if never_b else set()))
    if never_a == a.size and never_b == b.size:
        return bias, text, "nothing converged"
    if claim.kind == "ratio" and (never_a == a.size or never_b == b.size):
        side = names[0] if never_a == a.size else names[1]
        return bias, text, f"no seed of {side} converged: the ratio would be read from censored values alone"
    return bias, text, ""


def censored_at_worst(values: np.ndarray, lower: float, upper: float, up: np.ndarray, down: np.ndarray
                      ) -> Callable[[int], float]:
    """``side -> p``: the sign test (:func:`~rlcompare.stats.intervals.worst_case_sign_p`) of a conclusion that puts
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
    times in five at these seeds and this spread (:func:`~rlcompare.stats.power.provable_margin`, at α before
    any correction, the most it could be) exceeds ``margin_value``, so "supported" is out of reach and the label
    can only be contradicted or not resolved. Empty otherwise."""
    provable = provable_margin(float(np.std(differences, ddof=1)), differences.size) if differences.size > 1 else np.nan
    if not provable > margin_value:
        return ""
    where = f" {scale}" if scale else ""
    return (f"underpowered for its margin: {differences.size} seeds prove ±{number(provable)}{where} four times in "
            f"five, wider than ±{number(margin_value)}")


def _direction(difference: Estimate, p_value: float, sign: int) -> tuple[Verdict, int]:
    label = verdict(difference, p_value, sign)
    return label, (sign if label == SUPPORTED else -sign)


def _equivalence(test: Equivalence, p_value: float) -> tuple[Verdict, int]:
    label = equivalence_verdict(test, p_value)
    side = 0 if test.inside else (1 if test.estimate.value > test.upper else -1)
    return label, side


def margin_text(bounds: tuple[float, float]) -> str:
    """Where a claim's difference holds: ``> -5``, ``< 0``, ``in [-20, 20]``."""
    lower, upper = bounds
    if math.isinf(upper):
        return f"> {number(lower)}"
    return f"< {number(upper)}" if math.isinf(lower) else f"in [{number(lower)}, {number(upper)}]"


def _test_text(claim: Claim, names: tuple[str, str]) -> str:
    """What is tested, in words."""
    side = ">" if claim.sign > 0 else "<"
    difference = claim.about or f"{names[0]} - {names[1]}"
    if claim.kind == "direction":
        return f"{difference} {side} 0: Wilcoxon signed-rank"
    if claim.kind == "ratio":
        return (f"{names[1]} / {names[0]} in [{claim.value / RATIO_FACTOR:.2f}, {claim.value * RATIO_FACTOR:.2f}] "
                f"(about {number(claim.value, 2)} times): TOST on log ratios")
    if claim.kind == "within":
        lower, upper = claim.bounds
        if lower == -upper:
            return f"|{difference}| < {number(upper)}: TOST, paired t"
        return f"{difference} {margin_text(claim.bounds)}: one-sided t"
    return f"{names[0 if claim.reads == 'a' else 1]} {side} {number(claim.value)}: Wilcoxon signed-rank"


def _test(claim: Claim, metrics: dict[str, pd.DataFrame], episodes: int, names: tuple[str, str]) -> _Outcome:
    """The claim's test on the seeds (a never-converged run counts at the last episode, ``episodes``)."""
    a, b = _paired(metrics, claim)
    bias, censored, no_data = _censoring(claim, a, b, names)
    never_a, never_b = np.isnan(a), np.isnan(b)
    if claim.metric == CONVERGENCE:
        a, b = np.nan_to_num(a, nan=episodes), np.nan_to_num(b, nan=episodes)
    row: dict[str, object] = {"claim": claim.text, "metric": claim.metric, names[0]: float(np.mean(a)),
                              names[1]: float(np.mean(b)), "test": _test_text(claim, names), "censored": censored}
    if no_data or not (np.isfinite(a).all() and np.isfinite(b).all()):
        return _Outcome(row, np.nan, lambda _: (NO_DATA, 0), bias, no_data or "no finite value to test")
    if claim.kind == "direction":
        paired = compare_paired(a, b)
        better = paired.improvement if claim.sign > 0 else probability_of_improvement(b, a)
        return _Outcome(row | {"estimate": paired.difference.format(2),
                               "P(claim holds for a random pair)": better.format(2)},
                        paired.p_value, partial(_direction, paired.difference, sign=claim.sign), bias,
                        worst_case=censored_at_worst(a - b, 0.0, 0.0, never_a, never_b) if bias else None,
                        design=(SIGNED_RANK, a.size, _spread(a - b)))
    if claim.kind == "ratio":
        test = ratio_tost(b, a, claim.value, RATIO_FACTOR)
        logs = np.log(b / a)
        return _Outcome(row | {"estimate": test.estimate.format(2)}, test.p, partial(_equivalence, test), bias,
                        worst_case=censored_at_worst(logs, np.log(test.lower), np.log(test.upper), never_b, never_a)
                        if bias else None, power=underpowered(logs, np.log(RATIO_FACTOR), "on the log scale"),
                        design=(T_TEST, a.size, math.nan))
    if claim.kind == "within":
        lower, upper = claim.bounds
        test = tost(a - b, lower, upper)
        return _Outcome(row | {"estimate": test.estimate.format(2)}, test.p, partial(_equivalence, test), bias,
                        worst_case=censored_at_worst(a - b, lower, upper, never_a, never_b)
                        if bias else None, power=underpowered(a - b, upper) if lower == -upper else "",
                        design=(T_TEST, a.size, math.nan))
    values = a if claim.reads == "a" else b
    reference = np.full_like(values, claim.value)
    shift = paired_difference(values, reference)
    return _Outcome(row | {"estimate": shift.format(2)}, rank_test(values, reference, paired=True),
                    partial(_direction, shift, sign=claim.sign), design=(SIGNED_RANK, values.size, _spread(values)))


def _spread(values: np.ndarray) -> float:
    """The standard deviation of the numbers a rank test reads (NaN below two)."""
    return float(np.std(values, ddof=1)) if values.size > 1 else math.nan


def power_columns(outcome: _Outcome, family: int) -> dict[str, float]:
    """The power a claim's design gave it: the smallest p its test can give on its seeds, and the difference its
    seeds detect four times in five at Holm's strictest level over ``family`` claims (in the metric's units; NaN
    for a margin's t tests, whose power the note states, and where the test cannot pass: infinite)."""
    test, seeds, spread = outcome.design
    if not math.isfinite(outcome.p):
        return {"smallest p": math.nan, "detectable (80% power)": math.nan}
    detectable = (detectable_difference(test, spread, seeds, max(family, 1)) if test == SIGNED_RANK
                  else math.nan)
    return {"smallest p": smallest_p(test, seeds), "detectable (80% power)": detectable}


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
    if label != NOT_RESOLVED and outcome.worst_case is not None and not robust_to_censoring(side, outcome.bias):
        worst = max(p_adjusted, min(1.0, holm_factor * outcome.worst_case(side)))
        if not worst < ALPHA:
            return (NOT_RESOLVED, floor_text,
                    f"{label} from censored values: seeds that never converged could overturn it")
        return label, floor_text, (f"{label} whatever the never-converged seeds' true times: the sign test with "
                                   f"each at its worst gives p (Holm) {number(worst, 2)}")
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
    """The verdicts (columns :func:`columns`) and, for convergence claims, the label under each rule."""

    verdicts: pd.DataFrame
    rules: pd.DataFrame


def columns(names: tuple[str, str]) -> list[str]:
    """The columns of :func:`judge`'s table, A's and B's means named ``names``: stable for readers of
    ``verdicts.csv``."""
    return ["claim", "metric", *names, "test", "estimate", "P(claim holds for a random pair)", "p", "p (Holm)",
            "smallest p", "detectable (80% power)", "verdict", "fragile", "censored", "noise floor", "note"]


def judge_by_rule(claims: list[Claim], metrics: dict[str, pd.DataFrame], episodes: int, *,
                  names: tuple[str, str] = ("A", "B"), floors: dict[str, NoiseFloor] | None = None,
                  rules: dict[str, pd.DataFrame] | None = None) -> Judgement:
    """Every claim tested on the same seeds of its two configurations, one family under Holm's correction.

    ``metrics``: per-seed values by configuration (a ``seed`` column and one per metric); a run that never
    converged counts as converging at the last episode, ``episodes`` (a censored value: a label it could overturn
    becomes not resolved, and a claim with nothing converged has no data). ``names``: what the rows call A and B.
    ``floors``: noise floors by configuration, read by claims with ``floor``. ``rules``: per-seed episodes to
    converge under each rule, by configuration; each convergence claim is judged again under every rule (the
    family recomputed with that rule's episodes) and marked fragile where its label changes.
    """
    floors = floors or {}
    outcomes = [_test(c, metrics, episodes, names) for c in claims]
    adjusted, labels = _labels(claims, outcomes, floors)
    convergence_claims = [i for i, c in enumerate(claims) if c.metric == CONVERGENCE]
    frames = list(rules.values()) if rules and convergence_claims else []
    rule_names = ([n for n in frames[0].columns if n != "seed" and all(n in f.columns for f in frames)]
                  if rules and frames else [])
    by_rule = {}
    for rule in rule_names:
        varied = _under_rule(metrics, rules or {}, rule)
        redone = [_test(c, varied, episodes, names) if i in convergence_claims else o
                  for i, (c, o) in enumerate(zip(claims, outcomes, strict=True))]
        by_rule[rule] = [label for label, _, _ in _labels(claims, redone, floors)[1]]
    rows = []
    family = sum(math.isfinite(o.p) for o in outcomes)
    for i, (outcome, p_adjusted, (label, floor_text, note)) in enumerate(zip(outcomes, adjusted, labels,
                                                                             strict=True)):
        under = {rule: by_rule[rule][i] for rule in rule_names} if i in convergence_claims else {}
        fragile = is_fragile([label, *under.values()])
        listing = labels_by_definition(under)
        parts = (note, outcome.power, listing and f"by rule: {listing}")
        rows.append(outcome.row | power_columns(outcome, family) | {"p": outcome.p, "p (Holm)": p_adjusted,
                                   "verdict": label + (FRAGILE if fragile else ""), "fragile": fragile,
                                   "noise floor": floor_text, "note": "; ".join(part for part in parts if part)})
    table = pd.DataFrame(rows, columns=columns(names))
    rule_table = pd.DataFrame([{"claim": claims[i].text, "verdict": table["verdict"].iloc[i]}
                               | {rule: by_rule[rule][i] for rule in rule_names} for i in convergence_claims],
                              columns=["claim", "verdict", *rule_names])
    return Judgement(table, rule_table)


def judge(claims: list[Claim], metrics: dict[str, pd.DataFrame], episodes: int, *,
          names: tuple[str, str] = ("A", "B"), floors: dict[str, NoiseFloor] | None = None,
          rules: dict[str, pd.DataFrame] | None = None) -> pd.DataFrame:
    """The verdicts of :func:`judge_by_rule`: one row per claim, columns :func:`columns` (among them ``claim``,
    ``estimate``, ``p``, ``p (Holm)``, ``verdict`` with " (fragile)" appended where the rules disagree, and
    ``fragile``)."""
    return judge_by_rule(claims, metrics, episodes, names=names, floors=floors, rules=rules).verdicts


def holm_family(verdicts: pd.DataFrame) -> str:
    """The sentence naming Holm's family of a verdicts table: which claims, how many, at which level."""
    tested = verdicts[verdicts["p"].notna()]
    return (f"Holm's family: the {len(tested)} claims of this table that have data to test (of {len(verdicts)}), "
            f"family-wise α = {ALPHA:g}.")
