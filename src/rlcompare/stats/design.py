"""What a design can decide before anything trains: the smallest p-value each of the studies' rank tests can give
with so many seeds, the strictest level Holm's correction asks of a family, and whether the one can pass the other.

A rank test's p-value is computed from the ranks alone, so with ``n`` seeds it cannot fall below the probability of
its most extreme arrangement (every seed on one side), however large the difference:

| test                                           | smallest p          | why                                        |
|------------------------------------------------|---------------------|--------------------------------------------|
| Wilcoxon signed-rank, ``n`` pairs, two-sided   | ``2 / 2**n``        | ``2**n`` equally likely signs              |
| the same, one-sided (the learning gate)        | ``1 / 2**n``        |                                            |
| Mann-Whitney, ``n`` and ``m`` seeds, two-sided | ``2 / C(n + m, n)`` | ``C(n + m, n)`` equally likely orders      |
| a t test, or a bootstrap interval, ``n >= 2``  | 0                   | the spread can be as small as it likes     |

These are the exact tests' values (scipy's ``wilcoxon`` and ``mannwhitneyu`` with ``method="exact"``); scipy's
default computes the signed-rank test exactly up to 50 pairs without ties or zeros, and the rank-sum test exactly
below 8 seeds a side only. Holm's step-down procedure (Holm 1979) compares the smallest
of ``k`` p-values with ``level / k``: a test whose smallest p is above ``level / k`` can never reject in a family of
``k``, whatever the data. A design whose headline test is in that position cannot decide, and says so before it runs
(``docs/why.md``, "Decidable by design").

Where the spread of the seeds' numbers is known, :func:`detectable_difference` gives the difference the test finds
with 80% power at that strictest level: the t test's (exact, on the noncentral t), divided by the square root of
the rank tests' asymptotic relative efficiency against it on normal data, 3/π (Lehmann,
*Nonparametrics*, 1975, §2.4). It is a planning figure. Simulated on normal data against scipy's exact tests
(``tests/unit/test_design.py``) its power is within a few points of 80% from about 10 seeds on; near the fewest
seeds that can decide at all the exact test's steps cost power (64% at 9 pairs over 10 tests).
"""

from __future__ import annotations

import math
from typing import Literal, NamedTuple

from rlcompare.stats import power as power_of_t
from rlcompare.stats.power import ALPHA, POWER

Test = Literal["signed-rank", "signed-rank, one-sided", "rank-sum", "t", "interval"]
SIGNED_RANK: Test = "signed-rank"
GATE: Test = "signed-rank, one-sided"
RANK_SUM: Test = "rank-sum"
T_TEST: Test = "t"
INTERVAL: Test = "interval"
"""A 95% bootstrap interval that excludes 0, read without a p-value (the why study's decomposition)."""
RANK_EFFICIENCY = 3 / math.pi
"""The Wilcoxon tests' asymptotic relative efficiency against the t test on normal data."""
LARGEST_SEEDS = 10_000
"""Where :func:`seeds_needed` stops looking: a design that needs more is beyond any study here."""


def smallest_p(test: Test, seeds: int, other_seeds: int | None = None) -> float:
    """The smallest p-value ``test`` can give on ``seeds`` seeds (and ``other_seeds`` on the other side, for the
    rank-sum test; the same number by default); 1 with no seed at all."""
    if seeds < 1 or (other_seeds is not None and other_seeds < 1):
        return 1.0
    if test in (T_TEST, INTERVAL):
        return 0.0 if seeds >= 2 else 1.0
    if test == SIGNED_RANK:
        return min(1.0, 2.0**(1 - seeds))
    if test == GATE:
        return 2.0**-seeds
    total = seeds + (seeds if other_seeds is None else other_seeds)
    if math.lgamma(total + 1) - math.lgamma(seeds + 1) - math.lgamma(total - seeds + 1) > 700:
        return 0.0  # 2 / C(n + m, n) below a float's range (and C itself slow to compute for a million seeds)
    return min(1.0, 2.0 / math.comb(total, seeds))


