"""MinAtar's five games (Young and Tian 2019, arXiv 1903.03176) and the two protocols they are played under: the
facts the registry, the pictures and the deep engine's port share (no JAX here; the port is
:mod:`rlcompare.deep.minatar.games`).

| protocol    | sticky actions | actions         | episode ends                        | example name            |
|-------------|----------------|-----------------|-------------------------------------|-------------------------|
| ``minatar`` | 0.1            | all 6           | the game's own end only (its paper) | ``MinAtar/Breakout-v0`` |
| ``gymnax``  | none           | the minimal set | the game's end, or gymnax's limit   | ``Breakout-MinAtar``    |

Each environment is named as its library names it: ``MinAtar/<Game>-v0`` is the reference package's Gymnasium
registration (all six actions, sticky actions 0.1, difficulty ramping), ``<Game>-MinAtar`` gymnax's.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy as np

ACTION_NAMES = ("no-op", "left", "up", "right", "down", "fire")
"""MinAtar's six actions, in the reference's order (``n l u r d f``)."""


@dataclass(frozen=True)
class Protocol:
    """How the agent plays a game: the MinAtar paper's or gymnax's (PQN's)."""

    name: str
    sticky_action_prob: float
    """The chance that the previous action is repeated in place of the one chosen (Machado et al. 2018)."""
    full_action_set: bool
    """All six actions; otherwise the game's minimal set."""
    time_limit: bool
    """Truncate at gymnax's ``max_steps_in_episode``; otherwise only the game ends an episode."""
    summary: str


PROTOCOLS = {
    "minatar": Protocol("minatar", 0.1, True, False,
                        "the MinAtar paper's: sticky actions 0.1, all 6 actions, difficulty ramping, no time limit"),
    "gymnax": Protocol("gymnax", 0.0, False, True,
                       "gymnax's and PQN's: no sticky actions, the minimal action set, gymnax's time limits"),
}


@dataclass(frozen=True)
class Game:
    """One game: its names, its observation channels (the reference's order) and its minimal action set."""

    title: str
    """``SpaceInvaders``: as the Gymnasium names spell it."""
    module_name: str
    """``space_invaders``: as the reference package names it."""
    channels: tuple[str, ...]
    minimal_actions: tuple[int, ...]
    """Indices into :data:`ACTION_NAMES`."""
    time_limit: int
    """gymnax's ``max_steps_in_episode``."""
    reference: float
    """The MinAtar paper's DQN at 5 M frames (:data:`REFERENCE_SOURCE`): the top of the range margins and normalised
    scores are fractions of."""

    def name(self, protocol: str) -> str:
        return f"MinAtar/{self.title}-v0" if protocol == "minatar" else f"{self.title}-MinAtar"


REFERENCE_SOURCE = ("the MinAtar paper's DQN at 5 M frames (Young and Tian 2019, 'MinAtar: An Atari-Inspired Testbed "
                    "for Thorough and Reproducible Reinforcement Learning Experiments', Figure 2), read off its "
                    "published learning curves at their last point, to within about 5%")
"""Where the games' references come from, and how they were read (no table of them is published)."""

GAMES = {game.module_name: game for game in (
    Game("Asterix", "asterix", ("player", "enemy", "trail", "gold"), (0, 1, 2, 3, 4), 1000, 17.0),
    Game("Breakout", "breakout", ("paddle", "ball", "trail", "brick"), (0, 1, 3), 1000, 10.0),
    Game("Freeway", "freeway", ("chicken", "car", "speed1", "speed2", "speed3", "speed4", "speed5"), (0, 2, 4),
         2500, 50.0),
    Game("Seaquest", "seaquest", ("sub_front", "sub_back", "friendly_bullet", "trail", "enemy_bullet", "enemy_fish",
                                  "enemy_sub", "oxygen_guage", "diver_guage", "diver"), (0, 1, 2, 3, 4, 5), 1000, 20.0),
    Game("SpaceInvaders", "space_invaders",
         ("cannon", "alien", "alien_left", "alien_right", "friendly_bullet", "enemy_bullet"), (0, 1, 3, 5), 1000, 43.0),
)}
FREEWAY_STEPS = 2501
"""The reference's Freeway ends its episode (terminal) after this many steps; gymnax truncates one step earlier."""
NAMES = {game.name(protocol): (game, PROTOCOLS[protocol]) for game in GAMES.values() for protocol in PROTOCOLS}
"""Every MinAtar environment's name, with its game and protocol."""


def actions(game: Game, protocol: Protocol) -> tuple[int, ...]:
    """The agent's actions under ``protocol``, as indices into MinAtar's six."""
    return tuple(range(len(ACTION_NAMES))) if protocol.full_action_set else game.minimal_actions


def max_steps(game: Game, protocol: Protocol) -> int | None:
    """gymnax's limit under its protocol; None where only the game ends an episode."""
    return game.time_limit if protocol.time_limit else None


CELL = 24
"""Pixels per side of one of the grid's 10 x 10 cells in a picture."""


def palette(n_channels: int) -> np.ndarray:
    """``(n_channels + 1, 3)`` uint8: black, then one colour per channel, MinAtar's own: the reference package's
    ``render_mode="rgb_array"`` (``minatar/gym.py``) uses seaborn's ``cubehelix`` palette, which is matplotlib's
    cubehelix colour map at ``n`` evenly spaced inner points."""
    import matplotlib
    import numpy as np

    inner = np.linspace(0.0, 1.0, n_channels + 2)[1:-1]
    colours = np.vstack([np.zeros(3), matplotlib.colormaps["cubehelix"](inner)[:, :3]])
    return np.round(colours * 255).astype(np.uint8)


def picture(observation: np.ndarray, colours: np.ndarray, cell: int = CELL) -> np.ndarray:
    """``(10 cell, 10 cell, 3)`` uint8: each cell in the colour of the highest channel set in it, black where none
    is."""
    import numpy as np

    channels = observation.shape[-1]
    index = np.max(observation.astype(np.int64) * np.arange(1, channels + 1), axis=-1)
    return np.repeat(np.repeat(colours[index], cell, axis=0), cell, axis=1)
