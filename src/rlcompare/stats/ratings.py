"""Chess-style ratings from games, for a rating ladder of players who meet in pairs.

The model is Bradley and Terry's (1952, "Rank analysis of incomplete block designs: I. The method of paired
comparisons", Biometrika 39(3/4)) on Elo's scale (Elo 1978, *The Rating of Chessplayers, Past and Present*):

    P(i beats j) = 1 / (1 + 10^((R_j - R_i) / 400)),

so 400 points are odds of 10 to 1. A draw counts as half a win and half a loss. The ratings maximise the likelihood
of the games, found by Newton's method on the concave log-likelihood (Hunter 2004, "MM algorithms for generalized
Bradley-Terry models", Ann. Statist. 32(1), gives the likelihood and the slower MM alternative), and are shifted so
that an anchor (e.g. Stockfish at UCI_Elo 1350) has a given rating: the games identify only differences. There is
no white-advantage term: the ladder's games come in colour-swapped pairs.

A finite maximum exists exactly when, however the players are split in two, each part has scored against the
other (Zermelo 1929, Math. Z. 29; Ford 1957, "Solution of a ranking problem from binary comparisons", Amer. Math.
Monthly 64(8)), so a player who won every game has none. ``prior_draws`` adds that many virtual draws between every
pair of players who met, as Coulom's BayesElo does: the ratings stay finite and are pulled a little towards each
other. ``prior_draws=0`` is the plain maximum-likelihood estimate, and where it does not exist :func:`fit_ratings`
raises a ``ValueError`` naming the unbeaten and the scoreless players rather than returning infinities.

A score share carries Wilson's (1927, "Probable inference, the law of succession, and statistical inference", JASA
22(158)) score interval with draws as half points; ratings carry percentile bootstrap intervals (Efron and
Tibshirani 1993, *An Introduction to the Bootstrap*, ch. 13) over games resampled within each pairing.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import NamedTuple

import numpy as np

from rlcompare.stats.intervals import Estimate

ELO_SCALE = 400.0 / np.log(10.0)
"""Elo points per unit of natural-log strength: ``R = ELO_SCALE * theta``."""
_TOLERANCE = 1e-9
"""Newton stops when its largest step in natural-log strength (``ELO_SCALE`` times smaller than in Elo) is below."""
_MAX_ITERATIONS = 100
_MAX_HALVINGS = 60


class Game(NamedTuple):
    """One game: ``score`` is white's, 1 (white won), 0.5 (drawn) or 0 (black won)."""

    white: str
    black: str
    score: float


class Record(NamedTuple):
    """Wins, draws and losses of a player (against one opponent or all of them)."""

    wins: int
    draws: int
    losses: int

    @property
    def games(self) -> int:
        return self.wins + self.draws + self.losses

    @property
    def points(self) -> float:
        return self.wins + self.draws / 2

    @property
    def share(self) -> float:
        """Points per game; NaN without games."""
        return self.points / self.games if self.games else np.nan

    def interval(self, confidence: float = 0.95) -> Estimate:
        """The score share with Wilson's score interval, each game counted as a Bernoulli trial worth its points.

        Without draws this is the binomial Wilson interval (``scipy.stats.binomtest(wins, games)
        .proportion_ci(confidence, "wilson")``). A game's score ``X`` lies in [0, 1], so ``Var X <= s (1 - s)``: draws
        only shrink the variance, and with them the interval is conservative. No games: NaN throughout.
        """
        from scipy import stats

        if not self.games:
            return Estimate(np.nan, np.nan, np.nan)
        n, s = self.games, self.share
        z2 = float(stats.norm.ppf(0.5 + confidence / 2)) ** 2
        centre = (s + z2 / (2 * n)) / (1 + z2 / n)
        half = np.sqrt(z2 * s * (1 - s) / n + z2 * z2 / (4 * n * n)) / (1 + z2 / n)
        return Estimate(s, float(max(0.0, centre - half)), float(min(1.0, centre + half)))


