"""The rating ladder of ``rlcompare reproduce chess``: games between the learnt networks, a uniformly random player, a
one-ply material player and, for chess itself, Stockfish at two settings; each pairing played in pairs of games,
each pair from its own seeded opening (:func:`openings`) with colours swapped, and every distinct game rated
together (:mod:`rlcompare.stats.seeded_ratings`).

The games of networks, the random and the material player are played in pgx, side by side and seeded
(:func:`rlcompare.deep.rollout.play_from`, which gives each game's identity); those against Stockfish through
python-chess's UCI client from the same openings, the network choosing on pgx's copy of the board
(:mod:`rlcompare.deep.chess.board`). A player of the ladder is a method's network (every seed's, one player whose
seeds the two-level bootstrap resamples: the rating is of a network that method trains), ``random``, ``material`` or
a Stockfish rung.
"""

from __future__ import annotations

import functools
import hashlib
from collections.abc import Callable, Mapping
from contextlib import closing
from dataclasses import dataclass
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import pandas as pd

from rlcompare.deep import float64
from rlcompare.deep.agent import BoardAgent, action_values, network_template
from rlcompare.deep.chess.games import ChessGameEnv
from rlcompare.deep.envs import jax_env, step_all
from rlcompare.deep.methods import deep_method
from rlcompare.deep.results import DeepResults
from rlcompare.deep.rollout import Act, Mover, material_mover, play_from, policy_mover, random_mover
from rlcompare.players.games import GameRecord, play_pairs
from rlcompare.players.stockfish import LIMIT_1350, SKILL_0, StockfishPlayer
from rlcompare.stats.seeded_ratings import SeededGame

RANDOM, MATERIAL = "random", "material"
LADDER_KEY = 30_000
"""The ladder's games in pgx play from ``jax.random.key(LADDER_KEY + i)``, apart from training's keys."""
OPENINGS_KEY = LADDER_KEY - 1
"""The key of the ladder's opening suite."""
OPENING_PLIES = 4
"""k: each opening is k uniformly random legal plies from the start, two moves a side. Two greedy networks from one
position play one game, so every pair of games needs a position of its own. On Gardner's board (7 legal first moves)
4,096 seeded draws reach 7 positions at k = 1, 53 at k = 2 (too few for the default 32 pairs once repeats are drawn)
and 2,188 at k = 4, none of them ended; chess has 197,281 four-ply sequences. Two random moves a side vary the
position without deciding the game, and each opening is played with both colours, so what it gives one side it
gives the other player in the pair's other game."""
CANDIDATES = 8
"""Openings drawn per opening kept (those the random plies ended, and repeated positions, are dropped), and at least
:data:`MIN_CANDIDATES`, so that suites of up to 32 openings share one compiled program."""
MIN_CANDIDATES = 256
Played = tuple[jax.Array, jax.Array, jax.Array, jax.Array]
"""What :func:`rlcompare.deep.rollout.play_from` returns: ``(results, plies, decided, digest)``."""
COLUMNS = ("white", "black", "white_seed", "black_seed", "score", "plies", "termination", "opening", "game")
"""One row per game: the players (a seed where the player is a network, else -1), White's score, its length in plies
from the start (the opening's included), how it ended, the opening (its index in the suite) and the game's identity
(equal for equal games: the opening and a digest of the moves after it)."""
VERSION = 2
"""The ladder's form (2: games from an opening suite, with identities); a ladder of another form is played again."""


@dataclass(frozen=True)
class Learner:
    """A method's final networks, one per seed, as a ladder player."""

    name: str
    results: DeepResults

    @property
    def seeds(self) -> tuple[int, ...]:
        return self.results.seeds


@dataclass(frozen=True)
class Openings:
    """The opening suite: ``moves`` ``(openings, k)`` pgx actions from the start, ``states`` the positions they
    reach (a batch of pgx states), each a different position."""

    moves: np.ndarray
    states: Any

    def __len__(self) -> int:
        return int(self.moves.shape[0])

    def paired(self) -> Any:
        """The positions of the suite's games: each opening twice in a row, for a pair of games."""
        return jax.tree.map(lambda leaf: jnp.repeat(leaf, 2, axis=0), self.states)


@functools.cache
def opening_candidates(game: ChessGameEnv, candidates: int, plies: int) -> Callable[[jax.Array], tuple[Any, ...]]:
    """``(key) -> (states, moves, ended, observations)``: ``candidates`` games of ``plies`` uniformly random plies."""

    def draw(key: jax.Array) -> tuple[Any, ...]:
        states = jax.vmap(game.reset)(jax.random.split(key, candidates))
        unused = jax.random.split(key, candidates)

        def ply(carry: tuple[Any, jax.Array], t: jax.Array) -> tuple[tuple[Any, jax.Array], jax.Array]:
            state, ended = carry
            move = random_mover(game, state, jax.random.fold_in(key, t))
            state, _, term, _ = step_all(game, state, move, unused)
            return (state, ended | term), move

        (states, ended), moves = jax.lax.scan(ply, (states, jnp.zeros(candidates, bool)), jnp.arange(plies))
        return states, moves.T, ended, jax.vmap(game.observe)(states)

    return jax.jit(draw)


