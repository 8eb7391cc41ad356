"""A against B on paired seeds: the one comparison every study makes, and the one vocabulary it reports in.

:func:`compare_paired` gives the paired difference with its interval, the Wilcoxon p-value, the probability of
improvement and, where a margin is declared, the test of equivalence (:mod:`rlcompare.stats.intervals`);
:func:`comparison_label` says what it found in the words every report uses ("A better", "B better", "equivalent
(within ±m)", "not resolved", "no data"), read off :func:`~rlcompare.stats.significance.verdict`, the rule a claim is
judged by.
"""

from __future__ import annotations

from collections.abc import Hashable
from typing import NamedTuple

import numpy as np

from rlcompare.formatting import number
from rlcompare.stats.design import SIGNED_RANK, detectable_difference
from rlcompare.stats.intervals import (
    NO_ESTIMATE,
    Estimate,
    improvement_score_interval,
    independent_difference,
    paired_difference,
    per_seed_values,
    probability_of_improvement,
)
from rlcompare.stats.significance import (
    ALPHA,
    CONTRADICTED,
    NO_DATA,
    NOT_RESOLVED,
    SUPPORTED,
    Equivalence,
    equivalence_verdict,
    holm,
    rank_test,
    tost,
    verdict,
    welch_tost,
)


class Paired(NamedTuple):
    """A against B on paired seeds (seed ``s`` of each on the same start states): the comparison every study
    makes; or, from :func:`compare_independent`, on seeds that share nothing."""

    a_mean: float
    b_mean: float
    difference: Estimate
    """Mean of A - B over seeds, with its BCa bootstrap interval (:func:`paired_difference`)."""
    p_value: float
    """Two-sided Wilcoxon signed-rank p-value (:func:`rank_test`); NaN where a value is not finite."""
    improvement: Estimate
    """P(a seed of A beats a seed of B) (:func:`probability_of_improvement`); NaN where not asked for."""
    seeds: int
    equivalence: Equivalence | None = None
    """TOST of A - B within the declared ±margin; None where no margin is declared."""
    spread: float = np.nan
    """Standard deviation of A - B over seeds (``ddof=1``): what the power of the comparison reads."""


def compare_paired(a: np.ndarray, b: np.ndarray, margin: float | None = None, *, improvement: bool = True
                   ) -> Paired:
    """A against B on paired seeds: means, the difference with its interval, the rank test, the probability of
    improvement (unless ``improvement`` is False: a bootstrap of its own, which a grid of many cells may skip)
    and, where ``margin`` is given, the test of equivalence within ±margin."""
    a, b = per_seed_values(a), per_seed_values(b)
    finite = bool(np.isfinite(a - b).all())
    return Paired(float(np.mean(a)), float(np.mean(b)), paired_difference(a, b),
                  rank_test(a, b) if finite else np.nan,
                  probability_of_improvement(a, b) if improvement else NO_ESTIMATE, int(a.size),
                  None if margin is None else tost(a - b, -margin, margin),
                  float(np.std(a - b, ddof=1)) if a.size > 1 and finite else np.nan)


def compare_independent(a: np.ndarray, b: np.ndarray, margin: float | None = None) -> Paired:
    """A against B on seeds that share no randomness (runs other libraries made): means, the difference of means
    with its two-sample interval, the Mann-Whitney p-value, the probability of improvement with Newcombe's score
    interval (:func:`~rlcompare.stats.intervals.improvement_score_interval`) and, where ``margin``
    is given, Welch's test of equivalence. ``seeds`` and ``spread`` are those of a paired test on as many pairs as
    the smaller side with the two sides' variances summed, so the detectable difference it gives is on the safe side
    of the two-sample test's."""
    a, b = per_seed_values(a), per_seed_values(b)
    finite = bool(np.isfinite(a).all() and np.isfinite(b).all())
    spread = float(np.sqrt(a.var(ddof=1) + b.var(ddof=1))) if min(a.size, b.size) > 1 and finite else np.nan
    return Paired(float(np.mean(a)), float(np.mean(b)), independent_difference(a, b),
                  rank_test(a, b, paired=False) if finite else np.nan, improvement_score_interval(a, b),
                  int(min(a.size, b.size)), None if margin is None else welch_tost(a, b, -margin, margin), spread)


