"""Two-level intervals (seeds, then games) for ratings and scores, on inputs whose answers are computed by hand or by
enumerating every resample: one seed, all draws, a perfect score, repeated games, and seeds that disagree."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy import stats

from rlcompare.stats.ratings import bootstrap_ratings, fit_ratings
from rlcompare.stats.seeded_ratings import SeededGame, distinct, seeded_ratings, seeded_scores, seeds_of


def record(player: str, seed: int, opponent: str, wins: int, draws: int, losses: int,
           opponent_seed: int = -1) -> list[SeededGame]:
    """``player``'s (of ``seed``) games against ``opponent``, colours alternating, every game distinct."""
    scores = [1.0] * wins + [0.5] * draws + [0.0] * losses
    return [SeededGame(player, opponent, s, seed, opponent_seed, f"{player}{seed}-{k}") if k % 2 == 0 else
            SeededGame(opponent, player, 1 - s, opponent_seed, seed, f"{player}{seed}-{k}")
            for k, s in enumerate(scores)]


def elo(points: float, games: float) -> float:
    """The Bradley-Terry rating difference of two players from one's points over their games (hand formula)."""
    return 400 * math.log10(points / (games - points))


DISAGREE = record("A", 0, "random", 10, 0, 0) + record("A", 1, "random", 0, 10, 0) + \
    record("A", 2, "random", 0, 0, 10)
"""Three seeds of one method: one won every game against random, one drew every game, one lost every game."""


def test_seeds_that_disagree_widen_the_interval_by_their_spread_as_enumerating_every_resample_says():
    rated = seeded_ratings(DISAGREE, "random", resamples=1000)["A"]
    # pooled: 10 wins, 10 draws, 10 losses and the prior's virtual draw: exactly even
    assert rated.estimate.value == pytest.approx(0.0, abs=1e-6)
    # each seed alone: its 10 games and the virtual draw
    assert rated.per_seed == pytest.approx({0: elo(10.5, 11), 1: 0.0, 2: elo(0.5, 11)}, abs=1e-6)
    assert rated.spread == pytest.approx(elo(10.5, 11), abs=1e-6)  # the sd of (+r, 0, -r) is r: 528.9
    # games alone: every seed's games are all alike, so redrawing them changes nothing
    assert (rated.games_only.low, rated.games_only.high) == pytest.approx((0.0, 0.0), abs=1e-6)
    # seeds, then games: the games are fixed by the seeds drawn; every one of the 27 ordered draws of 3 seeds
    exact = sorted(elo(10 * draw.count(0) + 5 * draw.count(1) + 0.5, 31)
                   for draw in itertools.product(range(3), repeat=3))
    # three copies of the losing seed (1 in 27, 3.7% > 2.5%) is the 2.5% quantile; three of the winning one the 97.5%
    assert (exact[0], exact[-1]) == pytest.approx((elo(0.5, 31), elo(30.5, 31)))  # -714 and +714
    assert (rated.estimate.low, rated.estimate.high) == pytest.approx((exact[0], exact[-1]), abs=1e-6)
    # and the pooled bootstrap of the games alone, blind to seeds, is narrower than the between-seed spread
    pooled = bootstrap_ratings([g[:3] for g in DISAGREE], "random", resamples=1000)["A"]
    assert rated.estimate.high - rated.estimate.low > pooled.high - pooled.low + 2 * rated.spread


def test_scores_of_seeds_that_disagree_range_over_every_share_the_seeds_allow():
    scored = seeded_scores(DISAGREE, "random", resamples=1000)["A"]
    assert scored.estimate.value == 0.5
    assert scored.per_seed == {0: 1.0, 1: 0.5, 2: 0.0}
    assert scored.spread == pytest.approx(0.5)
    assert (scored.estimate.low, scored.estimate.high) == (0.0, 1.0)  # all-losing (1 in 27) and all-winning draws
    wilson = stats.binomtest(15, 30).proportion_ci(0.95, "wilson")  # 15 points of 30, as if 15 wins
    assert (scored.games_only.low, scored.games_only.high) == pytest.approx((wilson.low, wilson.high))


def test_score_intervals_follow_the_exact_distribution_of_the_two_level_resamples():
    """Two seeds of two games: one won and lost, one drew both. Enumerating the 4 ordered seed draws and then the
    games of each copy gives the exact distribution of the pooled share; its 1% and 99% quantiles are 0 and 1 (each
    1/64 > 1%), where redrawing the games alone could not go below 1/4 or above 3/4."""
    games = record("A", 0, "random", 1, 0, 1) + record("A", 1, "random", 0, 2, 0)
    outcomes = {0: (1.0, 0.0), 1: (0.5, 0.5)}
    probability: dict[float, float] = {}
    for draw in itertools.product((0, 1), repeat=2):
        for scores in itertools.product(*(itertools.product(outcomes[s], repeat=2) for s in draw)):
            share = sum(sum(pair) for pair in scores) / 4
            probability[share] = probability.get(share, 0) + 1 / 4 / 16
    cumulative = np.cumsum([probability[s] for s in sorted(probability)])
    assert probability[0.0] == probability[1.0] == 1 / 64
    lowest = sorted(probability)[int(np.searchsorted(cumulative, 0.01))]
    highest = sorted(probability)[int(np.searchsorted(cumulative, 0.99))]
    scored = seeded_scores(games, "random", resamples=4000, confidence=0.98)["A"]
    assert (scored.estimate.low, scored.estimate.high) == (lowest, highest) == (0.0, 1.0)