@float64
def openings(game: ChessGameEnv, count: int, plies: int = OPENING_PLIES) -> Openings:
    """``count`` openings of ``plies`` random plies, seeded (:data:`OPENINGS_KEY`): the first ``count`` distinct
    positions (by what the network sees of them) among ``max(MIN_CANDIDATES, CANDIDATES x count)`` drawn, those the
    plies ended left out; fewer is a ``ValueError``."""
    drawn = max(MIN_CANDIDATES, CANDIDATES * count)
    states, moves, ended, seen = opening_candidates(game, drawn, plies)(jax.random.key(OPENINGS_KEY))
    kept: dict[bytes, int] = {}
    for index, (done, observation) in enumerate(zip(np.asarray(ended), np.asarray(seen), strict=True)):
        if not done:
            kept.setdefault(observation.tobytes(), index)
    chosen = np.asarray(sorted(kept.values())[:count])
    if len(chosen) < count:
        raise ValueError(f"only {len(chosen)} distinct positions after {plies} random plies among {drawn} drawn; "
                         f"{count} pairs need {count}")
    return Openings(np.asarray(moves)[chosen], jax.tree.map(lambda leaf: leaf[chosen], states))


@functools.cache
def greedy_policy(algorithm: str, method_config: Any, env: str) -> Act:
    """A method's greedy policy, made once per configuration, so that the games built on it are traced once per
    process (a ladder played again, its games missing or changed, compiles nothing again)."""
    return deep_method(algorithm).module.act(method_config, jax_env(env))


@float64
def networks(learner: Learner) -> tuple[Act, Any]:
    """``(act, params)``: the greedy policy and every seed's final parameters, stacked."""
    config = learner.results.config
    act = greedy_policy(config.algorithm, config.method_config(), config.env)
    return act, learner.results.stacked_params(network_template(learner.results))


def seed_params(params: Any, index: int) -> Any:
    return jax.tree.map(lambda leaf: leaf[index], params)


def frame(rows: list[dict[str, Any]]) -> pd.DataFrame:
    return pd.DataFrame(rows, columns=list(COLUMNS)).astype({"white_seed": np.int64, "black_seed": np.int64,
                                                             "score": np.float64, "plies": np.int64,
                                                             "opening": np.int64, "game": str})


def paired_rows(player: str, opponent: str, played: Played, opening_plies: int, player_seed: int = -1,
                opponent_seed: int = -1) -> list[dict[str, Any]]:
    """The rows of :func:`rlcompare.deep.rollout.play_from`'s games from the suite's paired positions: ``player``
    White in the even games, games ``2i`` and ``2i + 1`` from opening ``i``."""
    results, plies, digests = np.asarray(played[0]), np.asarray(played[1]), np.asarray(played[3])
    rows = []
    for index, (result, length, digest) in enumerate(zip(results.tolist(), plies.tolist(), digests, strict=True)):
        score = (result + 1.0) / 2.0
        white_first = index % 2 == 0
        rows.append({"white": player if white_first else opponent, "black": opponent if white_first else player,
                     "white_seed": player_seed if white_first else opponent_seed,
                     "black_seed": opponent_seed if white_first else player_seed,
                     "score": score if white_first else 1.0 - score, "plies": opening_plies + int(length),
                     "termination": "decided" if result != 0 else "drawn", "opening": index // 2,
                     "game": f"{index // 2}:{int(digest[0]):08x}{int(digest[1]):08x}"})
    return rows


@float64
def pgx_games(game: ChessGameEnv, learners: list[Learner], pairs: int, suite: Openings | None = None
              ) -> pd.DataFrame:
    """Every network against the random and the material player, the networks of one seed against each other, and
    the random against the material player: ``pairs`` pairs of games each, played in pgx, pair ``i`` from the
    suite's opening ``i`` (:func:`openings`) with colours swapped. Each kind of game is compiled once, its networks'
    parameters and its positions given as arguments."""
    suite = suite or openings(game, pairs)
    starts, k = suite.paired(), suite.moves.shape[1]
    keys = (jax.random.key(LADDER_KEY + index) for index in range(10**6))
    rows = paired_rows(RANDOM, MATERIAL, fixed_games(game)(starts, next(keys)), k)
    nets = {learner.name: networks(learner) for learner in learners}
    for index, learner in enumerate(learners):
        act, params = nets[learner.name]
        for name, opponent in ((RANDOM, random_mover), (MATERIAL, material_mover)):
            against = network_games(game, act, opponent)
            for seed_index, seed in enumerate(learner.seeds):
                rows += paired_rows(learner.name, name, against(seed_params(params, seed_index), starts, next(keys)),
                                    k, player_seed=seed)
        for other in learners[index + 1:]:
            other_act, other_params = nets[other.name]
            duel = duel_games(game, act, other_act)
            for seed_index, seed in enumerate(learner.seeds):
                if seed in other.seeds:
                    result = duel(seed_params(params, seed_index),
                                  seed_params(other_params, other.seeds.index(seed)), starts, next(keys))
                    rows += paired_rows(learner.name, other.name, result, k, player_seed=seed, opponent_seed=seed)
    return frame(rows)


