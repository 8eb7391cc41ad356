"""``rlcompare bench selfplay``: self-play on Gardner's minichess, plies per second of the PQN training (the chess
study's preset, network and all) beside pgx's game alone (uniformly random legal moves, as many games side by side),
measured in turn in one run. Imported only when measured: it needs the ``deep`` extra."""

from __future__ import annotations

import functools
import statistics
import time
from collections.abc import Callable

import jax
import jax.numpy as jnp

from rlcompare.bench.tables import BenchTable, Measured, Say, Stage
from rlcompare.deep import float64
from rlcompare.deep.chess.games import chess_game_env
from rlcompare.deep.config import DeepConfig
from rlcompare.deep.rollout import random_mover
from rlcompare.deep.train import compiled_training, seed_keys

GAME = "gardner_chess"
PLIES = 128 * 32 * 24
"""Plies per measured training: 24 rollouts of the preset's 128 games x 32 plies."""


@float64
def game_alone(games: int = 128, plies: int = 32, rollouts: int = 24) -> tuple[int, float]:
    """``(plies, seconds)`` of pgx's game alone: ``games`` games side by side, uniformly random legal moves, a new
    game where one ended, ``rollouts`` scans of ``plies`` plies each (compiled first, outside the clock)."""
    game = chess_game_env(GAME)

    def rollout(states: object, key: jax.Array) -> tuple[object, jax.Array]:
        def one_ply(states: object, ply_key: jax.Array) -> tuple[object, jax.Array]:
            move_key, reset_key = jax.random.split(ply_key)
            after, _, ended, _ = jax.vmap(game.step)(states, random_mover(game, states, move_key))
            fresh = jax.vmap(game.reset)(jax.random.split(reset_key, games))
            states = jax.tree.map(lambda new, old: jnp.where(ended.reshape((-1,) + (1,) * (old.ndim - 1)), new, old),
                                  fresh, after)
            return states, jax.vmap(game.observe)(states).sum()

        return jax.lax.scan(one_ply, states, jax.random.split(key, plies))

    run = jax.jit(rollout)
    states = jax.vmap(game.reset)(jax.random.split(jax.random.key(0), games))
    states, _ = jax.block_until_ready(run(states, jax.random.key(1)))
    started = time.perf_counter()
    for index in range(rollouts):
        states, _ = jax.block_until_ready(run(states, jax.random.key(2 + index)))
    return games * plies * rollouts, time.perf_counter() - started


@float64
def training(seeds: int) -> tuple[int, float]:
    """``(plies, seconds)`` of the chess study's Q(λ) training, ``seeds`` side by side (compiled first)."""
    config = DeepConfig(algorithm="pqn_q_lambda", env=GAME, seeds=tuple(range(seeds)), vmap_width=seeds,
                        eval_rounds=1, eval_episodes=2, hyperparameters={"total_steps": PLIES})
    program = compiled_training(config)
    started = time.perf_counter()
    jax.block_until_ready(program(seed_keys(config.seeds)))
    return PLIES * seeds, time.perf_counter() - started


def measure_selfplay(say: Say, repeats: int = 3) -> Measured:
    """The game alone and the training on 1 and 2 seeds, in turn ``repeats`` times; medians."""
    measures: dict[str, Callable[[], tuple[int, float]]] = {
        "game alone": game_alone, "training, 1 seed": functools.partial(training, 1),
        "training, 2 seeds": functools.partial(training, 2)}
    runs: dict[str, list[float]] = {name: [] for name in measures}
    for _ in range(repeats):
        for name, measure in measures.items():
            plies, seconds = measure()
            runs[name].append(plies / seconds)
    rates = {name: statistics.median(values) for name, values in runs.items()}
    alone = rates["game alone"]
    for name, rate in rates.items():
        say(f"{name}: {rate:,.0f} plies/s ({rate / alone:.2f} of the game alone)")
    table = BenchTable("Self-play on Gardner's minichess: plies per second", ("what", "plies/s", "vs the game alone"),
                       [(name, f"{rate:,.0f}", f"{rate / alone:.2f}x") for name, rate in rates.items()],
                       ("game alone: pgx's game, 128 games side by side, uniformly random legal moves; training: the "
                        "chess study's PQN preset (128 games x 32 plies a rollout, 4 epochs x 8 minibatches, 2 x 256 "
                        "MLP), the greedy evaluations left out; medians of 3 turns",))
    return Measured(table, {"selfplay": rates})


SELFPLAY_STAGE = Stage("Self-play on Gardner's minichess beside pgx's game alone", measure_selfplay)