def strictest_level(family: int, level: float = ALPHA) -> float:
    """The level Holm's procedure asks of the smallest p-value in a family of ``family`` tests: ``level / family``."""
    if family < 1:
        raise ValueError(f"a family holds at least one test, not {family}")
    return level / family


def can_pass(test: Test, seeds: int, family: int = 1, level: float = ALPHA, other_seeds: int | None = None) -> bool:
    """Whether ``test`` on these seeds can reject at all in a Holm family of ``family`` tests at ``level``: its
    smallest p at or below :func:`strictest_level` (the learning gate is not corrected: ``family`` 1)."""
    return smallest_p(test, seeds, other_seeds) <= strictest_level(family, level)


def seeds_needed(test: Test, family: int = 1, level: float = ALPHA) -> int:
    """The fewest seeds (a side) on which ``test`` can reject in a Holm family of ``family`` tests at ``level``."""
    for seeds in range(1, LARGEST_SEEDS + 1):
        if can_pass(test, seeds, family, level):
            return seeds
    raise ValueError(f"no design of up to {LARGEST_SEEDS:,} seeds reaches level {level:g} over {family} tests")


class Reach(NamedTuple):
    """What a design's test can reach: its smallest p and the level it must pass."""

    test: Test
    seeds: int
    family: int
    smallest_p: float
    level: float
    """The strictest level it faces: ``ALPHA / family``."""
    needed: int
    """The fewest seeds on which it could pass."""

    @property
    def can_decide(self) -> bool:
        return self.smallest_p <= self.level

    def sentence(self) -> str:
        """One sentence: whether the design can decide, and with how many seeds it could."""
        tests = f"{self.family} tests" if self.family > 1 else "one test"
        if self.can_decide:
            return (f"With {self.seeds} seeds the {self.test} test can give a p of {self.smallest_p:.2g}, at or "
                    f"below the {self.level:.2g} Holm asks over {tests}: this design can decide.")
        return (f"With {self.seeds} seeds the {self.test} test cannot give a p below {self.smallest_p:.2g}, above "
                f"the {self.level:.2g} Holm asks over {tests}: this design cannot decide; with {self.needed} seeds "
                "it can.")


def reach(test: Test, seeds: int, family: int = 1, level: float = ALPHA, other_seeds: int | None = None) -> Reach:
    """:class:`Reach` of ``test`` on ``seeds`` seeds (and ``other_seeds`` on the other side, for the rank-sum test)
    in a Holm family of ``family`` tests."""
    return Reach(test, seeds, family, smallest_p(test, seeds, other_seeds), strictest_level(family, level),
                 seeds_needed(test, family, level))


def detectable_difference(test: Test, spread: float, seeds: int, family: int = 1, other_seeds: int | None = None,
                          level: float = ALPHA, power: float = POWER) -> float:
    """The difference of means ``test`` detects with probability ``power`` at Holm's strictest level over ``family``
    tests, where the seeds' numbers spread with standard deviation ``spread`` (of each side's numbers for the
    rank-sum test, of the paired differences for the signed-rank tests): the t test's, exact on the noncentral t
    (:func:`rlcompare.stats.power.detectable_difference`), over the square root of the rank tests' efficiency 3/π.
    Infinite where the test cannot pass at all on these seeds (:func:`can_pass`)."""
    if not can_pass(test, seeds, family, level, other_seeds) or not math.isfinite(spread):
        return math.inf
    other = (seeds if other_seeds is None else other_seeds) if test == RANK_SUM else None
    found = power_of_t.detectable_difference(spread, seeds, strictest_level(family, level), power,
                                             other_seeds=other, one_sided=test == GATE)
    efficiency = 1.0 if test in (T_TEST, INTERVAL) else RANK_EFFICIENCY
    return math.inf if math.isnan(found) else found / math.sqrt(efficiency)
