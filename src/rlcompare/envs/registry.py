"""Every environment rlcompare knows, one entry each: what compiled code steps, its spaces, default grid and
bounds, step limit, what counts as solved, and what figures and videos say of it.

| environment          | stepped by                        | features              | default grid    | limit |
|----------------------|-----------------------------------|-----------------------|-----------------|-------|
| ``MountainCar-v0``   | the port (the paper)              | grid or tiles         | 20 x 20         | 1000  |
| ``MountainCar-book`` | the port, position bounded at 0.5 | grid or tiles         | 20 x 20         | 1000  |
| ``CartPole-v1``      | the port                          | grid or tiles         | 1 x 1 x 6 x 12  | 500   |
| ``Acrobot-v1``       | the port                          | grid or tiles         | 4^4 x 8 x 8     | 500   |
| ``CliffWalking-v1``  | Gymnasium's transition table      | one per state         |                 | 1000  |
| ``FrozenLake-v1``    | Gymnasium's transition table      | one per state         |                 | 100   |
| ``FrozenLake8x8-v1`` | Gymnasium's transition table      | one per state         |                 | 200   |
| ``Taxi-v4``          | Gymnasium's transition table      | one per state         |                 | 200   |
| ``KRK``, ``KQK``     | the endgame's rules and solver    | one per state         |                 | 50    |
| any other            | Gymnasium, through the adapter    | one per state, or grid or tiles over a Box; 10 bins per |
|                      |                                   | dimension; Gymnasium's registered limit, else 1000     |

The grid and the tiles span the observation box, except where it is unbounded (CartPole's velocities) or
where the episode ends before its edge (CartPole's position and angle): ``docs/environments.md`` gives
every default and why. ``bounds`` in the configuration replaces them.

Compiled code is given the entry's ``dynamics`` and steps it with the functions of the module its type is defined
in (:mod:`rlcompare.tabular.steps`): every dynamics module has ``reset(env, rng) -> state``, ``step(env, state,
action, rng) -> (state, reward, terminated)`` and ``observe(env, state) -> observation``; a features module has
``states_buffer(features, size)`` and ``features_of(features, observation, buffer, at)``. Adding a port is its
dynamics file and its entry in ``_PORTED``. An entry imports its port when it is first asked for, so that reading
the registry's names compiles nothing.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

from rlcompare.envs import minatar
from rlcompare.envs.atari import games as atari
from rlcompare.envs.chess import endgames as chess
from rlcompare.envs.chess import games as chess_games

if TYPE_CHECKING:
    import numpy as np

    from rlcompare.envs.table import TableEnv

_CARTPOLE_VELOCITY = 3.0  # m/s; see docs/environments.md
_CARTPOLE_ANGULAR_VELOCITY = 3.5  # rad/s


class Painter(Protocol):
    """What draws an environment's frames quicker than ``env.render()`` (:attr:`Environment.painter`)."""

    @property
    def size(self) -> tuple[int, int]:
        """``(width, height)`` of the picture, in pixels."""

    def paint(self, out: np.ndarray) -> None:
        """The current frame into ``out``, ``(height, width)`` packed pixels, top row first."""


