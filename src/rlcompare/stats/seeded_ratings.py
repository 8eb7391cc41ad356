"""Ratings and scores of players that are *methods*: each method plays through several trained networks (its seeds),
and a rating should speak of "a network that method trains", not of the few networks this study happened to train.

:func:`rlcompare.stats.ratings.bootstrap_ratings` resamples games within each pairing, the players fixed: its
interval covers the noise of the games of these networks only. Here the bootstrap has two levels, as for any
hierarchical sample (Davison and Hinkley 1997, *Bootstrap Methods and their Application*, section 3.8: resample the
top-level units with replacement, then the observations within each chosen unit): first the seeds, then the games.
A seed is the unit of the study's paired design: every method's network of one seed, with all their games. Each
resample draws as many seeds as there are, with replacement; a seed drawn ``m`` times brings ``m`` copies of each of
its pairings, the games of each copy redrawn with replacement (a pairing of ``n`` games drawn ``m`` times is one
multinomial draw of ``n m`` games from its own outcomes). A player with no seed (``-1``: the random player, the
material player, an engine) is one unit in every resample; only its games are redrawn.

So the interval of a method whose seeds disagree is wider than the games-only one by the spread between its seeds,
and with one seed it is the games-only interval: there is no between-seed spread to measure, and :class:`Levelled`
says so (``spread`` is NaN). Each method's rating per seed (the same fit on that seed's games and the seedless
players' games) and their standard deviation show the spread directly; scores against one opponent likewise.

A game carries its identity (``game``, e.g. a digest of its moves): games with the same non-empty identity between
the same units and colours are one game, counted once (:func:`distinct`). Two deterministic players who meet twice in
the same position play the same game; counting it twice would count the same evidence twice.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import NamedTuple

import numpy as np

from rlcompare.stats.intervals import Estimate
from rlcompare.stats.ratings import (
    ELO_SCALE,
    Game,
    Record,
    _checked_prior,
    _maximise,
    _strongly_connected,
    _table,
    fit_ratings,
    pair_records,
)

NO_SEED = -1
"""The seed of a player that is not a trained network (one unit in every resample)."""


class SeededGame(NamedTuple):
    """One game: ``score`` is White's (1, 0.5, 0); each side's seed (:data:`NO_SEED` for a player that is not a
    network); ``game`` its identity (empty: every game counts)."""

    white: str
    black: str
    score: float
    white_seed: int = NO_SEED
    black_seed: int = NO_SEED
    game: str = ""


class Levelled(NamedTuple):
    """A player's estimate over every game, with its two-level interval (seeds, then games) and its games-only
    interval (these networks' games); the estimate of each seed alone and their standard deviation (NaN with
    fewer than two seeds: no spread between seeds can be measured; empty and NaN for a player without seeds)."""

    estimate: Estimate
    games_only: Estimate
    per_seed: dict[int, float]
    spread: float


def distinct(games: Iterable[SeededGame]) -> list[SeededGame]:
    """The games, each repeated one (same players, seeds, colours and non-empty identity) kept once, in order."""
    seen: set[tuple[str, str, int, int, str]] = set()
    kept = []
    for game in (SeededGame(*g) for g in games):
        key = (game.white, game.black, game.white_seed, game.black_seed, game.game)
        if game.game and key in seen:
            continue
        seen.add(key)
        kept.append(game)
    return kept


def seeds_of(games: Iterable[SeededGame]) -> tuple[int, ...]:
    """The seeds of the games' networks, sorted."""
    return tuple(sorted({s for g in games for s in (g.white_seed, g.black_seed) if s != NO_SEED}))


def _plain(games: Iterable[SeededGame]) -> list[Game]:
    return [Game(g.white, g.black, g.score) for g in games]


def _of_seed(games: list[SeededGame], seed: int) -> list[SeededGame]:
    """The games of ``seed``'s networks and of the seedless players among themselves."""
    return [g for g in games if g.white_seed in (seed, NO_SEED) and g.black_seed in (seed, NO_SEED)]


def _spread(values: list[float]) -> float:
    return float(np.std(values, ddof=1)) if len(values) > 1 else float("nan")


