"""Atari 2600 games through the Arcade Learning Environment (``ale-py``): the facts the registry and the deep
engine share (no emulator here; the engine's side is :mod:`rlcompare.deep.atari`).

One protocol, Machado et al.'s (2018, "Revisiting the Arcade Learning Environment", JAIR 61) as ALE's ``-v5``
environments take it, with the standard preprocessing of Mnih et al. (2015, "Human-level control through deep
reinforcement learning"):

| what                      | setting                                                                       |
|---------------------------|-------------------------------------------------------------------------------|
| sticky actions            | 0.25 (the emulator repeats the previous action with that chance, every frame)  |
| actions                   | all 18 of the joystick, whatever the game uses                                 |
| frames per step           | 4, the last two max-pooled                                                     |
| observation               | 84 x 84 grey levels, the last 4 steps stacked: ``(84, 84, 4)`` uint8            |
| an episode ends           | at game over (a lost life does not end it), or after 108,000 frames (27,000 steps) |
| start                     | the game's own (no random no-ops, no FIRE pressed: sticky actions randomise)   |
| rewards                   | the game's score; the methods learn from its sign (Mnih et al.), records keep the score |
| evaluation                | ε-greedy with ε = 0.05 (Mnih et al.), every episode to game over or the cut     |

Each game is named ``<Game>-Atari``, as MinAtar's gymnax games are ``<Game>-MinAtar``; :func:`gymnasium_env` is
Gymnasium's own environment of the game under the same protocol, where trained agents play.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from rlcompare.envs.atari import scores as atari_scores

if TYPE_CHECKING:
    import gymnasium as gym

ACTION_NAMES = ("no-op", "fire", "up", "right", "left", "down", "up-right", "up-left", "down-right", "down-left",
                "up-fire", "right-fire", "left-fire", "down-fire", "up-right-fire", "up-left-fire", "down-right-fire",
                "down-left-fire")
"""The joystick's 18 actions, in ALE's order (``ale_py.Action``)."""


@dataclass(frozen=True)
class Protocol:
    """How the agent plays: the emulator's settings and the preprocessing."""

    sticky_action_prob: float = 0.25
    frameskip: int = 4
    max_frames: int = 108_000
    """Frames after which an episode is cut (truncated)."""
    size: int = 84
    stack: int = 4
    eval_epsilon: float = 0.05
    """The evaluations' chance of a random action (Mnih et al. 2015's evaluation): a greedy policy that never
    presses FIRE would otherwise play to the cut, 27,000 steps, without starting the game."""
    summary: str = ("Machado et al. (2018): sticky actions 0.25, all 18 actions, no loss-of-life ends, episodes cut "
                    "at 108,000 frames; Mnih et al. (2015)'s preprocessing (4 frames a step, 84 x 84 grey, 4 stacked) "
                    "and evaluation at ε = 0.05")

    @property
    def max_steps(self) -> int:
        return self.max_frames // self.frameskip

    @property
    def observation_shape(self) -> tuple[int, int, int]:
        return (self.size, self.size, self.stack)


PROTOCOL = Protocol()
GAMES = {title: game.rom for title, game in atari_scores.GAMES.items()}
"""Game title (as ALE's Gymnasium names spell it) -> ALE's ROM id: the 57 games of the standard suite
(:mod:`rlcompare.envs.atari.scores`)."""
NAMES = {f"{title}-Atari": rom for title, rom in GAMES.items()}
"""Every Atari environment's name, with its ROM."""


def title_of(name: str) -> str:
    """``Breakout`` for ``Breakout-Atari``."""
    return name.removesuffix("-Atari")


def gymnasium_env(name: str, protocol: Protocol = PROTOCOL, **make: Any) -> gym.Env[Any, Any]:
    """Gymnasium's own ``ALE/<Game>-v5`` set as the engine's training is (``make``: ``render_mode``, say): the
    emulator's settings in ``gym.make`` (one frame a step, sticky actions, all 18 actions, the cut), then Gymnasium's
    ``AtariPreprocessing`` (4 frames a step, the last two max-pooled, 84 x 84 grey, no no-ops, a lost life goes on)
    and ``FrameStackObservation`` (4, zero-padded at a reset as ALE's vector environment starts its stacks). Its
    observations are ``(4, 84, 84)``; the same actions give the frames the engine's emulator gives
    (``tests/parity/test_atari.py``). Needs the Atari extra."""
    import ale_py
    import gymnasium

    from rlcompare.envs.gymnasium_env import UnsupportedEnvironment

    if name not in NAMES:
        raise UnsupportedEnvironment(f"{name!r} is not an Atari game here; allowed: NAME-Atari, NAME one of "
                                     f"{', '.join(GAMES)}")
    gymnasium.register_envs(ale_py)
    env = gymnasium.make(f"ALE/{title_of(name)}-v5", frameskip=1, repeat_action_probability=protocol.sticky_action_prob,
                         full_action_space=True, max_num_frames_per_episode=protocol.max_frames, **make)
    env = gymnasium.wrappers.AtariPreprocessing(env, noop_max=0, frame_skip=protocol.frameskip,
                                                screen_size=protocol.size, terminal_on_life_loss=False,
                                                grayscale_obs=True, scale_obs=False)
    return gymnasium.wrappers.FrameStackObservation(env, protocol.stack, padding_type="zero")


def action_set(env: gym.Env[Any, Any]) -> tuple[int, ...]:
    """The joystick actions (numbers of :data:`ACTION_NAMES`) that a Gymnasium ALE environment's actions 0, 1, ...
    press: all 18 in ALE's order (``full_action_space=True``, :func:`gymnasium_env`), or the game's minimal set,
    Gymnasium's default (Breakout's: no-op, fire, right, left). Read from ALE's names of the environment's own
    actions (``get_action_meanings``), whatever wrappers it has."""
    from rlcompare.validation import ConfigError

    unwrapped: Any = env.unwrapped
    if not hasattr(unwrapped, "ale"):
        raise ConfigError("env", type(unwrapped).__name__, "an ALE/<Game>-v5 environment of Gymnasium's (ale-py)")
    number = {action.name: int(action.value) for action in unwrapped.ale.getLegalActionSet()}
    return tuple(number[meaning] for meaning in unwrapped.get_action_meanings())