@dataclass(frozen=True)
class Environment:
    """What rlcompare knows of an environment: how the kernels step it and its defaults."""

    name: str
    dynamics: tuple[Any, ...] | None
    """What compiled code steps (a port's parameters, a table); None: Gymnasium, through the adapter."""
    n_actions: int
    n_states: int
    """Number of states of a finite environment (each its own feature); 0 for a box of observations."""
    low: np.ndarray
    """``(dims,)`` float64 default lower bounds of the grid and tiles (finite, or -inf where none is known)."""
    high: np.ndarray
    max_steps: int
    """The default episode limit."""
    bins: int | tuple[int, ...]
    """The default grid."""
    success: str
    """When an episode counts as solved: ``terminated`` (the goal), ``truncated`` (survived to the limit),
    ``positive_return``, or ``won`` (terminated with a return of at least minus the step limit: a game mated,
    where losing the piece costs more)."""
    action_names: tuple[str, ...] = ()
    """What each action does, for figures."""
    map_axes: tuple[str, str] | None = None
    """The names of the two observation dimensions the report draws maps over; None: no maps."""
    start_box: tuple[tuple[float, float], ...] | None = None
    """Where every episode starts, over the map axes: a (low, high) range per axis (equal where the start is
    fixed); the report's first actions are taken from there. None: no such region is drawn."""
    shown_as: str = ""
    """The Gymnasium environment that shows its agents in videos, where it is not the environment itself (the
    book's Mountain Car is Gymnasium's, whose trajectories are the same)."""
    endings: tuple[str, str] = ("terminated", "out of time")
    """How a video's last frame says the episode ended: terminated, truncated."""
    painter: Callable[[Any], Painter] | None = None
    """What draws a video's frames where ``env.render()`` is slow: built from the unwrapped Gymnasium
    environment, its ``paint(out)`` writes the picture ``env.render()`` would return, as packed pixels
    (:mod:`rlcompare.report.frames`); None: ``env.render()``."""
    bench_episodes: int = 0
    """Episodes per seed of Q-Learning with ε = 0.5 that make about a million steps (``rlcompare bench``);
    0: not benchmarked."""
    jax_port: str = ""
    """Where the deep engine's port of it in JAX lives, ``module:attribute`` (imported only by that engine): the
    port, or a function of the name that makes it; empty: the deep engine does not step it."""
    observation_shape: tuple[int, ...] = ()
    """The shape of an observation where it is not a vector of ``observation_size`` (MinAtar's images)."""
    tabular: bool = True
    """The tabular engine can play it (False for images: the deep engine only)."""
    legal_moves: np.ndarray | None = None
    """``(states, actions)`` bool: the legal moves of each state of a game whose legal moves change with the state
    (chess); every table holds −∞ at an illegal move, which no policy then chooses
    (:mod:`rlcompare.algorithms.policies`). None: every action is legal everywhere."""

    @property
    def moves_vary(self) -> bool:
        """Whether the legal moves change with the state (:attr:`legal_moves` is not None), known without them."""
        return self.legal_moves is not None

    @property
    def observation_size(self) -> int:
        return 1 if self.n_states else self.low.size

    @property
    def gymnasium_id(self) -> str:
        """The Gymnasium environment that plays and renders its agents."""
        return self.shown_as or self.name

    @property
    def is_ported(self) -> bool:
        """Stepped by compiled code; otherwise by Gymnasium at Python speed."""
        return self.dynamics is not None


def _mountain_car(name: str, *, book: bool = False, bench_episodes: int = 0, shown_as: str = "", jax_port: str = ""
                  ) -> Environment:
    """Gymnasium's Mountain Car, or the book's (Example 10.1: the position bounded at the goal)."""
    import numpy as np

    from rlcompare.envs import mountain_car
    from rlcompare.envs.mountain_car_picture import MountainCarPainter

    right = mountain_car.BOOK_MAX_POSITION if book else mountain_car.MAX_POSITION
    low, high = mountain_car.OBSERVATION_LOW.astype(np.float64), mountain_car.OBSERVATION_HIGH.astype(np.float64)
    high[0] = np.float32(right)
    return Environment(name, mountain_car.MountainCar(right), mountain_car.N_ACTIONS, 0, low, high, 1000, 20,
                       "terminated", action_names=("push left", "no push", "push right"),
                       map_axes=("position", "velocity"),
                       start_box=((mountain_car.RESET_LOW, mountain_car.RESET_HIGH), (0.0, 0.0)), shown_as=shown_as,
                       endings=("reached the flag", "out of time"), painter=MountainCarPainter,
                       bench_episodes=bench_episodes, jax_port=jax_port)


def _cartpole() -> Environment:
    import numpy as np

    from rlcompare.envs import cartpole

    theta = np.float32(cartpole.THETA_THRESHOLD)
    high = np.array([np.float32(cartpole.X_THRESHOLD), _CARTPOLE_VELOCITY, theta, _CARTPOLE_ANGULAR_VELOCITY])
    return Environment(cartpole.ENV_ID, cartpole.CartPole(), cartpole.N_ACTIONS, 0, -high, high, 500, (1, 1, 6, 12),
                       "truncated", endings=("the pole fell", "balanced to the end"),
                       bench_episodes=5000, jax_port="rlcompare.deep.classic:CARTPOLE")


