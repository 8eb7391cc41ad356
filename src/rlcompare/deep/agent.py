"""A trained deep agent that acts inside Gymnasium's own environment, loaded from a run directory; a network trained
at chess plays on python-chess boards instead."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import jax
import jax.numpy as jnp
import numpy as np

from rlcompare.deep import float64, use_compilation_cache
from rlcompare.deep.config import DeepConfig
from rlcompare.deep.envs import is_game
from rlcompare.deep.methods import deep_method
from rlcompare.deep.results import DeepResults
from rlcompare.deep.train import params_template
from rlcompare.envs.atari import games as atari
from rlcompare.envs.observations import check_box_observation
from rlcompare.validation import ConfigError

if TYPE_CHECKING:  # pgx and python-chess are imported where a chess network plays, not by every deep run
    import chess

    from rlcompare.deep.chess.games import ChessGameEnv


class DeepAgent:
    """The greedy policy of one seed's network at one stage of learning: ``act(observation) -> action``, for an
    observation of Gymnasium's own environment (an Atari game's: :func:`rlcompare.envs.atari.games.gymnasium_env`).
    Given ``env``, its actions are that environment's: an ``ALE/<Game>-v5`` on Gymnasium's minimal action set gets
    the best of the network's scores among the actions it has (:func:`playable_actions`)."""

    def __init__(self, results: DeepResults, seed: int, stage: str = "final", env: Any = None) -> None:
        config = results.config
        self.config, self.seed, self.stage = config, seed, stage
        self.params: Any = results.seed_params(seed, params_template(config), stage)
        module = deep_method(config.algorithm).module
        self._act = jax.jit(module.act(config.method_config(), config.environment))
        self._scores = jax.jit(module.scores(config.method_config(), config.environment))
        self._shape = tuple(config.environment.observation_shape)
        self.actions = None if env is None else playable_actions(config, env)
        """The network's actions that ``env``'s actions 0, 1, ... are; None where they are the network's own."""

    @float64
    def act(self, observation: np.ndarray) -> int:
        """The greedy action for one observation as Gymnasium's ``env.step`` returns it."""
        if isinstance(observation, np.ndarray) and observation.dtype == np.bool_:  # MinAtar's images
            observation = observation.astype(np.float32)
        if self.config.env in atari.NAMES:  # Gymnasium's stack of frames first, the engine's last
            observation = np.moveaxis(np.asarray(observation), 0, -1)
        checked = check_box_observation(observation, self._shape, self.config.env).astype(np.float32)
        if self.actions is None:
            return int(self._act(self.params, checked[None])[0])
        scores = np.asarray(self._scores(self.params, checked[None])[0])
        return int(np.argmax(scores[list(self.actions)]))  # ties: the first, as the greedy policy's


def gymnasium_shape(config: DeepConfig) -> tuple[int, ...]:
    """The observations' shape as Gymnasium's environment gives them: an Atari game's stack first."""
    shape = tuple(config.environment.observation_shape)
    return (shape[-1], *shape[:-1]) if config.env in atari.NAMES else shape


def playable_actions(config: DeepConfig, env: Any) -> tuple[int, ...] | None:
    """The network's actions that ``env``'s are (None: the same), after checking that ``env`` gives the observations
    the network reads; one line naming ``env`` and what it needs where it does not."""
    made = env.spec.id if getattr(env, "spec", None) is not None else type(env).__name__
    expected = gymnasium_shape(config)
    builder = (f"rlcompare.envs.atari.games.gymnasium_env({config.env!r})" if config.env in atari.NAMES
               else f"gymnasium.make({config.env!r})")
    if tuple(env.observation_space.shape or ()) != expected:
        raise ConfigError("env", f"{made}, observations of shape {env.observation_space.shape}",
                          f"an environment whose observations are {expected}, as {builder} makes")
    if config.env in atari.NAMES:
        actions = atari.action_set(env)
        return None if actions == tuple(range(config.environment.n_actions)) else actions
    if int(env.action_space.n) != config.environment.n_actions:
        raise ConfigError("env", f"{made}, {env.action_space.n} actions",
                          f"an environment of {config.environment.n_actions} actions, as {builder} makes")
    return None