def elo_difference(share: float) -> float:
    """The rating difference at which the model expects ``share`` of the points: ``400 log10(s / (1 - s))``;
    ±inf at a share of 1 or 0."""
    if not 0 <= share <= 1:
        raise ValueError(f"a score share lies in [0, 1], got {share}")
    if share in (0, 1):
        return float(np.inf if share == 1 else -np.inf)
    return float(400 * np.log10(share / (1 - share)))


def expected_score(difference: float) -> float:
    """The share of the points the model expects of a player rated ``difference`` above the opponent (the inverse
    of :func:`elo_difference`)."""
    from scipy import special

    return float(special.expit(difference / ELO_SCALE))


def _checked(games: Iterable[Game]) -> list[Game]:
    checked = [Game(*game) for game in games]
    for game in checked:
        if game.white == game.black:
            raise ValueError(f"a player cannot play itself: {game}")
        if game.score not in (0, 0.5, 1):
            raise ValueError(f"a game's score is 1, 0.5 or 0, got {game}")
    if not checked:
        raise ValueError("no games")
    return checked


def pair_records(games: Iterable[Game]) -> dict[tuple[str, str], Record]:
    """Each player's record against each opponent met, keyed ``(player, opponent)``, colours merged; every pair
    appears under both orders."""
    tally: dict[tuple[str, str], list[int]] = {}
    for game in _checked(games):
        for player, opponent, score in ((game.white, game.black, game.score), (game.black, game.white, 1 - game.score)):
            counts = tally.setdefault((player, opponent), [0, 0, 0])
            counts[0 if score == 1 else 1 if score == 0.5 else 2] += 1
    return {pair: Record(*counts) for pair, counts in sorted(tally.items())}


def player_records(games: Iterable[Game]) -> dict[str, Record]:
    """Each player's record against all opponents together."""
    totals: dict[str, list[int]] = {}
    for (player, _), record in pair_records(games).items():
        total = totals.setdefault(player, [0, 0, 0])
        for k, count in enumerate(record):
            total[k] += count
    return {player: Record(*total) for player, total in totals.items()}


class _Table(NamedTuple):
    """Games as arrays over players (sorted by name): ``wins[i, j]`` games i won against j, ``draws[i, j]`` games
    they drew (symmetric)."""

    names: list[str]
    wins: np.ndarray
    draws: np.ndarray

    @property
    def met(self) -> np.ndarray:
        return np.asarray((self.wins + self.wins.T + self.draws) > 0)


def _table(games: Iterable[Game], anchor: str) -> _Table:
    from scipy import sparse
    from scipy.sparse import csgraph

    records = pair_records(games)
    names = sorted({player for player, _ in records})
    if anchor not in names:
        raise ValueError(f"the anchor {anchor!r} played no game; players: {', '.join(names)}")
    index = {name: i for i, name in enumerate(names)}
    wins, draws = np.zeros((len(names), len(names))), np.zeros((len(names), len(names)))
    for (player, opponent), record in records.items():
        wins[index[player], index[opponent]] = record.wins
        draws[index[player], index[opponent]] = record.draws
    table = _Table(names, wins, draws)
    _, component = csgraph.connected_components(sparse.csr_array(table.met.astype(np.int8)), directed=False)
    apart = [name for name, c in zip(names, component, strict=True) if c != component[index[anchor]]]
    if apart:
        raise ValueError(f"no games connect {', '.join(apart)} to the anchor {anchor!r}: their ratings are undefined")
    return table


