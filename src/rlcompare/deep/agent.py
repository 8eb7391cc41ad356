"""A trained deep agent that acts inside Gymnasium's own environment, loaded from a run directory; a network trained
at chess plays on python-chess boards instead."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import jax
import numpy as np

from rlcompare.deep import float64
from rlcompare.deep.envs import is_game
from rlcompare.deep.methods import deep_method
from rlcompare.deep.results import DeepResults
from rlcompare.deep.train import params_template
from rlcompare.envs.atari import games as atari
from rlcompare.envs.observations import check_box_observation

if TYPE_CHECKING:  # pgx and python-chess are imported where a chess network plays, not by every deep run
    import chess

    from rlcompare.deep.chess.games import ChessGameEnv


class DeepAgent:
    """The greedy policy of one seed's network at one stage of learning: ``act(observation) -> action``, for an
    observation of Gymnasium's own environment (an Atari game's: :func:`rlcompare.envs.atari.games.gymnasium_env`)."""

    def __init__(self, results: DeepResults, seed: int, stage: str = "final") -> None:
        config = results.config
        self.config, self.seed, self.stage = config, seed, stage
        self.params: Any = results.seed_params(seed, params_template(config), stage)
        self._act = jax.jit(deep_method(config.algorithm).module.act(config.method_config(), config.environment))
        self._shape = tuple(config.environment.observation_shape)

    @float64
    def act(self, observation: np.ndarray) -> int:
        """The greedy action for one observation as Gymnasium's ``env.step`` returns it."""
        if isinstance(observation, np.ndarray) and observation.dtype == np.bool_:  # MinAtar's images
            observation = observation.astype(np.float32)
        if self.config.env in atari.NAMES:  # Gymnasium's stack of frames first, the engine's last
            observation = np.moveaxis(np.asarray(observation), 0, -1)
        checked = check_box_observation(observation, self._shape, self.config.env).astype(np.float32)
        return int(self._act(self.params, checked[None])[0])


class BoardAgent:
    """A network's greedy move on python-chess boards (:class:`rlcompare.players.basic.ChessPlayer`), chosen on
    pgx's copy of the board (:func:`rlcompare.deep.chess.board.state_of`), which keeps the history pgx's planes
    show. Chess only: python-chess has no Gardner's minichess."""

    def __init__(self, name: str, game: ChessGameEnv, act: Any, params: Any) -> None:
        self.name = name
        self.params = params
        self._seen: tuple[str, list[chess.Move], Any] | None = None
        """The root, the moves and pgx's state of the last board it moved on."""
        self._choose = jax.jit(lambda params, state: act(params, game.observe(state)[None],  # the rules' moves
                                                         state._x.legal_action_mask[None])[0])

    @classmethod
    def of(cls, results: DeepResults, seed: int, stage: str = "final") -> BoardAgent:
        from rlcompare.deep.chess.games import ChessGameEnv

        config = results.config
        game = config.environment
        if not isinstance(game, ChessGameEnv) or game.game.board_size != 8:
            raise ValueError(f"a run of {config.env}: only a network trained at chess plays on python-chess boards")
        act = deep_method(config.algorithm).module.act(config.method_config(), game)
        return cls(f"rlcompare {config.name} seed {seed} {stage}", game, act,
                   results.seed_params(seed, params_template(config), stage))

    @float64
    def move(self, board: chess.Board) -> chess.Move:
        """The network's move for the side to move on ``board``."""
        from rlcompare.deep.chess.board import move_of

        state = self._state_of(board)
        return move_of(state, int(self._choose(self.params, state)))

    def _state_of(self, board: chess.Board) -> Any:
        """pgx's state of ``board``: the last one this agent saw, stepped on by the moves since, where ``board``
        continues that game; else replayed from its root (:func:`~rlcompare.deep.chess.board.state_of`)."""
        from rlcompare.deep.chess.board import action_of, state_of, step

        seen, moves = self._seen, board.move_stack
        if seen is None or seen[0] != board.root().fen() or moves[:len(seen[1])] != seen[1]:
            state = state_of(board, rules_decide=True)
        else:
            state = seen[2]
            for move in moves[len(seen[1]):]:
                state = step(state, action_of(state, move))
            if bool(state.terminated):  # pgx ended the game by its own count: rebuilt as state_of rebuilds it
                state = state_of(board, rules_decide=True)
        self._seen = (board.root().fen(), list(moves), state)
        return state

    def close(self) -> None:
        """Holds nothing."""


def agent(results: DeepResults, seed: int, stage: str = "final") -> DeepAgent | BoardAgent:
    """The greedy agent of ``seed``'s network at ``stage`` (``results.stages``): on python-chess boards for a
    network trained at chess."""
    if is_game(results.config.environment):
        return BoardAgent.of(results, seed, stage)
    return DeepAgent(results, seed, stage)


@float64
def gymnasium_returns(results: DeepResults, episodes: int = 10, first_episode_seed: int = 1_000_000) -> np.ndarray:
    """``(seeds, episodes)`` returns of every seed's greedy policy in Gymnasium's own environment (``gym.make``,
    its registered limit), all seeds stepped in lockstep and acting in one call. Episode ``k`` of every seed
    starts from ``env.reset(seed=first_episode_seed + k)``, so the seeds are compared on the same start states."""
    import gymnasium as gym

    config = results.config
    act = jax.jit(jax.vmap(deep_method(config.algorithm).module.act(config.method_config(), config.environment),
                           in_axes=(0, 0)))
    params = results.stacked_params(params_template(config))
    runs = len(results.seeds)
    envs = [gym.make(config.env) for _ in range(runs)]
    returns = np.zeros((runs, episodes))
    try:
        for k in range(episodes):
            observations = np.stack([env.reset(seed=first_episode_seed + k)[0] for env in envs]).astype(np.float32)
            running = np.ones(runs, bool)
            while running.any():
                actions = np.asarray(act(params, observations[:, None]))[:, 0]
                for i in np.flatnonzero(running):
                    observation, reward, terminated, truncated, _ = envs[i].step(int(actions[i]))
                    observations[i] = observation
                    returns[i, k] += reward
                    running[i] = not (terminated or truncated)
    finally:
        for env in envs:
            env.close()
    return returns
