"""An agent played in Gymnasium, frame by frame: the environment's picture at every step, packed
(:mod:`rlcompare.report.frames`), with the return so far.

Rendering needs no display and no sound card: the first call that renders sets ``SDL_VIDEODRIVER`` and
``SDL_AUDIODRIVER`` to ``dummy`` (``pygame.init()``, which Gymnasium's renderers call, opens the sound device too,
and ALSA printed a dozen errors where there is none) and hides pygame's banner, with ``os.environ.setdefault``, so
a value set by the user wins. Importing this module changes nothing.

Where the environment's registry entry has a painter (Mountain Car's draws Gymnasium's picture pixel for pixel
in 0.15 ms, where ``env.render()`` takes 1.9 ms), it draws the pictures; else ``env.render()`` does.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from typing import Any, NamedTuple, Protocol

import numpy as np

from rlcompare.envs.registry import environment
from rlcompare.report import frames


class Agent(Protocol):
    def act(self, observation: np.ndarray) -> int: ...


class Frame(NamedTuple):
    picture: np.ndarray | None
    """The environment's picture, packed (:mod:`rlcompare.report.frames`), in a buffer the next frame reuses;
    None at a step :func:`play` was asked not to draw."""
    step: int
    return_so_far: float
    terminated: bool
    truncated: bool


def _headless() -> None:
    """Let pygame render without a display, a sound card or its banner; a value the user set wins."""
    os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
    os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
    os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")


def play(agent: Agent, episode_seed: int, max_steps: int, env_id: str,
         drawn: Callable[[int], bool] | None = None) -> Iterator[Frame]:
    """Step ``agent`` through one rendered episode, yielding the start frame and one frame per step.

    ``drawn(step)``: whether that step's picture is drawn (default: every step); the last step's always is, and
    the others' pictures are None (a video that shows every second step need not draw the others)."""
    _headless()
    import gymnasium as gym  # after _headless: gymnasium imports pygame when it first renders

    env = gym.make(env_id, render_mode="rgb_array", max_episode_steps=max_steps)
    try:
        observation, _ = env.reset(seed=episode_seed)
        picture = _painter(env, env_id)
        total, step, terminated, truncated = 0.0, 0, False, False
        yield Frame(picture(), step, total, terminated, truncated)
        while not (terminated or truncated):
            observation, reward, terminated, truncated, _ = env.step(agent.act(observation))
            total += float(reward)
            step += 1
            shown = drawn is None or drawn(step) or terminated or truncated
            yield Frame(picture() if shown else None, step, total, bool(terminated), bool(truncated))
    finally:
        env.close()


def _painter(env: Any, env_id: str) -> Callable[[], np.ndarray]:
    """What draws ``env``'s current picture, packed: the registry's painter, equal to ``env.render()`` and
    quicker, where the environment has one; else ``env.render()`` itself."""
    painter = environment(env_id).painter
    if painter is None:
        return lambda: frames.pack(env.render())
    drawn = painter(env.unwrapped)
    buffer = np.empty(drawn.size[::-1], dtype=np.uint32)

    def picture() -> np.ndarray:
        drawn.paint(buffer)
        return buffer
    return picture