class BoardAgent:
    """A network's greedy move on python-chess boards (:class:`rlcompare.players.basic.ChessPlayer`), chosen on
    pgx's copy of the board (:func:`rlcompare.deep.chess.board.state_of`), which keeps the history pgx's planes
    show, among python-chess's legal moves: the rules' moves decide, never pgx's mask (all True once pgx has ended
    a game by its own count). ``values`` is the network's ``(params, observations) -> action values``. Chess only:
    python-chess has no Gardner's minichess."""

    def __init__(self, name: str, game: ChessGameEnv, values: Any, params: Any) -> None:
        self.name = name
        self.params = params
        self._seen: tuple[str, list[chess.Move], Any] | None = None
        """The root, the moves and pgx's state of the last board it moved on."""
        self._values = jax.jit(lambda params, state: values(params, game.observe(state)[None])[0])

    @classmethod
    def of(cls, results: DeepResults, seed: int, stage: str = "final") -> BoardAgent:
        from rlcompare.deep.chess.games import ChessGameEnv

        config = results.config
        game = config.environment
        if not isinstance(game, ChessGameEnv) or game.game.board_size != 8:
            raise ValueError(f"a run of {config.env}: only a network trained at chess plays on python-chess boards")
        use_compilation_cache()  # a second start of an engine (rlcompare uci) finds its programs compiled
        return cls(f"rlcompare {config.name} seed {seed} {stage}", game, action_values(results),
                   results.seed_params(seed, network_template(results), stage))

    def move(self, board: chess.Board) -> chess.Move:
        """The network's move for the side to move on ``board``."""
        return self.evaluate(board)[0]

    @float64
    def evaluate(self, board: chess.Board) -> tuple[chess.Move, float]:
        """The network's move for the side to move on ``board`` and its action value (the mover's expected return,
        -1 lost to +1 won): the first of the best among python-chess's legal moves, by pgx's action order, as the
        network's greedy policy chooses in pgx. A board with no legal move is a ``ValueError``."""
        from rlcompare.deep.chess.board import action_of

        moves = list(board.legal_moves)
        if not moves:
            raise ValueError(f"no legal move in {board.fen()}")
        state = self._state_of(board)
        by_action = {action_of(state, move): move for move in moves}
        actions = np.array(sorted(by_action))
        values = np.asarray(self._values(self.params, state))[actions]
        best = int(np.argmax(values))
        return by_action[int(actions[best])], float(values[best])

    def _state_of(self, board: chess.Board) -> Any:
        """pgx's state of ``board``: the last one this agent saw, stepped on by the moves since, where ``board``
        continues that game and pgx has not ended it on the way; else :func:`~rlcompare.deep.chess.board.player_state`
        (replayed from its root, rebuilt from the position where pgx ended the game by its own count)."""
        from rlcompare.deep.chess.board import action_of, player_state, step

        seen, moves = self._seen, board.move_stack
        state = None
        if seen is not None and seen[0] == board.root().fen() and moves[:len(seen[1])] == seen[1]:
            state = seen[2]
            for move in moves[len(seen[1]):]:
                state = step(state, action_of(state, move))
                if bool(state.terminated):
                    state = None
                    break
        if state is None:
            state = player_state(board)
        self._seen = (board.root().fen(), list(moves), state)
        return state

    def close(self) -> None:
        """Holds nothing."""


@float64
def network_of(results: DeepResults) -> Any:
    """The run's network (a flax module): PQN's, the one method that plays games here."""
    config = results.config
    return deep_method(config.algorithm).module.network(config.method_config(), config.environment)


def network_template(results: DeepResults) -> Any:
    """The shape of one seed's parameters of a network that plays a game, from the network's own ``init`` (the
    tree :func:`~rlcompare.deep.train.params_template` traces, without tracing a training: 0.06 s, not 1.5-5 s)."""
    observation = jnp.zeros((1, *results.config.environment.observation_shape), jnp.float32)
    return jax.eval_shape(network_of(results).init, jax.random.key(0), observation)


def action_values(results: DeepResults) -> Any:
    """The network's ``(params, observations) -> (batch, actions)`` action values (its greedy policy is their argmax
    among the legal moves)."""
    return network_of(results).apply


def agent(results: DeepResults, seed: int, stage: str = "final", env: Any = None) -> DeepAgent | BoardAgent:
    """The greedy agent of ``seed``'s network at ``stage`` (``results.stages``), acting in ``env`` where given
    (:class:`DeepAgent`): on python-chess boards for a network trained at chess."""
    if is_game(results.config.environment):
        if env is not None:
            raise ConfigError("env", type(env).__name__, "none for a network that plays chess boards")
        return BoardAgent.of(results, seed, stage)
    return DeepAgent(results, seed, stage, env)


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
