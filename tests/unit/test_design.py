"""What a design can decide before it runs: each rank test's smallest p against scipy's exact tests on the most
extreme data, Holm's strictest level, and the seeds each study's family needs, computed by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from rlcompare.stats.design import (
    GATE,
    RANK_SUM,
    SIGNED_RANK,
    can_pass,
    detectable_difference,
    reach,
    seeds_needed,
    smallest_p,
    strictest_level,
)


@pytest.mark.parametrize("seeds", range(1, 13))
def test_the_signed_rank_tests_smallest_p_is_every_seed_on_one_side(seeds):
    differences = np.arange(1.0, seeds + 1)
    assert smallest_p(SIGNED_RANK, seeds) == pytest.approx(stats.wilcoxon(differences, method="exact").pvalue)
    assert smallest_p(GATE, seeds) == pytest.approx(
        stats.wilcoxon(differences, method="exact", alternative="greater").pvalue)
    # no arrangement of the same number of seeds does better
    mixed = differences * np.where(np.arange(seeds) == 0, -1, 1)
    assert stats.wilcoxon(mixed, method="exact").pvalue >= smallest_p(SIGNED_RANK, seeds)


@pytest.mark.parametrize(("n", "m"), [(1, 1), (2, 3), (3, 3), (4, 5), (5, 5), (8, 8), (3, 9)])
def test_the_rank_sum_tests_smallest_p_is_one_side_wholly_above_the_other(n, m):
    a, b = np.arange(n) + 100.0, np.arange(m, dtype=float)
    exact = stats.mannwhitneyu(a, b, method="exact").pvalue
    assert smallest_p(RANK_SUM, n, m) == pytest.approx(exact)
    assert smallest_p(RANK_SUM, n, m) == min(1.0, 2 / math.comb(n + m, n))


def test_ties_only_raise_the_rank_sum_tests_p():
    """4 seeds a side, A's all at a cap of 500: scipy's default falls back to its normal approximation with ties
    (0.0202); the exact permutation p is the smallest the design allows, 2 / C(8, 4) = 0.0286."""
    capped, other = np.full(4, 500.0), np.array([100.0, 200.0, 300.0, 400.0])
    assert smallest_p(RANK_SUM, 4) == pytest.approx(2 / 70)
    assert stats.mannwhitneyu(capped, other).pvalue < smallest_p(RANK_SUM, 4)  # the approximation goes below it
    assert stats.permutation_test((capped, other), lambda x, y: np.mean(x) - np.mean(y),
                                  n_resamples=np.inf, permutation_type="independent").pvalue == pytest.approx(2 / 70)


def test_no_seed_gives_no_evidence():
    assert smallest_p(SIGNED_RANK, 0) == smallest_p(GATE, 0) == smallest_p(RANK_SUM, 0, 3) == 1.0


def test_holms_strictest_level_is_the_level_over_the_family():
    assert strictest_level(1) == 0.05
    assert strictest_level(40) == pytest.approx(0.00125)
    with pytest.raises(ValueError, match="at least one test"):
        strictest_level(0)


@pytest.mark.parametrize(("test", "family", "needed"), [
    (GATE, 1, 5),  # 1/2^5 = 0.031; 1/2^4 = 0.0625: the learning gate cannot pass below 5 seeds
    (SIGNED_RANK, 1, 6),  # one game: 2/2^6 = 0.031 <= 0.05 < 2/2^5
    (SIGNED_RANK, 6, 8),  # Atari-5 with the overall row: 0.05/6 = 0.0083; 2/2^8 = 0.0078, 2/2^7 = 0.0156
    (SIGNED_RANK, 27, 11),  # Atari 100k's 26 games and the overall row: 0.00185; 2/2^11 = 0.00098, 2/2^10 = 0.00195
    (SIGNED_RANK, 40, 11),  # the chess endgames' 40 tests: 0.00125; 10 seeds give 0.00195
    (RANK_SUM, 1, 4),  # 3 seeds a side: 2/C(6,3) = 0.1; 4: 2/C(8,4) = 0.029
])
def test_the_seeds_each_family_needs(test, family, needed):
    assert seeds_needed(test, family) == needed
    assert can_pass(test, needed, family)
    assert not can_pass(test, needed - 1, family)


def test_a_design_that_cannot_decide_says_so_and_how_many_seeds_can():
    endgames = reach(SIGNED_RANK, 10, family=40)
    assert not endgames.can_decide
    assert endgames.sentence() == ("With 10 seeds the signed-rank test cannot give a p below 0.002, above the 0.0013 "
                                   "Holm asks over 40 tests: this design cannot decide; with 11 seeds it can.")
    assert reach(SIGNED_RANK, 11, family=40).can_decide
    assert reach(GATE, 5).sentence().endswith("this design can decide.")


def t_power(shift: float, freedom: int, level: float, one_sided: bool = False) -> float:
    """The t test's power at a standardised shift, from scipy's noncentral t (both tails where two-sided)."""
    critical = stats.t.ppf(1 - (level if one_sided else level / 2), freedom)
    return float(stats.nct.sf(critical, freedom, shift) + (0 if one_sided else stats.nct.cdf(-critical, freedom,
                                                                                             shift)))


def test_the_detectable_difference_is_the_t_tests_over_the_rank_tests_efficiency_by_hand():
    efficiency = math.sqrt(3 / math.pi)
    # rank-sum, 10 seeds a side, spread 1, one test: the t test's power at d * sqrt(3/pi) / sqrt(1/10 + 1/10) is 0.8
    found = detectable_difference(RANK_SUM, 1.0, 10)
    assert t_power(found * efficiency / math.sqrt(0.2), 18, 0.05) == pytest.approx(0.8, abs=1e-9)
    assert found == pytest.approx(1.3559, abs=1e-4)
    assert detectable_difference(RANK_SUM, 2.0, 10) == pytest.approx(2 * found)  # twice the spread, twice
    # the gate is one-sided at 0.05; Holm's level over 10 tests is 0.005
    gate = detectable_difference(GATE, 1.0, 10)
    assert t_power(gate * efficiency * math.sqrt(10), 9, 0.05, one_sided=True) == pytest.approx(0.8, abs=1e-9)
    holm = detectable_difference(SIGNED_RANK, 1.0, 20, family=10)
    assert t_power(holm * efficiency * math.sqrt(20), 19, 0.005) == pytest.approx(0.8, abs=1e-9)
    # a design that cannot pass detects nothing, however large
    assert detectable_difference(SIGNED_RANK, 1.0, 4) == math.inf
    assert detectable_difference(SIGNED_RANK, 1.0, 9, family=100) == math.inf


@pytest.mark.slow("simulates 4,000 exact rank tests")
@pytest.mark.parametrize(("test", "seeds", "family"), [(RANK_SUM, 12, 1), (SIGNED_RANK, 20, 10)])
def test_the_detectable_difference_is_found_about_four_times_in_five_by_scipys_exact_tests(test, seeds, family):
    rng = np.random.default_rng(7)
    spread, level = 2.0, 0.05 / family
    shift = detectable_difference(test, spread, seeds, family)
    found = 0
    for _ in range(2000):
        if test == RANK_SUM:
            p = stats.mannwhitneyu(rng.normal(shift, spread, seeds), rng.normal(0, spread, seeds),
                                   method="exact").pvalue
        else:
            p = stats.wilcoxon(rng.normal(shift, spread, seeds), method="exact").pvalue
        found += p <= level
    assert 0.74 <= found / 2000 <= 0.86


@pytest.mark.parametrize("test", [SIGNED_RANK, GATE, RANK_SUM])
def test_the_smallest_p_of_a_million_seeds_is_zero_not_an_overflow(test):
    assert smallest_p(test, 1_000_000) == 0.0
    assert smallest_p(test, 1_000_000, 3 if test == RANK_SUM else None) >= 0.0
    assert reach(test, 1_000_000, family=80).can_decide