def _acrobot() -> Environment:
    import numpy as np

    from rlcompare.envs import acrobot

    return Environment(acrobot.ENV_ID, acrobot.Acrobot(), acrobot.N_ACTIONS, 0,
                       acrobot.OBSERVATION_LOW.astype(np.float64), acrobot.OBSERVATION_HIGH.astype(np.float64), 500,
                       (4, 4, 4, 4, 8, 8),
                       "terminated", endings=("swung above the bar", "out of time"), bench_episodes=300,
                       jax_port="rlcompare.deep.classic:ACROBOT")


def _minatar(name: str) -> Environment:
    """A MinAtar game under a protocol (:mod:`rlcompare.envs.minatar`); ``max_steps`` 0 where only the game
    ends an episode."""
    import numpy as np

    game, protocol = minatar.NAMES[name]
    shape = (10, 10, len(game.channels))
    actions = minatar.actions(game, protocol)
    return Environment(name, None, len(actions), 0, np.zeros(int(np.prod(shape))), np.ones(int(np.prod(shape))),
                       minatar.max_steps(game, protocol) or 0, 1, "positive_return",
                       action_names=tuple(minatar.ACTION_NAMES[action] for action in actions),
                       endings=("game over", "out of time"), jax_port="rlcompare.deep.minatar.games:minatar_env",
                       observation_shape=shape, tabular=False)


class _MadeWhereRead:
    """A field of a chess endgame's :class:`Environment`, its tables (``dynamics``) or ``legal_moves``, made where it
    is first read, not where the environment is named: solving the endgame takes a second, and a configuration's
    checks and a plan read only the sizes its facts give (:class:`rlcompare.envs.chess.endgames.Facts`)."""

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    def __set__(self, instance: Environment, value: Any) -> None:
        instance.__dict__[self.name] = value

    def __get__(self, instance: Environment | None, owner: type | None = None) -> Any:
        if instance is None:
            return self
        value = instance.__dict__[self.name]
        if isinstance(value, _Later):
            from rlcompare.envs.chess import endgame as chess_endgame

            tables = chess_endgame.make_endgame(chess.parse(instance.name))  # cached
            value = tables if self.name == "dynamics" else chess_endgame.legal_moves(tables)
            instance.__dict__[self.name] = value
        return value


class _Later:
    """What a field made where it is first read holds until then (a copy, pickled, is one too)."""


_LATER: Any = _Later()


class _EndgameEnvironment(Environment):
    """A chess endgame: its tables and legal moves made where first read (:class:`_MadeWhereRead`)."""

    dynamics = _MadeWhereRead()
    legal_moves = _MadeWhereRead()

    @property
    def moves_vary(self) -> bool:
        return True


def _endgame(name: str) -> Environment:
    """A chess endgame against its defender (:mod:`rlcompare.envs.chess.endgame`); ``name`` carries its options. A
    start given as a FEN is checked now; the tables are made where first read."""
    import numpy as np

    options = chess.parse(name)
    if options.starts not in chess.STARTS:
        from rlcompare.envs.chess.endgame import fen_start

        fen_start(options)  # a FEN that is not a legal start of the endgame refused here, as before its tables
    facts = chess.ENDGAMES[options.endgame]
    return _EndgameEnvironment(options.name, _LATER, facts.n_actions, facts.n_states(options.symmetries),
                               np.zeros(1), np.ones(1), chess.MOVE_LIMIT, 1,
                               "positive_return" if options.rewards == "mate" else "won",
                               endings=("mate, or the piece lost", "fifty moves without mate"), legal_moves=_LATER)


def _atari(name: str) -> Environment:
    """An Atari 2600 game under Machado et al.'s protocol (:mod:`rlcompare.envs.atari.games`), through ale-py."""
    import numpy as np

    shape = atari.PROTOCOL.observation_shape
    size = int(np.prod(shape))
    return Environment(name, None, len(atari.ACTION_NAMES), 0, np.zeros(size), np.full(size, 255.0),
                       atari.PROTOCOL.max_steps, 1, "positive_return", action_names=atari.ACTION_NAMES,
                       endings=("game over", "out of time"), jax_port="rlcompare.deep.atari:atari_env",
                       observation_shape=shape, tabular=False)


