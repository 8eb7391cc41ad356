"""Elo ratings from games: the Bradley-Terry fit, its prior of virtual draws, bootstrap intervals, score records."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy import optimize, special, stats

from rlcompare.stats.ratings import (
    Game,
    Record,
    bootstrap_ratings,
    elo_difference,
    expected_score,
    fit_ratings,
    pair_records,
    player_records,
)

TRUE = {"random": -500.0, "material": 0.0, "stockfish": 350.0, "agent": 150.0}


def ladder(per_pair: int, seed: int, draw: float = 0.2, true: dict[str, float] = TRUE) -> list[Game]:
    """``per_pair`` games between every two players (colours alternating), won with the model's odds among the games
    not drawn, drawn with probability ``draw``."""
    rng = np.random.default_rng(seed)
    games = []
    for a, b in itertools.combinations(true, 2):
        for k in range(per_pair):
            white, black = (a, b) if k % 2 == 0 else (b, a)
            win = expected_score(true[white] - true[black])
            u = rng.random()
            games.append(Game(white, black, 0.5 if u < draw else 1.0 if u < draw + (1 - draw) * win else 0.0))
    return games


def games_of(a: str, b: str, wins: int, draws: int, losses: int) -> list[Game]:
    """``a``'s record against ``b``, colours alternating."""
    scores = [1.0] * wins + [0.5] * draws + [0.0] * losses
    return [Game(a, b, s) if k % 2 == 0 else Game(b, a, 1 - s) for k, s in enumerate(scores)]


def scipy_fit(games: list[Game], anchor: str, prior_draws: float) -> dict[str, float]:
    """The same model written independently: minus the log-likelihood of each game (and each pair's virtual draws)
    in Elo, minimised by BFGS over the players other than the anchor (rated 0)."""
    names = sorted({g.white for g in games} | {g.black for g in games})
    free = [n for n in names if n != anchor]
    pairs = {tuple(sorted((g.white, g.black))) for g in games}
    # (i, j, points of i, points of j): each game, and each pair's virtual draws
    terms = [(g.white, g.black, g.score, 1 - g.score) for g in games] + \
        [(a, b, prior_draws / 2, prior_draws / 2) for a, b in pairs]
    rows = np.array([[names.index(t[0]), names.index(t[1])] for t in terms])
    first, second = np.array([t[2] for t in terms]), np.array([t[3] for t in terms])
    scale = np.log(10) / 400

    def ratings(x: np.ndarray) -> np.ndarray:
        r = np.zeros(len(names))
        r[[names.index(n) for n in free]] = x * 100  # optimise in hundreds of Elo points, for conditioning
        return r

    def nll(x: np.ndarray) -> tuple[float, np.ndarray]:
        r = ratings(x)
        d = scale * (r[rows[:, 0]] - r[rows[:, 1]])
        value = -np.sum(first * special.log_expit(d) + second * special.log_expit(-d))
        per_term = -(first * special.expit(-d) - second * special.expit(d)) * scale
        grad = np.zeros(len(names))
        np.add.at(grad, rows[:, 0], per_term)
        np.add.at(grad, rows[:, 1], -per_term)
        return float(value), grad[[names.index(n) for n in free]] * 100

    result = optimize.minimize(nll, np.zeros(len(free)), jac=True, method="BFGS")
    # BFGS stops short of a tiny gtol ("precision loss"): polish by solving gradient = 0 (the minimum of a convex
    # function is its only stationary point), by Powell's hybrid method
    # (its own stopping test can complain of slow progress at rounding level: the gradient is what must vanish)
    result = optimize.root(lambda x: nll(x)[1], result.x, method="hybr", options={"xtol": 1e-13})
    assert np.abs(nll(result.x)[1]).max() < 1e-10, result
    return dict(zip(names, ratings(result.x), strict=True))


# --- score shares and Elo differences ---------------------------------------------------------------


def test_elo_difference_is_the_closed_form_and_expected_score_inverts_it():
    # 3 to 1 odds: 400 log10 3 = 190.848...; 10 to 1: 400 exactly
    assert elo_difference(0.75) == pytest.approx(400 * np.log10(3), abs=1e-12)
    assert elo_difference(10 / 11) == pytest.approx(400.0, abs=1e-9)
    assert elo_difference(0.5) == 0.0
    assert elo_difference(1.0) == np.inf
    assert elo_difference(0.0) == -np.inf
    for share in (0.01, 0.3, 0.5, 0.9, 0.999):
        assert expected_score(elo_difference(share)) == pytest.approx(share, rel=1e-12)
    with pytest.raises(ValueError, match="score share"):
        elo_difference(1.5)


def test_records_merge_colours_and_count_both_sides():
    games = [Game("a", "b", 1.0), Game("b", "a", 1.0), Game("b", "a", 0.5), Game("a", "c", 0.0)]
    pairs = pair_records(games)
    assert pairs[("a", "b")] == Record(wins=1, draws=1, losses=1)
    assert pairs[("b", "a")] == Record(wins=1, draws=1, losses=1)
    assert pairs[("c", "a")] == Record(wins=1, draws=0, losses=0)
    assert ("b", "c") not in pairs
    totals = player_records(games)
    assert totals == {"a": Record(1, 1, 2), "b": Record(1, 1, 1), "c": Record(1, 0, 0)}
    assert totals["a"].games == 4
    assert totals["a"].points == 1.5
    assert totals["a"].share == 0.375


