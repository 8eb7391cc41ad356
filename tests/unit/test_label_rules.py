"""Every rule that sets a verdict's label, as a table of cases: a direction, an equivalence, censoring, the worst
case of censored seeds, fragility across the convergence rules and the listing of which rule gives which label,
then the case the rules were written for: a ratio far from the claimed one, with seeds that never converged, is
contradicted under every definition that can decide it."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from rlcompare.stats import significance, verdicts
from rlcompare.stats.intervals import Estimate
from rlcompare.stats.significance import (
    Equivalence,
    equivalence_verdict,
    holm_factors,
    robust_to_censoring,
    verdict,
    worst_case_sign_p,
)
from rlcompare.stats.verdicts import censored_at_worst, is_fragile, labels_by_definition
from rlcompare.studies.paper.claims import NAMES, paper_claim

SUPPORTED, CONTRADICTED, NOT_RESOLVED, UNDECIDABLE, NO_DATA = (
    significance.SUPPORTED, significance.CONTRADICTED, significance.NOT_RESOLVED, significance.UNDECIDABLE,
    significance.NO_DATA)


def judge_by_rule(*args, **kwargs):
    """:func:`rlcompare.stats.verdicts.judge_by_rule` with the paper's names for A and B."""
    return verdicts.judge_by_rule(*args, names=NAMES, **kwargs)

NAN = float("nan")


@pytest.mark.parametrize(("difference", "p", "sign", "label"), [
    ((5.0, 1.0, 9.0), 0.01, +1, SUPPORTED),        # interval above 0, as claimed
    ((5.0, 1.0, 9.0), 0.01, -1, CONTRADICTED),     # above 0, the claim said below
    ((-5.0, -9.0, -1.0), 0.01, -1, SUPPORTED),
    ((5.0, -1.0, 9.0), 0.01, +1, NOT_RESOLVED),    # the interval holds 0
    ((5.0, 1.0, 9.0), 0.06, +1, NOT_RESOLVED),     # the family's p does not reject
    ((5.0, 1.0, 9.0), NAN, +1, NOT_RESOLVED),
    ((5.0, NAN, NAN), 0.001, +1, NOT_RESOLVED),    # one seed: more could settle it
    ((NAN, NAN, NAN), 0.001, +1, NO_DATA),
])
def test_direction(difference: tuple, p: float, sign: int, label: str) -> None:
    assert verdict(Estimate(*difference), p, sign) == label


@pytest.mark.parametrize(("estimate", "p_equivalent", "p_beyond", "p", "label"), [
    (0.5, 0.01, 1.0, None, SUPPORTED),             # inside the margin, equivalence shown
    (0.5, 0.2, 1.0, None, NOT_RESOLVED),           # inside, not shown
    (3.0, 1.0, 0.001, None, CONTRADICTED),         # beyond the margin, shown beyond
    (3.0, 1.0, 0.2, None, NOT_RESOLVED),
    (0.5, 0.01, 1.0, 0.08, NOT_RESOLVED),          # the Holm-adjusted p decides
    (NAN, NAN, NAN, None, NO_DATA),
])
def test_equivalence(estimate: float, p_equivalent: float, p_beyond: float, p: float | None, label: str) -> None:
    test = Equivalence(Estimate(estimate, estimate - 0.1, estimate + 0.1), -1.0, 1.0, p_equivalent, p_beyond)
    assert equivalence_verdict(test, p) == label


@pytest.mark.parametrize(("side", "bias", "robust"), [
    (-1, set(), True),      # nothing censored
    (-1, {-1}, True),       # censoring can only push further below
    (-1, {1}, False),       # ... or back up towards the bound
    (1, {1}, True),
    (1, {-1, 1}, False),
    (0, set(), True),
    (0, {1}, False),        # inside a band: any move can leave it
])
def test_censoring_that_can_only_push_further_keeps_the_label(side: int, bias: set, robust: bool) -> None:
    assert robust_to_censoring(side, bias) is robust