def _unbounded(points: np.ndarray, names: list[str]) -> str | None:
    """Why the plain maximum-likelihood ratings are infinite (``points[i, j]`` what i scored against j), or None
    when they are finite: the players split into groups each of which scored against every other (strongly
    connected), and the message names the groups no outsider scored against, and those that scored against
    nobody outside."""
    from scipy import sparse
    from scipy.sparse import csgraph

    scored = sparse.csr_array((points > 0).astype(np.int8))
    count, group = csgraph.connected_components(scored, directed=True, connection="strong")
    if count == 1:
        return None
    outside = group[:, None] != group[None, :]
    scored_in = np.zeros(count, dtype=bool)
    scored_out = np.zeros(count, dtype=bool)
    for i, j in zip(*np.nonzero((points > 0) & outside), strict=True):
        scored_out[group[i]], scored_in[group[j]] = True, True

    def members(groups: np.ndarray) -> str:
        return "; ".join(", ".join(name for name, g in zip(names, group, strict=True) if g == k)
                         for k in np.flatnonzero(groups))

    return (f"no finite maximum-likelihood ratings: unbeaten by the others they met: {members(~scored_in)}; "
            f"scoreless against the others they met: {members(~scored_out)}; use prior_draws > 0")


def _strongly_connected(scored: np.ndarray) -> np.ndarray:
    """Per resample, whether the directed graph ``scored[b, i, j]`` (i scored against j) is strongly connected: its
    reflexive transitive closure, by repeated squaring, is all true."""
    reach = scored | np.eye(scored.shape[1], dtype=bool)
    for _ in range(int(np.ceil(np.log2(max(scored.shape[1], 2))))):
        reach = (reach.astype(np.int64) @ reach.astype(np.int64)) > 0
    return np.asarray(reach.all(axis=(1, 2)))


