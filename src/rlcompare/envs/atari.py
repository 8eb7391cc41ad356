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

Each game is named ``<Game>-Atari``, as MinAtar's gymnax games are ``<Game>-MinAtar``.
"""

from __future__ import annotations

from dataclasses import dataclass

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
    summary: str = ("Machado et al. (2018): sticky actions 0.25, all 18 actions, no loss-of-life ends, episodes cut "
                    "at 108,000 frames; Mnih et al. (2015)'s preprocessing: 4 frames a step, 84 x 84 grey, 4 stacked")

    @property
    def max_steps(self) -> int:
        return self.max_frames // self.frameskip

    @property
    def observation_shape(self) -> tuple[int, int, int]:
        return (self.size, self.size, self.stack)


PROTOCOL = Protocol()
GAMES = {"Asterix": "asterix", "Breakout": "breakout", "Freeway": "freeway", "Pong": "pong", "Seaquest": "seaquest",
         "SpaceInvaders": "space_invaders"}
"""Game title (as ALE's Gymnasium names spell it) -> ALE's ROM id: the originals of MinAtar's five, and Pong."""
NAMES = {f"{title}-Atari": rom for title, rom in GAMES.items()}
"""Every Atari environment's name, with its ROM."""
