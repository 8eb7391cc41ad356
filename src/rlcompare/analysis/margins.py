"""Every margin a verdict reads, in one table, each with its reason, declared before any run was read; and how
large a difference the seeds a study runs could detect (``docs/why.md``, "Margins and power").

A margin turns "the same" into a test: two one-sided tests (Schuirmann 1987) show equivalence only when the
difference's interval lies inside it, so a study with too few seeds for its margin says "not resolved", never
"equivalent". The power functions say, from the seed-to-seed spread a study measured, what its seeds could
have shown: the smallest difference a paired t test finds four times in five, and the smallest margin two
one-sided tests prove four times in five when there is no difference at all.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from scipy import optimize, stats

from rlcompare.analysis.stats import ALPHA

POWER = 0.8
"""The chance of detection the power columns are read at (Cohen 1988's convention)."""


@dataclass(frozen=True)
class Margin:
    """A bound below which a difference counts as none (or, for a ratio, a band around the claimed factor)."""

    study: str
    bounds: str
    """What it bounds, as the report names it."""
    value: float
    unit: str
    reason: str


MARGINS = {m.study + ": " + m.bounds: m for m in (
    Margin("paper", "a similar time frame (convergence)", 0.1, "share of the training's episodes",
           "the paper reads its Table I's 13.8 against 11.5 (17% of the larger) as a similar time frame; a tenth "
           "of the training (500 of 5000 episodes) holds that reading"),
    Margin("paper", "the same solution (greedy return)", 20.0, "return per episode",
           "the paper calls -174 and -191 the same solution: 17 apart; 20 holds its own reading"),
    Margin("paper", "about R times (ratio)", 1.25, "factor on either side of R",
           "the 80-125% band of average bioequivalence (FDA 2001), the field's convention for 'about' a ratio"),
    Margin("deep", "CartPole-v1 (final greedy return)", 25.0, "return per episode",
           "5% of the return's range (0 to 500)"),
    Margin("deep", "Acrobot-v1 (final greedy return)", 25.0, "return per episode",
           "5% of the return's range (-500 to 0)"),
    Margin("deep", "MountainCar-v0 (final greedy return)", 10.0, "return per episode",
           "5% of the return's range (-200 to 0)"),
    Margin("minatar", "a game (final greedy return)", 1.0, "points per episode",
           "one point, the smallest score a game gives (one brick, one alien, one fish, one crossing)"),
    Margin("minatar", "over the games (normalised score)", 0.05, "normalised score",
           "5% of the distance from a random policy (0) to the best method here (1)"),
    Margin("book 6.3", "Expected SARSA at least as good as SARSA", 1.0, "return per episode",
           "one step of Cliff Walking's -1 per step: less than a step per episode is no difference"),
    Margin("book 6.3", "an asymptote collapses", 5.0, "return per episode",
           "5 steps per episode, against the book's axis from -160 to 0"),
)}
"""Every margin, by ``"<study>: <what it bounds>"``."""


def margin(study: str, bounds: str) -> float:
    return MARGINS[f"{study}: {bounds}"].value


def detectable_difference(spread: float, seeds: int, level: float = ALPHA, power: float = POWER) -> float:
    """The smallest true mean difference a two-sided paired t test at ``level`` finds with probability ``power``
    over ``seeds`` paired seeds whose differences have standard deviation ``spread`` (exact: the noncentral t).
    NaN with fewer than two seeds; 0 where the spread is 0."""
    if seeds < 2 or not math.isfinite(spread):
        return math.nan
    if spread == 0:
        return 0.0
    df = seeds - 1
    critical = stats.t.ppf(1 - level / 2, df)

    def shortfall(effect: float) -> float:
        shift = effect * math.sqrt(seeds)
        wrong_side = stats.nct.cdf(-critical, df, shift)  # negligible; scipy gives NaN far out in the tail
        return stats.nct.sf(critical, df, shift) + (wrong_side if math.isfinite(wrong_side) else 0.0) - power

    rough = (critical + stats.t.ppf(power, df)) / math.sqrt(seeds)  # the normal approximation's answer
    return float(optimize.brentq(shortfall, 0.0, 2.0 * rough)) * spread


def provable_margin(spread: float, seeds: int, level: float = ALPHA, power: float = POWER) -> float:
    """The smallest margin ``m`` that two one-sided t tests at ``level`` prove (the difference within ``±m``) with
    probability about ``power`` when the true difference is 0, over ``seeds`` paired seeds of spread ``spread``:
    ``(t_{1-level} + t_{(1+power)/2}) spread / sqrt(seeds)`` with ``seeds - 1`` degrees of freedom (Chow, Shao and
    Wang 2008, section 3.2). NaN with fewer than two seeds."""
    if seeds < 2 or not math.isfinite(spread):
        return math.nan
    df = seeds - 1
    return float((stats.t.ppf(1 - level, df) + stats.t.ppf((1 + power) / 2, df)) * spread / math.sqrt(seeds))