def _log_likelihood(theta: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Per row of ``theta`` (resamples x players): ``sum_ij points_ij log P(i beats j)``."""
    from scipy import special

    likelihood: np.ndarray = np.einsum("bij,bij->b", points, special.log_expit(theta[:, :, None] - theta[:, None, :]))
    return likelihood


def _maximise(points: np.ndarray, games: np.ndarray, anchor: int, start: np.ndarray) -> np.ndarray:
    """Natural-log strengths (resamples x players, the anchor's 0) maximising each resample's likelihood, by Newton's
    method with step halving. ``points[b, i, j]``: what i scored against j; ``games = points + points^T``.

    The gradient is ``sum_j points_ij - games_ij p_ij`` and the Hessian minus the Laplacian of the weights
    ``games_ij p_ij (1 - p_ij)``: negative definite once the anchor's coordinate is fixed, for connected players.
    """
    from scipy import special

    free = np.arange(points.shape[1]) != anchor
    theta = np.array(start, dtype=np.float64)
    theta[:, ~free] = 0.0
    likelihood = _log_likelihood(theta, points)
    for _ in range(_MAX_ITERATIONS):
        p = special.expit(theta[:, :, None] - theta[:, None, :])
        gradient = (points - games * p).sum(axis=2)[:, free]
        weights = games * p * (1 - p)
        laplacian = weights.sum(axis=2)[:, :, None] * np.eye(weights.shape[1]) - weights
        step = np.zeros_like(theta)
        negative_hessian = laplacian[:, free][:, :, free]
        step[:, free] = np.linalg.solve(negative_hessian, gradient[..., None])[..., 0]
        size = np.ones(theta.shape[0])
        for _ in range(_MAX_HALVINGS):
            candidate = theta + size[:, None] * step
            new = _log_likelihood(candidate, points)
            worse = new < likelihood - 1e-12 * (1 + np.abs(likelihood))
            if not worse.any():
                break
            size[worse] /= 2
        theta, likelihood = candidate, new
        if np.abs(step).max() < _TOLERANCE:
            return theta
    raise RuntimeError(f"Newton's method did not converge in {_MAX_ITERATIONS} iterations")


def _points(wins: np.ndarray, draws: np.ndarray, met: np.ndarray, prior_draws: float) -> np.ndarray:
    return wins + (draws + prior_draws * met) / 2


def _checked_prior(prior_draws: float) -> None:
    if not prior_draws >= 0:
        raise ValueError(f"prior_draws cannot be negative, got {prior_draws}")


def fit_ratings(games: Iterable[Game], anchor: str, anchor_rating: float = 0.0,
                prior_draws: float = 1.0) -> dict[str, float]:
    """Maximum-likelihood Elo ratings of every player (sorted by name), ``anchor`` rated exactly ``anchor_rating``.

    ``prior_draws`` virtual draws are added between every pair of players who met (BayesElo's prior); with 0, games
    where some group of players won every game against the rest (a perfect score) have no finite estimate and raise
    ``ValueError`` naming those players. Players with no chain of games to the anchor raise ``ValueError`` naming them.
    """
    _checked_prior(prior_draws)
    table = _table(games, anchor)
    points = _points(table.wins, table.draws, table.met, prior_draws)
    if prior_draws == 0 and (reason := _unbounded(points, table.names)):
        raise ValueError(reason)
    a = table.names.index(anchor)
    theta = _maximise(points[None], (points + points.T)[None], a, np.zeros((1, len(table.names))))[0]
    return {name: anchor_rating + float(ELO_SCALE * t) for name, t in zip(table.names, theta, strict=True)}


def bootstrap_ratings(games: Iterable[Game], anchor: str, anchor_rating: float = 0.0, prior_draws: float = 1.0,
                      resamples: int = 1000, seed: int = 0, confidence: float = 0.95) -> dict[str, Estimate]:
    """:func:`fit_ratings` of every player with a percentile bootstrap interval, relative to the anchor (whose own
    interval is the point ``anchor_rating``).

    Each resample redraws, for every pair of players who met, as many games as they played from their own games with
    replacement (a bootstrap stratified by pairing: the schedule is fixed by design, the outcomes are random), then
    adds the ``prior_draws`` virtual draws and refits. Deterministic for a ``seed`` (``numpy.random.default_rng``).
    With ``prior_draws=0`` a resample with a perfect score has no finite estimate, and the call raises ``ValueError``.
    """
    if resamples < 2:
        raise ValueError(f"resamples must be at least 2, got {resamples}")
    if not 0 < confidence < 1:
        raise ValueError(f"confidence lies in (0, 1), got {confidence}")
    games = _checked(games)
    ratings = fit_ratings(games, anchor, anchor_rating, prior_draws)
    table = _table(games, anchor)
    n = len(table.names)
    rng = np.random.default_rng(seed)
    wins, draws = np.zeros((resamples, n, n)), np.zeros((resamples, n, n))
    for i, j in zip(*np.nonzero(np.triu(table.met)), strict=True):
        outcomes = np.array([table.wins[i, j], table.draws[i, j], table.wins[j, i]])
        drawn = rng.multinomial(int(outcomes.sum()), outcomes / outcomes.sum(), size=resamples)
        wins[:, i, j], wins[:, j, i] = drawn[:, 0], drawn[:, 2]
        draws[:, i, j] = draws[:, j, i] = drawn[:, 1]
    points = _points(wins, draws, table.met[None], prior_draws)
    if prior_draws == 0:
        unbounded = int((~_strongly_connected(points > 0)).sum())
        if unbounded:
            raise ValueError(f"{unbounded} of {resamples} resamples have no finite maximum-likelihood ratings "
                             "(a perfect score); use prior_draws > 0")
    a = table.names.index(anchor)
    start = np.array([(ratings[name] - anchor_rating) / ELO_SCALE for name in table.names])
    theta = _maximise(points, points + points.transpose(0, 2, 1), a, np.broadcast_to(start, (resamples, n)))
    low, high = np.quantile(anchor_rating + ELO_SCALE * theta, [(1 - confidence) / 2, (1 + confidence) / 2], axis=0)
    return {name: Estimate(ratings[name], float(lo), float(hi))
            for name, lo, hi in zip(table.names, low, high, strict=True)}