def test_one_seed_has_no_spread_and_its_interval_is_the_games_only_bootstrap():
    games = record("A", 3, "random", 6, 3, 3) + record("A", 3, "material", 2, 4, 6) + \
        record("material", -1, "random", 5, 2, 5)
    assert seeds_of(games) == (3,)
    rated = seeded_ratings(games, "random", resamples=500, seed=2)
    plain = bootstrap_ratings([g[:3] for g in games], "random", resamples=500, seed=2)
    for name in ("A", "material"):
        assert rated[name].estimate == rated[name].games_only == plain[name]
    assert math.isnan(rated["A"].spread)
    assert rated["A"].per_seed == pytest.approx({3: plain["A"].value})
    assert rated["material"].per_seed == {}
    scored = seeded_scores(games, "random")["A"]
    assert math.isnan(scored.spread)
    assert scored.per_seed == {3: 0.625}


def test_all_draws_rate_everyone_equal_with_no_width_anywhere():
    games = [g for s in range(3) for g in record("A", s, "random", 0, 6, 0) + record("B", s, "random", 0, 4, 0)
             + record("A", s, "B", 0, 2, 0, opponent_seed=s)]
    rated = seeded_ratings(games, "random", anchor_rating=100.0, resamples=200)
    for name in ("A", "B", "random"):
        assert tuple(rated[name].estimate) == pytest.approx((100.0, 100.0, 100.0))
        assert tuple(rated[name].games_only) == pytest.approx((100.0, 100.0, 100.0))
    assert rated["A"].per_seed == pytest.approx({0: 100.0, 1: 100.0, 2: 100.0})
    assert rated["A"].spread == pytest.approx(0.0)
    scored = seeded_scores(games, "random", resamples=200)
    assert tuple(scored["A"].estimate) == (0.5, 0.5, 0.5)
    assert scored["B"].spread == 0.0


def test_a_perfect_score_is_finite_through_the_prior_and_has_no_width():
    games = record("A", 0, "random", 5, 0, 0) + record("A", 1, "random", 5, 0, 0)
    rated = seeded_ratings(games, "random", resamples=200)["A"]
    assert tuple(rated.estimate) == pytest.approx((elo(10.5, 11),) * 3)  # every resample: 10 wins and the prior
    assert tuple(rated.games_only) == pytest.approx((elo(10.5, 11),) * 3)
    assert rated.per_seed == pytest.approx({0: elo(5.5, 6), 1: elo(5.5, 6)})  # the prior weighs more on 5 games
    assert rated.spread == pytest.approx(0.0)
    assert tuple(seeded_scores(games, "random", resamples=200)["A"].estimate) == (1.0, 1.0, 1.0)
    with pytest.raises(ValueError, match="no finite maximum-likelihood ratings"):
        seeded_ratings(games, "random", prior_draws=0, resamples=200)


def test_a_repeated_game_counts_once():
    """Two deterministic networks playing one opening 32 times with each colour: 2 games, not 64."""
    once = [*record("A", 0, "B", 1, 0, 0, opponent_seed=0)[:1], SeededGame("B", "A", 0.5, 0, 0, "other")]
    repeated = once * 32
    assert distinct(repeated) == once
    base = record("A", 0, "random", 3, 2, 3) + record("B", 0, "random", 2, 4, 2)
    assert repr(seeded_ratings(base + repeated, "random", resamples=100)) == repr(
        seeded_ratings(base + once, "random", resamples=100))  # repr: NaN spreads compare equal
    assert fit_ratings([g[:3] for g in base + once], "random") == pytest.approx(
        {k: v.estimate.value for k, v in seeded_ratings(base + repeated, "random", resamples=100).items()})
    anonymous = [SeededGame("A", "B", 1.0, 0, 0)] * 3  # no identity: every game counts
    assert distinct(anonymous) == anonymous


def test_the_bootstrap_is_deterministic_for_a_seed_and_refuses_seeds_the_methods_do_not_share():
    games = DISAGREE + record("B", 0, "random", 3, 3, 4) + record("B", 1, "random", 6, 1, 3) + \
        record("B", 2, "random", 2, 2, 6)
    first = repr(seeded_ratings(games, "random", resamples=100, seed=1))  # repr: NaN spreads compare equal
    assert first == repr(seeded_ratings(games, "random", resamples=100, seed=1))
    assert first != repr(seeded_ratings(games, "random", resamples=100, seed=2))
    apart = record("A", 0, "random", 2, 2, 2) + record("B", 1, "A", 2, 2, 2, opponent_seed=0)
    with pytest.raises(ValueError, match="seeds differ"):
        seeded_ratings(apart, "random", resamples=50)
    with pytest.raises(ValueError, match="resamples must be at least 2"):
        seeded_ratings(games, "random", resamples=1)