def comparison_label(difference: Estimate, p_adjusted: float, names: tuple[str, str],
                     equivalence: Equivalence | None = None, level: float = ALPHA,
                     p_equivalence: float | None = None) -> str:
    """What A against B found, in the one vocabulary: "A better" / "B better" where :func:`verdict` supports or
    contradicts "A - B > 0" (``difference``) at ``p_adjusted``; else "equivalent (within ±m)" where a margin was
    declared and :func:`equivalence_verdict` supports ``equivalence`` at ``p_equivalence`` (its p-value adjusted in
    the same family as ``p_adjusted``: :func:`judge_family`); "no data" without an estimate; "not resolved"
    otherwise."""
    direction = verdict(difference, p_adjusted, +1, level)
    if direction in (SUPPORTED, CONTRADICTED):
        return f"{names[0] if direction == SUPPORTED else names[1]} better"
    if direction == NO_DATA:
        return NO_DATA
    if equivalence is not None and equivalence_verdict(equivalence, p_equivalence, level) == SUPPORTED:
        return f"equivalent (within ±{number(equivalence.upper)})"
    return NOT_RESOLVED


NEITHER_LEARNT = "neither learnt at this budget"


def gated_label(label: str, learnt: tuple[bool, bool], names: tuple[str, str]) -> str:
    """A comparison's label behind the learning gate (:func:`~rlcompare.stats.significance.has_learnt` of each
    side): where neither side has learnt, :data:`NEITHER_LEARNT`; where one has, that is the answer ("only A
    learnt"); where both have, ``label``."""
    if not any(learnt):
        return NEITHER_LEARNT
    if not all(learnt):
        return f"only {names[0] if learnt[0] else names[1]} learnt"
    return label


class Judged(NamedTuple):
    """One comparison of a family, judged."""

    paired: Paired
    p: float
    """Holm-adjusted p of the direction (Wilcoxon)."""
    p_equivalence: float
    """Holm-adjusted p of the equivalence (TOST within the margin); NaN where no margin was declared."""
    label: str
    detectable: float
    """The smallest true difference the signed-rank test at the family's strictest Holm step (α over the family's
    size) finds four times in five over these paired seeds, infinite where its smallest p cannot pass that step
    (:func:`~rlcompare.stats.design.detectable_difference`)."""


def judge_family(found: dict[Hashable, Paired], names: tuple[str, str], level: float = ALPHA
                 ) -> dict[Hashable, Judged]:
    """Every comparison of a report as one family: each one's direction test and, where a margin was declared,
    its equivalence test, all Holm-adjusted together (Holm 1979), so that "A better" and "equivalent" share one
    family-wise error rate; each labelled by :func:`comparison_label`, with the difference its seeds could detect."""
    keys = list(found)
    directions = [found[k].p_value for k in keys]
    equivalences = [np.nan if (test := found[k].equivalence) is None else test.p_equivalent for k in keys]
    adjusted = holm([*directions, *equivalences])
    size = max(int(np.sum(~np.isnan([*directions, *equivalences]))), 1)
    judged = {}
    for i, key in enumerate(keys):
        paired, p, p_equivalence = found[key], adjusted[i], adjusted[len(keys) + i]
        label = comparison_label(paired.difference, p, names, paired.equivalence, level, p_equivalence)
        detectable = detectable_difference(SIGNED_RANK, paired.spread, paired.seeds, size, level=level)
        judged[key] = Judged(paired, p, p_equivalence, label, detectable)
    return judged
