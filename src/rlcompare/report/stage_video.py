"""A video of an agent at several stages of learning, side by side, one captioned panel a stage: the paper shows its
agents "in three stages of learning". The episodes (one a stage, played in lockstep) and how a state is pictured
come from the caller: :mod:`rlcompare.deep.playback` plays a deep run's stages, and the environment's own module
draws its states (MinAtar's in its own colours, :func:`rlcompare.envs.minatar.picture`).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Protocol

import numpy as np

from rlcompare.report import captions, frames
from rlcompare.report.encode import GIF_EVERY, GIF_SCALE, GifFrames, mp4_writer

FPS = 20
"""MinAtar's display shows each state for 50 ms."""
GUTTER = 6
"""White pixels between two panels."""


class Episodes(Protocol):
    """One episode a stage, played in lockstep (:class:`rlcompare.deep.playback.Played`)."""

    @property
    def observations(self) -> np.ndarray:
        """(stages, steps + 1, ...): an ended episode keeps its last observation."""
        ...

    @property
    def returns(self) -> np.ndarray:
        """(stages, steps + 1): the return so far."""
        ...

    @property
    def lengths(self) -> np.ndarray:
        """(stages,): steps each episode took before it ended or the limit."""
        ...

    @property
    def ended(self) -> np.ndarray:
        """(stages,): whether the episode ended within the limit."""
        ...


def frames_of(played: Episodes, titles: list[str], picture: Callable[[np.ndarray], np.ndarray]
              ) -> Iterator[np.ndarray]:
    """The video's packed frames: one panel a stage, side by side, each ``picture(observation)`` under its title
    (the stage and the training behind it) and its return and step so far."""
    for t in range(int(played.lengths.max()) + 1):
        panels = []
        for index, title in enumerate(titles):
            at = min(t, int(played.lengths[index]))
            over = played.ended[index] and t >= played.lengths[index]
            state = f"game over at step {at:,}" if over else f"step {at:,}"
            panels.append(captions.add_caption(picture(played.observations[index, at]), title,
                                               f"return {played.returns[index, at]:g} · {state}"))
        gutter = np.full((panels[0].shape[0], GUTTER, 3), 255, np.uint8)
        yield frames.pack(np.hstack([part for panel in panels for part in (panel, gutter)][:-1]))


def render_stages(played: Episodes, titles: list[str], picture: Callable[[np.ndarray], np.ndarray], mp4: Path,
                  gif: Path | None = None) -> list[Path]:
    """Write one MP4 (and a small looping GIF) of the stages playing side by side (:func:`frames_of`)."""
    small = GifFrames(GIF_SCALE, GIF_EVERY) if gif is not None else None
    with warnings.catch_warnings():  # JAX warns of any fork; ffmpeg's is followed at once by exec
        warnings.filterwarnings("ignore", "os.fork", RuntimeWarning)
        with mp4_writer(Path(mp4), FPS) as writer:
            for packed in frames_of(played, titles, picture):
                writer.append(packed)
                if small is not None:
                    small.add(packed)
    return [Path(mp4)] if small is None or gif is None else [Path(mp4), small.save(gif, FPS)]