def _multiplicities(seeds: tuple[int, ...], resamples: int, seed: int, levels: int) -> np.ndarray:
    """``(resamples, seeds)``: how often each seed is drawn in each resample (all ones with one level)."""
    if levels == 1 or not seeds:
        return np.ones((resamples, len(seeds)), dtype=np.int64)
    drawn = np.random.default_rng((seed, 1)).integers(len(seeds), size=(resamples, len(seeds)))
    return np.stack([np.bincount(row, minlength=len(seeds)) for row in drawn])


def _copies(units: tuple[int, int], seeds: tuple[int, ...], counts: np.ndarray) -> np.ndarray:
    """``(resamples,)``: the copies of a pairing of two units (their seeds) in each resample: the product of the
    multiplicities of their distinct seeds, 1 for two seedless players."""
    copies = np.ones(counts.shape[0], dtype=np.int64)
    for unit_seed in set(units) - {NO_SEED}:
        copies = copies * counts[:, seeds.index(unit_seed)]
    return copies


def _redrawn(outcomes: np.ndarray, copies: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """``(resamples, 3)``: ``copies[b]`` copies of a pairing's games, each redrawn from its ``outcomes`` (wins, draws,
    losses) with replacement."""
    total = int(outcomes.sum())
    return rng.multinomial(total * copies, outcomes / total)


def _checked_bootstrap(resamples: int, confidence: float) -> None:
    if resamples < 2:
        raise ValueError(f"resamples must be at least 2, got {resamples}")
    if not 0 < confidence < 1:
        raise ValueError(f"confidence lies in (0, 1), got {confidence}")


def _resampled_ratings(games: list[SeededGame], anchor: str, start: dict[str, float], prior_draws: float,
                       resamples: int, seed: int, levels: int) -> tuple[list[str], np.ndarray]:
    """The players' names and ``(resamples, players)`` Elo ratings relative to the anchor, each resample refitted."""
    table = _table(_plain(games), anchor)
    names, n = table.names, len(table.names)
    seeds = seeds_of(games)
    counts = _multiplicities(seeds, resamples, seed, levels)
    index = {name: i for i, name in enumerate(names)}
    pairings: dict[tuple[int, int, int, int], np.ndarray] = {}
    for g in games:  # by (first, second, first's seed, second's seed), first < second: wins, draws, losses of first
        i, j = index[g.white], index[g.black]
        key, score = ((i, j, g.white_seed, g.black_seed), g.score) if i < j else \
            ((j, i, g.black_seed, g.white_seed), 1 - g.score)
        pairings.setdefault(key, np.zeros(3, dtype=np.int64))[0 if score == 1 else 1 if score == 0.5 else 2] += 1
    rng = np.random.default_rng(seed)
    wins, draws = np.zeros((resamples, n, n)), np.zeros((resamples, n, n))
    for (i, j, seed_i, seed_j), outcomes in sorted(pairings.items()):
        drawn = _redrawn(outcomes, _copies((seed_i, seed_j), seeds, counts), rng)
        wins[:, i, j] += drawn[:, 0]
        wins[:, j, i] += drawn[:, 2]
        draws[:, i, j] += drawn[:, 1]
        draws[:, j, i] += drawn[:, 1]
    met = (wins + wins.transpose(0, 2, 1) + draws) > 0
    apart = int((~_strongly_connected(met)).sum())
    if apart:
        raise ValueError(f"{apart} of {resamples} resamples leave some player without games joining it to the others "
                         "(the methods' seeds differ); rate seeds that every method has")
    points = wins + (draws + prior_draws * met) / 2
    if prior_draws == 0:
        unbounded = int((~_strongly_connected(points > 0)).sum())
        if unbounded:
            raise ValueError(f"{unbounded} of {resamples} resamples have no finite maximum-likelihood ratings "
                             "(a perfect score); use prior_draws > 0")
    first = np.array([start[name] / ELO_SCALE for name in names])
    theta = _maximise(points, points + points.transpose(0, 2, 1), names.index(anchor),
                      np.broadcast_to(first, (resamples, n)))
    return names, ELO_SCALE * theta


def seeded_ratings(games: Iterable[SeededGame], anchor: str, anchor_rating: float = 0.0, prior_draws: float = 1.0,
                   resamples: int = 1000, seed: int = 0, confidence: float = 0.95) -> dict[str, Levelled]:
    """Every player's :func:`~rlcompare.stats.ratings.fit_ratings` over the :func:`distinct` games (seeds pooled
    by player), with percentile intervals from the two-level bootstrap (seeds, then games) and from games alone (the
    seeds fixed: :func:`~rlcompare.stats.ratings.bootstrap_ratings`'s resamples), each seed's own rating and their
    spread. Deterministic for a ``seed``; the anchor's intervals are its point."""
    _checked_prior(prior_draws)
    _checked_bootstrap(resamples, confidence)
    kept = distinct(games)
    pooled = fit_ratings(_plain(kept), anchor, 0.0, prior_draws)
    quantiles = [(1 - confidence) / 2, (1 + confidence) / 2]
    bounds = {}
    for levels in (2, 1):
        names, ratings = _resampled_ratings(kept, anchor, pooled, prior_draws, resamples, seed, levels)
        bounds[levels] = dict(zip(names, np.quantile(ratings, quantiles, axis=0).T.tolist(), strict=True))
    by_seed: dict[str, dict[int, float]] = {}
    for unit in seeds_of(kept):
        own = _of_seed(kept, unit)
        players = {g.white for g in own if g.white_seed == unit} | {g.black for g in own if g.black_seed == unit}
        for name, rating in fit_ratings(_plain(own), anchor, anchor_rating, prior_draws).items():
            if name in players:
                by_seed.setdefault(name, {})[unit] = rating
    result = {}
    for name, value in pooled.items():
        (low2, high2), (low1, high1) = bounds[2][name], bounds[1][name]
        per_seed = by_seed.get(name, {})
        result[name] = Levelled(Estimate(anchor_rating + value, anchor_rating + low2, anchor_rating + high2),
                                Estimate(anchor_rating + value, anchor_rating + low1, anchor_rating + high1),
                                per_seed, _spread(list(per_seed.values())))
    return result


def seeded_scores(games: Iterable[SeededGame], opponent: str, resamples: int = 1000, seed: int = 0,
                  confidence: float = 0.95) -> dict[str, Levelled]:
    """Each player's share of the points against ``opponent`` over the :func:`distinct` games: Wilson's interval for
    the games alone (:meth:`~rlcompare.stats.ratings.Record.interval`), the two-level percentile interval (seeds,
    then games), each seed's share and their spread. A seed's share weighs its games: a player's share is its points
    over its games, pooled."""
    _checked_bootstrap(resamples, confidence)
    kept = [g for g in distinct(games) if opponent in (g.white, g.black) and g.white != g.black]
    seeds = seeds_of(kept)
    counts = _multiplicities(seeds, resamples, seed, 2)
    rng = np.random.default_rng(seed)
    result = {}
    for name in sorted(({g.white for g in kept} | {g.black for g in kept}) - {opponent}):
        units: dict[int, Record] = {}
        for unit in sorted({g.white_seed if g.white == name else g.black_seed for g in kept if name in (g.white,
                                                                                                        g.black)}):
            own = [Game(g.white, g.black, g.score) for g in kept if (g.white, g.white_seed) == (name, unit)
                   or (g.black, g.black_seed) == (name, unit)]
            units[unit] = pair_records(own)[(name, opponent)]
        pooled = Record(*(sum(r[k] for r in units.values()) for k in range(3)))
        points, total = np.zeros(resamples), np.zeros(resamples)
        for unit, record in units.items():
            drawn = _redrawn(np.array(record, dtype=np.int64), _copies((unit, unit), seeds, counts), rng)
            points += drawn[:, 0] + drawn[:, 1] / 2
            total += drawn.sum(axis=1)
        if not total.all():
            raise ValueError(f"some resamples leave {name} without games against {opponent} (its seeds differ from "
                             "the others')")
        low, high = np.quantile(points / total, [(1 - confidence) / 2, (1 + confidence) / 2])
        per_seed = {unit: record.share for unit, record in units.items() if unit != NO_SEED}
        result[name] = Levelled(Estimate(pooled.share, float(low), float(high)), pooled.interval(confidence),
                                per_seed, _spread(list(per_seed.values())))
    return result