@pytest.mark.parametrize(("wins", "games"), [(0, 10), (3, 10), (10, 10), (17, 40), (1, 1)])
@pytest.mark.parametrize("confidence", [0.95, 0.8])
def test_score_interval_without_draws_is_scipys_wilson_interval(wins, games, confidence):
    estimate = Record(wins, 0, games - wins).interval(confidence)
    expected = stats.binomtest(wins, games).proportion_ci(confidence, method="wilson")
    assert estimate.value == wins / games
    assert estimate.low == pytest.approx(expected.low, abs=1e-12)
    assert estimate.high == pytest.approx(expected.high, abs=1e-12)


def test_score_interval_with_draws_covers_at_least_the_nominal_rate():
    # Exact coverage over all 496 trinomial outcomes of 30 games with many draws: share 0.45, a game's variance
    # 0.2 + 0.5 / 4 - 0.45² = 0.1225 against the 0.2475 Wilson assumes, so the interval errs wide (0.994 here; Wald's
    # interval on the trinomial variance would cover 0.933).
    n, p_win, p_draw = 30, 0.2, 0.5
    true_share = p_win + p_draw / 2
    coverage = 0.0
    for wins in range(n + 1):
        for draws in range(n + 1 - wins):
            low, high = Record(wins, draws, n - wins - draws).interval()[1:]
            if low <= true_share <= high:
                coverage += stats.multinomial.pmf([wins, draws, n - wins - draws], n, [p_win, p_draw, 0.3])
    assert 0.95 <= coverage < 1.0


def test_score_interval_of_no_games_is_nan():
    assert all(np.isnan(Record(0, 0, 0).interval()))


# --- the fit ------------------------------------------------------------------------------------------


@pytest.mark.parametrize(("wins", "draws", "losses"), [(7, 0, 3), (5, 4, 1), (2, 6, 2), (1, 1, 8), (30, 1, 0)])
def test_two_players_get_the_closed_form_difference(wins, draws, losses):
    games = games_of("a", "b", wins, draws, losses)
    n, points = wins + draws + losses, wins + draws / 2
    plain = fit_ratings(games, anchor="b", prior_draws=0)
    assert plain["a"] == pytest.approx(400 * np.log10(points / (n - points)), abs=1e-9)
    assert plain["b"] == 0.0
    # three virtual draws: 1.5 points more in 3 games more
    prior = fit_ratings(games, anchor="b", prior_draws=3)
    assert prior["a"] == pytest.approx(elo_difference((points + 1.5) / (n + 3)), abs=1e-9)


@pytest.mark.parametrize("prior_draws", [0.0, 1.0, 2.5])
def test_several_players_fit_equals_scipy_minimising_the_likelihood(prior_draws):
    games = ladder(per_pair=12, seed=3)
    fitted = fit_ratings(games, anchor="material", prior_draws=prior_draws)
    expected = scipy_fit(games, anchor="material", prior_draws=prior_draws)
    assert fitted.keys() == expected.keys()
    for name in fitted:
        assert fitted[name] == pytest.approx(expected[name], abs=1e-6), name


def test_the_prior_pulls_ratings_together():
    games = ladder(per_pair=12, seed=3)
    spread = [np.ptp(list(fit_ratings(games, "material", prior_draws=p).values())) for p in (0, 1, 4, 16)]
    assert np.all(np.diff(spread) < 0)


def test_the_anchor_gets_exactly_its_rating_and_the_others_shift_with_it():
    games = ladder(per_pair=6, seed=5)
    at_zero = fit_ratings(games, anchor="stockfish")
    at_1350 = fit_ratings(games, anchor="stockfish", anchor_rating=1350.0)
    assert at_1350["stockfish"] == 1350.0
    assert at_zero["stockfish"] == 0.0
    for name in at_zero:
        assert at_1350[name] - at_zero[name] == pytest.approx(1350.0, abs=1e-9)
    # another anchor: the same differences
    other = fit_ratings(games, anchor="random", anchor_rating=-7.0)
    assert other["random"] == -7.0
    for name in at_zero:
        assert other[name] - other["random"] == pytest.approx(at_zero[name] - at_zero["random"], abs=1e-8)


def test_ratings_do_not_depend_on_the_order_or_colours_of_games():
    games = ladder(per_pair=6, seed=7)
    swapped = [Game(g.black, g.white, 1 - g.score) for g in games]
    shuffled = [swapped[i] for i in np.random.default_rng(0).permutation(len(swapped))]
    fitted, again = fit_ratings(games, "agent"), fit_ratings(shuffled, "agent")
    assert fitted == pytest.approx(again, abs=1e-9)
    assert len(set(fitted.values())) == 4


