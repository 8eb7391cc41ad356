"""How large a difference the seeds a study runs could detect, from the seed-to-seed spread it measured: the
smallest difference a paired t test finds four times in five, and the smallest margin two one-sided tests
(Schuirmann 1987) prove four times in five when there is no difference at all. A study with too few seeds for a
margin says "not resolved", never "equivalent" (``docs/why.md``, "Every margin, its reason and its power")."""

from __future__ import annotations

import math

ALPHA = 0.05
"""Family-wise error rate of one report's claims (here, with no import of scipy, for the plans' design)."""
POWER = 0.8
"""The chance of detection the power columns are read at (Cohen 1988's convention)."""


def detectable_difference(spread: float, seeds: int, level: float = ALPHA, power: float = POWER, *,
                          other_seeds: int | None = None, one_sided: bool = False) -> float:
    """The smallest true mean difference a two-sided paired t test at ``level`` finds with probability ``power``
    over ``seeds`` paired seeds whose differences have standard deviation ``spread`` (exact: the noncentral t);
    with ``other_seeds``, the two-sample t test of ``seeds`` against ``other_seeds`` independent seeds, each side
    of spread ``spread``; ``one_sided``: the test of one direction at ``level``. NaN with too few seeds to test;
    0 where the spread is 0."""
    df = seeds - 1 if other_seeds is None else seeds + other_seeds - 2
    if seeds < 1 or df < 1 or not math.isfinite(spread):
        return math.nan
    if spread == 0:
        return 0.0
    from scipy import optimize, stats  # here: a plan imports this module, and most plans read no spread

    scale = math.sqrt(1 / seeds + (0 if other_seeds is None else 1 / other_seeds))
    critical = stats.t.ppf(1 - (level if one_sided else level / 2), df)

    def shortfall(effect: float) -> float:
        shift = effect / scale
        wrong_side = 0.0 if one_sided else stats.nct.cdf(-critical, df, shift)  # scipy's NaN far in the tail
        return stats.nct.sf(critical, df, shift) + (wrong_side if math.isfinite(wrong_side) else 0.0) - power

    rough = (critical + stats.t.ppf(power, df)) * scale  # the normal approximation's answer
    return float(optimize.brentq(shortfall, 0.0, 2.0 * rough)) * spread


def provable_margin(spread: float, seeds: int, level: float = ALPHA, power: float = POWER) -> float:
    """The smallest margin ``m`` that two one-sided t tests at ``level`` prove (the difference within ``±m``) with
    probability about ``power`` when the true difference is 0, over ``seeds`` paired seeds of spread ``spread``:
    ``(t_{1-level} + t_{(1+power)/2}) spread / sqrt(seeds)`` with ``seeds - 1`` degrees of freedom (Chow, Shao and
    Wang 2008, section 3.2). NaN with fewer than two seeds."""
    if seeds < 2 or not math.isfinite(spread):
        return math.nan
    from scipy import stats

    df = seeds - 1
    return float((stats.t.ppf(1 - level, df) + stats.t.ppf((1 + power) / 2, df)) * spread / math.sqrt(seeds))
