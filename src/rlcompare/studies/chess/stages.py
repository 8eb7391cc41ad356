"""The chess study's networks at three stages of learning: each method's first seed, its network after a tenth and
half of the training and at its end, playing one game as White against the uniformly random player; the last
position drawn, and the game's record written (PGN for chess, pgx's FEN of every position for Gardner's game)."""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any

import chess
import chess.pgn
import jax
import jax.numpy as jnp
from matplotlib.figure import Figure

from rlcompare.deep import float64
from rlcompare.deep.agent import network_template
from rlcompare.deep.chess.games import ChessGameEnv, chess_game_env, fen_of
from rlcompare.deep.methods import DEEP_METHODS, deep_method
from rlcompare.deep.results import DeepResults
from rlcompare.deep.rollout import random_mover
from rlcompare.experiment import store
from rlcompare.report.boards import draw_board
from rlcompare.report.page import save_figure

STAGE_KEY = 40_000
"""The random player's moves in these games come from ``jax.random.key(STAGE_KEY + seed)``."""
RESULTS = {1.0: "1-0", 0.0: "1/2-1/2", -1.0: "0-1"}


Choose = Any
"""``choose(params, state) -> action``: a network's greedy move, compiled once for every stage of its training."""


def greedy_player(game: ChessGameEnv, act: Any) -> Choose:
    """The network's greedy move in ``game``, its parameters an argument (one compile serves every stage)."""
    return jax.jit(lambda params, state: act(params, game.observe(state)[None], game.legal(state)[None])[0])


@functools.cache
def random_player_and_step(game: ChessGameEnv) -> tuple[Any, Any]:
    """The random player's reply and ``game``'s step, compiled once per game."""
    reply = jax.jit(lambda state, k: random_mover(game, jax.tree.map(lambda x: x[None], state), k)[0])
    return reply, jax.jit(game.step)


@float64
def stage_game(game: ChessGameEnv, choose: Choose, params: Any, key: jax.Array) -> tuple[list[Any], list[int], float]:
    """``(states, actions, result)``: one game of the greedy network (White) against the random player, every
    position from the start, every move, and White's result (+1, 0, -1)."""
    reply, step = random_player_and_step(game)
    state = game.reset(key)  # White to move: the network's
    states, actions, result = [state], [], 0.0
    for ply in range(game.game.max_plies):
        action = int(choose(params, state) if ply % 2 == 0 else reply(state, jax.random.fold_in(key, ply)))
        state, reward, terminated, _ = step(state, jnp.int32(action))
        states.append(state)
        actions.append(action)
        if bool(terminated):
            result = float(reward) if ply % 2 == 0 else -float(reward)
            break
    return states, actions, result


def board_of(game: ChessGameEnv, state: Any) -> chess.Board:
    """The position on a python-chess board: Gardner's five ranks in the corner a1-e5."""
    fen = fen_of(game, state)
    if game.game.board_size == 8:
        return chess.Board(fen)
    board = chess.Board.empty()
    for rank_index, rank in enumerate(fen.split()[0].split("/")):
        file = 0
        for symbol in rank:
            if symbol.isdigit():
                file += int(symbol)
                continue
            board.set_piece_at(chess.square(file, 4 - rank_index), chess.Piece.from_symbol(symbol))
            file += 1
    return board


def record(game: ChessGameEnv, states: list[Any], actions: list[int], result: float, headers: dict[str, str]
           ) -> str:
    """The game as PGN (chess) or as one FEN a line (Gardner's game), with ``headers``."""
    if game.game.board_size == 8:
        from rlcompare.deep.chess.board import move_of

        pgn = chess.pgn.Game(headers={**headers, "Result": RESULTS[result]})
        node: chess.pgn.GameNode = pgn
        for state, action in zip(states, actions, strict=False):
            node = node.add_variation(move_of(state, action))
        return str(pgn) + "\n"
    lines = [f'[{name} "{value}"]' for name, value in {**headers, "Result": RESULTS[result]}.items()]
    return "\n".join([*lines, "", *(fen_of(game, state) for state in states)]) + "\n"


def stage_games(out: Path, runs: dict[str, DeepResults], env: str) -> tuple[list[tuple[str, str]], list[str]]:
    """The figures (one per method: its three stages side by side) and a paragraph naming the records."""
    game = chess_game_env(env)
    figures, written = [], []
    for results in sorted(runs.values(), key=lambda r: r.config.name):
        config, seed = results.config, results.seeds[0]
        choose = greedy_player(game, deep_method(config.algorithm).module.act(config.method_config(),
                                                                               config.environment))
        template = network_template(results)
        stages = [(stage, jax.tree.map(lambda leaf: leaf[0], results.stacked_params(template, stage)))
                  for stage in results.stages]
        label = DEEP_METHODS[config.algorithm].label
        figure = Figure(figsize=(3.2 * len(stages), 3.6))
        for ax, (stage, params) in zip(figure.subplots(1, len(stages), squeeze=False)[0], stages, strict=True):
            states, actions, result = stage_game(game, choose, params, jax.random.key(STAGE_KEY + seed))
            name = f"{config.name}-seed{seed}-{stage}"
            suffix = "pgn" if game.game.board_size == 8 else "fen.txt"
            text = record(game, states, actions, result, {"Event": f"{label}, {stage}", "White": label,
                                                          "Black": "random"})
            store.write_bytes_atomic(out / "games" / f"{name}.{suffix}", text.encode())
            written.append(f"games/{name}.{suffix}")
            draw_board(ax, board_of(game, states[-1]), size=game.game.board_size,
                       title=f"{stage}: {RESULTS[result]} in {len(actions)} plies")
        figure.tight_layout()
        figures.append((save_figure(figure, out / "figures" / f"stages-{config.name}.png"),
                        f"{label}, seed {seed}: the last position of a game as White against the random player, "
                        "after a tenth, half and all of the training"))
    return figures, [f"Each game's record: {', '.join(written)}."]