def test_a_perfect_score_is_finite_with_the_prior_and_refused_without_it():
    games = games_of("agent", "random", 10, 0, 0)
    with_prior = fit_ratings(games, anchor="random", prior_draws=1)
    assert np.isfinite(with_prior["agent"])
    assert with_prior["agent"] == pytest.approx(elo_difference(10.5 / 11), abs=1e-9)
    refusal = r"unbeaten by the others they met: agent; scoreless .*: random; use prior_draws > 0"
    with pytest.raises(ValueError, match=refusal):
        fit_ratings(games, anchor="random", prior_draws=0)


def test_the_refusal_names_groups_that_won_everything_against_the_rest():
    # agent and stockfish drew each other and beat everyone else; material and random split their games
    games = (games_of("agent", "stockfish", 0, 2, 0) + games_of("material", "random", 1, 0, 1)
             + games_of("agent", "material", 2, 0, 0) + games_of("stockfish", "random", 2, 0, 0))
    with pytest.raises(ValueError, match=r"unbeaten by the others they met: agent, stockfish; .*: material, random;"):
        fit_ratings(games, anchor="random", prior_draws=0)
    assert set(fit_ratings(games, anchor="random", prior_draws=0.5)) == {"agent", "material", "random", "stockfish"}


def test_players_with_no_games_to_the_anchor_are_named():
    games = games_of("a", "b", 1, 1, 1) + games_of("c", "d", 2, 0, 1)
    with pytest.raises(ValueError, match=r"no games connect c, d to the anchor 'a'"):
        fit_ratings(games, anchor="a")
    with pytest.raises(ValueError, match="no games connect"):
        bootstrap_ratings(games, anchor="a", resamples=10)


@pytest.mark.parametrize(
    ("games", "message"),
    [([Game("a", "a", 1.0)], "cannot play itself"), ([Game("a", "b", 0.25)], "1, 0.5 or 0"), ([], "no games"),
     ([Game("a", "b", 1.0), Game("b", "a", 1.0)], "the anchor 'z' played no game")],
)
def test_bad_games_are_refused(games, message):
    with pytest.raises(ValueError, match=message):
        fit_ratings(games, anchor="z")


def test_a_negative_prior_is_refused():
    with pytest.raises(ValueError, match="prior_draws"):
        fit_ratings(games_of("a", "b", 1, 0, 1), anchor="a", prior_draws=-1)


# --- bootstrap intervals ---------------------------------------------------------------------------


def test_bootstrap_is_deterministic_for_a_seed_and_contains_the_estimate():
    games = ladder(per_pair=10, seed=11)
    first = bootstrap_ratings(games, "stockfish", 1350.0, resamples=500, seed=4)
    assert first == bootstrap_ratings(games, "stockfish", 1350.0, resamples=500, seed=4)
    assert first != bootstrap_ratings(games, "stockfish", 1350.0, resamples=500, seed=5)
    fitted = fit_ratings(games, "stockfish", 1350.0)
    for name, estimate in first.items():
        assert estimate.value == fitted[name]
        assert estimate.low <= estimate.value <= estimate.high
    assert first["stockfish"] == (1350.0, 1350.0, 1350.0)
    assert all(first[name].high - first[name].low > 50 for name in ("agent", "material", "random"))


def test_bootstrap_intervals_narrow_with_more_games():
    # four times the games: about half the width
    few = bootstrap_ratings(ladder(per_pair=10, seed=13), "material", resamples=400)
    many = bootstrap_ratings(ladder(per_pair=40, seed=13), "material", resamples=400)
    for name in ("agent", "random", "stockfish"):
        ratio = (many[name].high - many[name].low) / (few[name].high - few[name].low)
        assert 0.3 < ratio < 0.8, name


def test_bootstrap_of_two_players_follows_the_score_share():
    # Two players, 40 games: a resample's difference is elo_difference of its share with the virtual draw, a monotone
    # map, so the interval is the map of the share's percentiles (here from 20,000 draws of the trinomial). Shares
    # lie on a lattice of half points in 41, so the two sets of resamples may pick neighbouring lattice points.
    games = games_of("a", "b", 22, 8, 10)
    estimate = bootstrap_ratings(games, "b", resamples=2000, seed=1)["a"]
    shares = (np.random.default_rng(2).multinomial(40, [22 / 40, 8 / 40, 10 / 40], 20_000) @ [1, 0.5, 0] + 0.5) / 41
    for bound, share in zip(estimate[1:], np.quantile(shares, [0.025, 0.975]), strict=True):
        lattice_step = elo_difference(share + 1 / 82) - elo_difference(share)
        assert bound == pytest.approx(elo_difference(share), abs=lattice_step)


def test_bootstrap_without_the_prior_refuses_resamples_with_a_perfect_score():
    games = games_of("a", "b", 2, 0, 1)  # 8 in 27 resamples have three wins, 1 in 27 none
    with pytest.raises(ValueError, match=r"of 200 resamples have no finite"):
        bootstrap_ratings(games, "b", prior_draws=0, resamples=200)
    assert np.isfinite(bootstrap_ratings(games, "b", prior_draws=1, resamples=200)["a"].high)
