"""The margins' table and the power functions: a paired t test finds the detectable difference four times in
five, two one-sided tests prove the provable margin about four times in five when there is no difference
(simulated with scipy's tests), and every study reads its margins from the one table."""

from __future__ import annotations

import re

import numpy as np
import pytest
from scipy import stats

from rlcompare.stats.claims import RATIO_FACTOR
from rlcompare.stats.power import POWER, detectable_difference, provable_margin
from rlcompare.stats.significance import tost
from rlcompare.studies.margins import MARGINS, margin, read_margins


@pytest.mark.parametrize(("seeds", "level"), [(10, 0.05), (30, 0.05 / 9), (8, 0.05 / 4)])
def test_a_paired_t_test_finds_the_detectable_difference_four_times_in_five(seeds: int, level: float) -> None:
    spread = 3.0
    effect = detectable_difference(spread, seeds, level)
    samples = np.random.default_rng(seeds).normal(effect, spread, (20_000, seeds))
    found = stats.ttest_1samp(samples, 0.0, axis=1).pvalue < level
    assert found.mean() == pytest.approx(POWER, abs=0.015)
    # half the effect is found far less often: the function is not just any number
    weaker = stats.ttest_1samp(samples - effect / 2, 0.0, axis=1).pvalue < level
    assert weaker.mean() < 0.5


@pytest.mark.slow("compiles or trains for a second or more")
@pytest.mark.parametrize("seeds", [10, 30])
def test_two_one_sided_tests_prove_the_provable_margin_about_four_times_in_five(seeds: int) -> None:
    spread = 2.0
    m = provable_margin(spread, seeds)
    rng = np.random.default_rng(seeds)
    proved = [tost(rng.normal(0.0, spread, seeds), -m, m).p_equivalent < 0.05 for _ in range(4000)]
    assert np.mean(proved) == pytest.approx(POWER, abs=0.04)
    narrower = [tost(rng.normal(0.0, spread, seeds), -m / 2, m / 2).p_equivalent < 0.05 for _ in range(2000)]
    assert np.mean(narrower) < 0.3


def test_power_scales_with_the_spread_and_shrinks_with_the_seeds() -> None:
    assert detectable_difference(2.0, 10) == pytest.approx(2 * detectable_difference(1.0, 10))
    assert detectable_difference(1.0, 40) < detectable_difference(1.0, 10) / 1.9
    assert detectable_difference(0.0, 10) == 0.0
    assert np.isnan(detectable_difference(1.0, 1))
    assert np.isnan(provable_margin(1.0, 1))


def test_every_margin_has_its_reason_and_the_studies_read_them_from_the_table() -> None:
    from rlcompare.studies.book import figure_6_3 as book_6_3
    from rlcompare.studies.deep import study as deep
    from rlcompare.studies.paper import claims as paper_claims

    assert all(m.reason and m.unit and m.value > 0 for m in MARGINS.values())
    assert margin("paper", "about R times (ratio)") == RATIO_FACTOR
    assert {env: margin("deep", f"{env} (final greedy return)") for env in deep.MARGIN} == deep.MARGIN
    assert margin("book 6.3", "Expected SARSA at least as good as SARSA") == book_6_3.NONINFERIORITY_MARGIN
    assert margin("book 6.3", "an asymptote collapses") == book_6_3.COLLAPSE_MARGIN
    same = {c.metric: c.bounds[1] for c in paper_claims.CLAIMS if c.kind == "within"}
    assert same == {"convergence_episode": margin("paper", "a similar time frame (convergence)"),
                    "greedy_return": margin("paper", "the same solution (greedy return)")}


def test_the_documented_table_is_the_codes() -> None:
    from pathlib import Path

    page = (Path(__file__).parents[2] / "docs" / "why.md").read_text(encoding="utf-8")
    for m in MARGINS.values():
        assert f"| {m.study} | {m.bounds} | {m.value:g} {m.unit} | {m.reason} |" in page


@pytest.mark.parametrize("entry", [
    'study = "x"\nbounds = "y"\nvalue = 0.0\nunit = "u"\nreason = "r"',  # not above 0
    'study = "x"\nbounds = "y"\nvalue = 1.0\nunit = "u"',  # no reason
    'study = "x"\nbounds = "y"\nvalue = 1.0\nunit = "u"\nreason = "r"\nextra = 1',
])
def test_a_margin_without_its_reason_or_above_zero_is_refused_naming_it(entry: str) -> None:
    refused = re.escape("margins.toml: a margin must give study, bounds, value, unit, reason")
    with pytest.raises(ValueError, match=refused):
        read_margins(f"[[margin]]\n{entry}\n")