def _chess_game(name: str) -> Environment:
    """A whole game of chess, played against itself (:mod:`rlcompare.envs.chess.games`), through pgx."""
    import numpy as np

    game = chess_games.GAMES[name]
    shape = game.observation_shape
    size = int(np.prod(shape))
    return Environment(name, None, game.n_actions, 0, np.zeros(size), np.ones(size), game.max_plies, 1, "won",
                       endings=("mate, or a draw by the rules", f"{game.max_plies} plies"),
                       jax_port="rlcompare.deep.chess.games:chess_game_env", observation_shape=shape, tabular=False)


_PORTED = {
    "MountainCar-v0": lambda: _mountain_car("MountainCar-v0", bench_episodes=300,
                                            jax_port="rlcompare.deep.classic:MOUNTAIN_CAR"),
    "MountainCar-book": lambda: _mountain_car("MountainCar-book", book=True, shown_as="MountainCar-v0"),
    "CartPole-v1": _cartpole,
    "Acrobot-v1": _acrobot,
}
_TABLE_DEFAULTS = {"CliffWalking-v1": (1000, "terminated", 3000), "FrozenLake-v1": (100, "positive_return", 20000),
                   "FrozenLake8x8-v1": (200, "positive_return", 5000), "Taxi-v4": (200, "terminated", 1000)}
"""Step limit, what counts as solved, and benchmark episodes of each table environment."""
PORTS = tuple(_PORTED)
ENDGAMES = tuple(chess.ENDGAMES)
"""Chess endgames, each stepped by its rules against a defender; options follow the name (``KRK:defender=random``)."""
TABLE_ENVIRONMENTS = tuple(_TABLE_DEFAULTS)
"""Finite environments stepped from their Gymnasium transition tables; their state is their feature."""


@functools.cache
def environment(name: str, adapter: bool = False) -> Environment:
    """The environment called ``name``: a port, a table, or any Gymnasium environment the adapter can run
    (:class:`rlcompare.envs.gymnasium_env.UnsupportedEnvironment` otherwise). ``adapter``: step a port's
    environment through Gymnasium's API instead, with the port's defaults."""
    import numpy as np

    from rlcompare.envs import gymnasium_env

    if adapter and name in (*PORTS, *TABLE_ENVIRONMENTS):
        gymnasium_env.describe(name)  # MountainCar-book is not one of Gymnasium's
        port = environment(name)
        return dataclasses.replace(port, dynamics=None)
    if name in _PORTED:
        return _PORTED[name]()
    if name in minatar.NAMES:
        return _minatar(name)
    if name in atari.NAMES:
        return _atari(name)
    if name in chess_games.GAMES:
        return _chess_game(name)
    if chess.is_endgame_name(name):
        return _endgame(name)
    if name in TABLE_ENVIRONMENTS:
        tabled = table_of(name)
        limit, success, bench_episodes = _TABLE_DEFAULTS[name]
        return Environment(name, tabled, tabled.n_actions, tabled.n_states, np.zeros(1), np.ones(1), limit, 1, success,
                           bench_episodes=bench_episodes)
    spaces = gymnasium_env.describe(name)
    return Environment(name, None, spaces.n_actions, spaces.n_states, spaces.low, spaces.high,
                       spaces.max_episode_steps or 1000, 10, "terminated")


@functools.cache
def table_of(name: str) -> TableEnv:
    from rlcompare.envs.table import from_gymnasium

    return from_gymnasium(name)


def make_env(env: Environment, handle: int = -1) -> Any:
    """What compiled code steps for ``env``: its port or table, or, for the adapter, the Gymnasium environments
    opened under ``handle``."""
    from rlcompare.envs import gymnasium_env

    if env.is_ported:
        return env.dynamics
    return gymnasium_env.Adapted(handle, 0, env.observation_size)
