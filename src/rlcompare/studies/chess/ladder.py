"""The rating ladder of ``rlcompare reproduce chess``: games between the learnt networks, a uniformly random player, a
one-ply material player and, for chess itself, Stockfish at two strengths; each pairing played in pairs of games,
colours swapped, and every game rated together (:mod:`rlcompare.stats.ratings`).

The games of networks, the random and the material player are played in pgx, side by side and seeded
(:func:`rlcompare.deep.rollout.play`); those against Stockfish through python-chess's UCI client, the network
choosing on pgx's copy of the board (:mod:`rlcompare.deep.chess.board`). A player of the ladder is a method's
network (every seed's, pooled: the rating is of a network that method trains), ``random``, ``material`` or a
Stockfish rung.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping
from contextlib import closing
from dataclasses import dataclass
from typing import Any

import jax
import numpy as np
import pandas as pd

from rlcompare.deep import float64
from rlcompare.deep.agent import BoardAgent, action_values, network_template
from rlcompare.deep.chess.games import ChessGameEnv
from rlcompare.deep.envs import jax_env
from rlcompare.deep.methods import deep_method
from rlcompare.deep.results import DeepResults
from rlcompare.deep.rollout import Act, Mover, material_mover, play, policy_mover, random_mover
from rlcompare.players.games import GameRecord, play_pairs
from rlcompare.players.stockfish import ELO_1350, SKILL_0, StockfishPlayer
from rlcompare.stats.ratings import Game

RANDOM, MATERIAL = "random", "material"
LADDER_KEY = 30_000
"""The ladder's games in pgx play from ``jax.random.key(LADDER_KEY + i)``, apart from training's keys."""
Played = tuple[jax.Array, jax.Array, jax.Array]
"""What :func:`rlcompare.deep.rollout.play` returns: ``(results, plies, decided)``."""
COLUMNS = ("white", "black", "white_seed", "black_seed", "score", "plies", "termination")
"""One row per game: the players (a seed where the player is a network, else -1), White's score, its length."""


@dataclass(frozen=True)
class Learner:
    """A method's final networks, one per seed, as a ladder player."""

    name: str
    results: DeepResults

    @property
    def seeds(self) -> tuple[int, ...]:
        return self.results.seeds


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
                                                             "score": np.float64, "plies": np.int64})


def paired_rows(player: str, opponent: str, results: np.ndarray, plies: np.ndarray, player_seed: int = -1,
                opponent_seed: int = -1) -> list[dict[str, Any]]:
    """The rows of :func:`rlcompare.deep.rollout.play`'s games: ``player`` White in the even games."""
    rows = []
    for index, (result, length) in enumerate(zip(results.tolist(), plies.tolist(), strict=True)):
        score = (result + 1.0) / 2.0
        white_first = index % 2 == 0
        rows.append({"white": player if white_first else opponent, "black": opponent if white_first else player,
                     "white_seed": player_seed if white_first else opponent_seed,
                     "black_seed": opponent_seed if white_first else player_seed,
                     "score": score if white_first else 1.0 - score, "plies": int(length),
                     "termination": "decided" if result != 0 else "drawn"})
    return rows


@float64
def pgx_games(game: ChessGameEnv, learners: list[Learner], pairs: int) -> pd.DataFrame:
    """Every network against the random and the material player, the networks of one seed against each other, and
    the random against the material player: ``pairs`` pairs of games each, played in pgx. Each kind of game is
    compiled once, its networks' parameters given as arguments."""
    games = 2 * pairs
    keys = (jax.random.key(LADDER_KEY + index) for index in range(10**6))
    rows = paired_rows(RANDOM, MATERIAL, *played(fixed_games(game, games)(next(keys))))
    nets = {learner.name: networks(learner) for learner in learners}
    for index, learner in enumerate(learners):
        act, params = nets[learner.name]
        for name, opponent in ((RANDOM, random_mover), (MATERIAL, material_mover)):
            against = network_games(game, act, opponent, games)
            for seed_index, seed in enumerate(learner.seeds):
                rows += paired_rows(learner.name, name, *played(against(seed_params(params, seed_index), next(keys))),
                                    player_seed=seed)
        for other in learners[index + 1:]:
            other_act, other_params = nets[other.name]
            duel = duel_games(game, act, other_act, games)
            for seed_index, seed in enumerate(learner.seeds):
                if seed in other.seeds:
                    result = duel(seed_params(params, seed_index),
                                  seed_params(other_params, other.seeds.index(seed)), next(keys))
                    rows += paired_rows(learner.name, other.name, *played(result), player_seed=seed,
                                        opponent_seed=seed)
    return frame(rows)