@functools.cache
def fixed_games(game: ChessGameEnv) -> Callable[[Any, jax.Array], Played]:
    """``(starts, key) -> play_from(...)``: the random player against the material player, compiled once."""
    return jax.jit(lambda starts, key: play_from(game, random_mover, material_mover, key, starts))


@functools.cache
def network_games(game: ChessGameEnv, act: Act, opponent: Mover) -> Callable[[Any, Any, jax.Array], Played]:
    """``(params, starts, key) -> play_from(...)``: a network against a fixed player, compiled once per process."""
    return jax.jit(lambda params, starts, key: play_from(game, policy_mover(act, params), opponent, key, starts))


@functools.cache
def duel_games(game: ChessGameEnv, act: Act, other_act: Act) -> Callable[[Any, Any, Any, jax.Array], Played]:
    """``(params, other_params, starts, key) -> play_from(...)``: one network against another, compiled once."""
    return jax.jit(lambda params, other_params, starts, key: play_from(
        game, policy_mover(act, params), policy_mover(other_act, other_params), key, starts))


def identity(record: GameRecord, opening: int) -> str:
    """A python-chess game's identity: its opening and a digest of its start and moves."""
    moves = " ".join(move.uci() for move in record.game.mainline_moves())
    return f"{opening}:{hashlib.sha1(f'{record.game.board().fen()} {moves}'.encode()).hexdigest()[:16]}"


def record_rows(records: list[tuple[int, GameRecord]], seeds: Mapping[str, int], opening_plies: int
                ) -> list[dict[str, Any]]:
    """Rows of python-chess games, each with its opening; ``seeds`` gives the seed of a network player by its name
    in the games."""
    return [{"white": r.white.split(" #")[0], "black": r.black.split(" #")[0],
             "white_seed": seeds.get(r.white, -1), "black_seed": seeds.get(r.black, -1), "score": r.white_points,
             "plies": opening_plies + r.plies, "termination": r.termination, "opening": opening,
             "game": identity(r, opening)} for opening, r in records]


def stockfish_games(game: ChessGameEnv, learners: list[Learner], pairs: int, suite: Openings | None = None
                    ) -> tuple[pd.DataFrame, list[GameRecord]]:
    """Each network (every seed) against both Stockfish rungs, and the random and material players and the weaker
    rung against the stronger, which tie the rungs to the rest of the ladder: ``pairs`` pairs each, pair ``i`` from
    the suite's opening ``i`` with colours swapped, as in pgx."""
    from rlcompare.deep.chess.board import board_of
    from rlcompare.players.basic import ChessPlayer, MaterialPlayer, RandomPlayer

    suite = suite or openings(game, pairs)
    starts = [board_of(seed_params(suite.states, i)) for i in range(pairs)]
    records: list[tuple[int, GameRecord]] = []
    seeds: dict[str, int] = {}

    def pair(a: ChessPlayer, b: ChessPlayer) -> None:
        for opening, start in enumerate(starts):
            records.extend((opening, record) for record in play_pairs(a, b, 1, start=start))

    with closing(StockfishPlayer(SKILL_0)) as weak, closing(StockfishPlayer(LIMIT_1350)) as strong:
        pair(weak, strong)
        for fixed in (RandomPlayer(0), MaterialPlayer(0)):
            pair(fixed, weak)
        for learner in learners:
            values, params = action_values(learner.results), networks(learner)[1]
            for index, seed in enumerate(learner.seeds):
                name = f"{learner.name} #{seed}"
                seeds[name] = seed
                player = BoardAgent(name, game, values, seed_params(params, index))
                for rung in (weak, strong):
                    pair(player, rung)
    return frame(record_rows(records, seeds, suite.moves.shape[1])), [record for _, record in records]


def games_of(frame: pd.DataFrame) -> list[SeededGame]:
    """The ladder's games as :mod:`rlcompare.stats.seeded_ratings` takes them: each player's seed, and the game's
    identity where both players are networks (greedy: one position, one game), so that a repeated game counts once;
    a game with a random, material or Stockfish player is a draw of a random game and always counts."""
    return [SeededGame(white, black, score, white_seed, black_seed, game if min(white_seed, black_seed) >= 0 else "")
            for white, black, score, white_seed, black_seed, game in
            zip(frame["white"], frame["black"], frame["score"], frame["white_seed"], frame["black_seed"],
                frame["game"], strict=True)]


def distinct_games(frame: pd.DataFrame) -> int:
    """How many of the games differ (by players, seeds, colours and identity)."""
    return len(frame.drop_duplicates(["white", "black", "white_seed", "black_seed", "game"]))