def test_the_worst_case_sign_test_puts_each_censored_seed_against_the_conclusion() -> None:
    below = np.full(30, -1.0)
    up = np.arange(30) < 6                         # six seeds could only be larger: put above the bound
    # 24 of 30 below the bound, whatever the six are: the one-sided binomial tail P(X >= 24 | 30, 1/2)
    expected = stats.binomtest(24, 30, 0.5, alternative="greater").pvalue
    assert worst_case_sign_p(below, 0.0, -1, up, np.zeros(30, bool)) == pytest.approx(expected)
    # the same seeds could only be smaller: no harm to "below", all 30 count
    assert worst_case_sign_p(below, 0.0, -1, np.zeros(30, bool), up) == pytest.approx(0.5 ** 30)
    # half censored against the conclusion: nothing can be concluded
    assert worst_case_sign_p(below, 0.0, -1, np.arange(30) < 15, np.zeros(30, bool)) > 0.5
    # a conclusion above the bound reads the seeds that could only be smaller
    assert worst_case_sign_p(-below, 0.0, 1, np.zeros(30, bool), up) == pytest.approx(expected)
    with pytest.raises(ValueError, match="side"):
        worst_case_sign_p(below, 0.0, 0, up, up)


def test_inside_a_band_must_survive_the_worst_on_both_sides() -> None:
    values = np.zeros(20)
    none, some = np.zeros(20, bool), np.arange(20) < 3
    both = censored_at_worst(values, -1.0, 1.0, some, none)
    sides = (worst_case_sign_p(values, -1.0, 1, some, none), worst_case_sign_p(values, 1.0, -1, some, none))
    assert both(0) == max(sides)
    assert both(0) > censored_at_worst(values, -1.0, 1.0, none, none)(0)


def test_holm_factors_are_what_each_p_is_multiplied_by() -> None:
    np.testing.assert_array_equal(holm_factors([0.01, NAN, 0.04, 0.03]), [3.0, NAN, 1.0, 2.0])


@pytest.mark.parametrize(("labels", "fragile"), [
    ([SUPPORTED, SUPPORTED, SUPPORTED], False),
    ([SUPPORTED, CONTRADICTED], True),                    # two rules decide opposite ways
    ([CONTRADICTED, NOT_RESOLVED, CONTRADICTED], False),  # a rule that cannot decide adds no evidence
    ([NOT_RESOLVED, SUPPORTED, CONTRADICTED], True),
    ([NOT_RESOLVED, SUPPORTED], False),
    ([NO_DATA, CONTRADICTED], False),
    ([UNDECIDABLE, SUPPORTED], False),
    ([], False),
])
def test_a_label_is_fragile_when_two_definitions_decide_it_opposite_ways(labels: list, fragile: bool) -> None:
    assert is_fragile(labels) is fragile


def test_the_row_lists_which_definitions_give_which_label() -> None:
    assert labels_by_definition({"a": SUPPORTED, "b": SUPPORTED}) == ""
    assert labels_by_definition({"a": SUPPORTED, "b": NOT_RESOLVED, "c": SUPPORTED}) == (
        "supported under a and c; not resolved under b")
    assert labels_by_definition({}) == ""


# --- the case the rules were written for ---

def _rule_frames(sarsa: np.ndarray, q: np.ndarray, rules: dict[str, float]) -> dict[str, pd.DataFrame]:
    """Convergence episodes under each rule: the seeds' times scaled by the rule's factor (NaN: never)."""
    seeds = np.arange(sarsa.size)
    return {name: pd.DataFrame({"seed": seeds} | {rule: times * factor for rule, factor in rules.items()})
            for name, times in (("sarsa-decay", sarsa), ("q_learning-decay", q))}