@functools.cache
def fixed_games(game: ChessGameEnv, games: int) -> Callable[[jax.Array], Played]:
    """``(key) -> play(...)``: the random player against the material player, compiled once per process."""
    return jax.jit(lambda key: play(game, random_mover, material_mover, key, games))


@functools.cache
def network_games(game: ChessGameEnv, act: Act, opponent: Mover, games: int) -> Callable[[Any, jax.Array], Played]:
    """``(params, key) -> play(...)``: a network against a fixed player, compiled once per process."""
    return jax.jit(lambda params, key: play(game, policy_mover(act, params), opponent, key, games))


@functools.cache
def duel_games(game: ChessGameEnv, act: Act, other_act: Act, games: int
               ) -> Callable[[Any, Any, jax.Array], Played]:
    """``(params, other_params, key) -> play(...)``: one network against another, compiled once per process."""
    return jax.jit(lambda params, other_params, key: play(game, policy_mover(act, params),
                                                         policy_mover(other_act, other_params), key, games))


def played(result: tuple[jax.Array, jax.Array, jax.Array]) -> tuple[np.ndarray, np.ndarray]:
    """``(results, plies)`` of :func:`rlcompare.deep.rollout.play`'s games, on the host."""
    return np.asarray(result[0]), np.asarray(result[1])


def record_rows(records: list[GameRecord], seeds: Mapping[str, int]) -> list[dict[str, Any]]:
    """Rows of python-chess games; ``seeds`` gives the seed of a network player by its name in the games."""
    return [{"white": r.white.split(" #")[0], "black": r.black.split(" #")[0],
             "white_seed": seeds.get(r.white, -1), "black_seed": seeds.get(r.black, -1), "score": r.white_points,
             "plies": r.plies, "termination": r.termination} for r in records]


def stockfish_games(game: ChessGameEnv, learners: list[Learner], pairs: int
                    ) -> tuple[pd.DataFrame, list[GameRecord]]:
    """Each network (every seed) against both Stockfish rungs, and the random and material players and the weaker
    rung against the stronger, which tie the rungs to the rest of the ladder: ``pairs`` pairs each."""
    from rlcompare.players.basic import MaterialPlayer, RandomPlayer

    records: list[GameRecord] = []
    seeds: dict[str, int] = {}
    with closing(StockfishPlayer(SKILL_0)) as weak, closing(StockfishPlayer(ELO_1350)) as strong:
        records += play_pairs(weak, strong, pairs)
        for fixed in (RandomPlayer(0), MaterialPlayer(0)):
            records += play_pairs(fixed, weak, pairs)
        for learner in learners:
            values, params = action_values(learner.results), networks(learner)[1]
            for index, seed in enumerate(learner.seeds):
                name = f"{learner.name} #{seed}"
                seeds[name] = seed
                player = BoardAgent(name, game, values, seed_params(params, index))
                for rung in (weak, strong):
                    records += play_pairs(player, rung, pairs)
    return frame(record_rows(records, seeds)), records


def games_of(frame: pd.DataFrame) -> list[Game]:
    """The ladder's games as :mod:`rlcompare.stats.ratings` takes them (seeds pooled by player)."""
    return [Game(white, black, score) for white, black, score in
            zip(frame["white"], frame["black"], frame["score"], strict=True)]