def test_a_ratio_far_from_the_claim_is_contradicted_under_every_definition_that_can_decide() -> None:
    rng = np.random.default_rng(0)
    sarsa = rng.uniform(2000, 3000, 30)
    q = sarsa * rng.uniform(1.3, 1.8, 30)
    q[:6] = np.nan                                        # six Q-Learning seeds never converge
    rules = {"band 5%, window 100": 1.0, "band 10%, window 50": 0.8, "band 20%, window 200": 0.6}
    frames = _rule_frames(sarsa, q, rules)
    main = {name: frame[["seed", "band 5%, window 100"]].rename(columns={"band 5%, window 100": "convergence_episode"})
            for name, frame in frames.items()}
    four = paper_claim("about 4 times", "decay", "convergence_episode", kind="ratio", value=3.88)
    judgement = judge_by_rule([four], main, 5000, rules=frames)
    row = judgement.verdicts.iloc[0]
    assert row["verdict"] == CONTRADICTED
    assert not row["fragile"]
    assert set(judgement.rules.iloc[0][list(rules)]) == {CONTRADICTED}
    assert "whatever the never-converged seeds' true times" in row["note"]
    # with half the Q-Learning seeds censored the worst case could reach the band: not resolved, not fragile
    q[:15] = np.nan
    frames = _rule_frames(sarsa, q, rules)
    main = {name: frame[["seed", "band 5%, window 100"]].rename(columns={"band 5%, window 100": "convergence_episode"})
            for name, frame in frames.items()}
    row = judge_by_rule([four], main, 5000, rules=frames).verdicts.iloc[0]
    assert row["verdict"] == NOT_RESOLVED
    assert "could overturn it" in row["note"]


@pytest.mark.parametrize(("seeds", "spread", "margin_value", "underpowered_note"), [
    (30, 1.0, 1.0, False),    # 30 seeds prove about ±0.5 at spread 1: a margin of 1 is within reach
    (5, 1.0, 1.0, True),      # 5 seeds prove about ±1.8: "supported" is out of reach
    (30, 30.0, 20.0, False),  # "the same solution" at 30 seeds would need a spread under about 36
    (30, 1250.0, 500.0, True),  # the paper's "similar time frame": ±500 needs about ±690
])
def test_a_margin_the_seeds_cannot_prove_is_named_underpowered(seeds: int, spread: float, margin_value: float,
                                                                 underpowered_note: bool) -> None:
    from rlcompare.stats.verdicts import underpowered

    differences = np.random.default_rng(0).standard_normal(seeds)
    differences = (differences - differences.mean()) / differences.std(ddof=1) * spread  # exactly that spread
    note = underpowered(differences, margin_value)
    assert bool(note) is underpowered_note
    if note:
        assert note.startswith(f"underpowered for its margin: {seeds} seeds prove ±")


# --- the learning gate: a comparison only where a method has learnt ----------------------------------------------

@pytest.mark.parametrize(("learnt", "label"), [
    ((True, True), "on-policy better"),
    ((True, False), "only on-policy learnt"),
    ((False, True), "only off-policy learnt"),
    ((False, False), "neither learnt at this budget"),
])
def test_the_learning_gate_stands_before_the_comparison_s_label(learnt, label):
    from rlcompare.stats.compare import gated_label

    assert gated_label("on-policy better", learnt, ("on-policy", "off-policy")) == label


@pytest.mark.parametrize(("finals", "learnt"), [
    ([3.0] * 8, True),                      # every seed above floor + margin: p = 1/256
    ([3.0] * 7 + [1.0], True),              # one seed below: still p < 0.05
    ([3.0] * 4 + [1.0] * 4, False),         # half above, half below
    ([1.5] * 8, False),                     # at floor + margin exactly: not beyond it
    ([1.2] * 8, False),                     # above random, within the margin
    ([3.0] * 4, False),                     # too few seeds: 1/16 is the smallest p
])
def test_a_method_has_learnt_when_the_signed_rank_test_puts_it_beyond_the_margin(finals, learnt):
    from rlcompare.stats.significance import has_learnt

    floor, margin = 1.0, 0.5
    assert has_learnt(np.asarray(finals), floor, margin) is learnt
    above = np.asarray(finals) - floor - margin
    if not np.all(above == 0):
        p = stats.wilcoxon(above, zero_method="zsplit", alternative="greater").pvalue
        assert bool(p < 0.05) == learnt
