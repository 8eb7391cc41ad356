"""Videos of a MinAtar agent at three stages of learning, side by side, in MinAtar's own colours.

The paper shows its agents "in three stages of learning"; here the networks a deep run keeps
(``DeepResults.stages``: after a tenth and half of the training, and the last) play one episode each from the same
start, with the same environment draws (one key for all three), so the panels differ only in what the agent has
learned. A picture colours each cell by the highest channel set in it, black where none is, with the palette of the
reference package's ``render_mode="rgb_array"`` (``minatar/gym.py``: seaborn's ``cubehelix`` palette, one colour per
channel, which is matplotlib's cubehelix colour map at ``n`` evenly spaced inner points).
"""

from __future__ import annotations

import warnings
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import matplotlib
import numpy as np

from rlcompare.analysis import captions, frames
from rlcompare.analysis.encode import GIF_EVERY, GIF_SCALE, GifFrames, mp4_writer
from rlcompare.deep import float64
from rlcompare.deep.methods import deep_method
from rlcompare.deep.rollout import stage_rounds
from rlcompare.deep.run import DeepResults, params_template

CELL = 24
"""Pixels per side of one of the grid's 10 x 10 cells."""
FPS = 20
"""The reference's display shows each state for 50 ms."""
MAX_STEPS = 1_000
"""A video shows at most this many steps of its episode (50 seconds)."""
EPISODE_KEY = 10_000
"""The episode's key, ``jax.random.key(EPISODE_KEY)``: apart from every training and evaluation key."""
GUTTER = 6


def palette(n_channels: int) -> np.ndarray:
    """``(n_channels + 1, 3)`` uint8: black, then one cubehelix colour per channel (MinAtar's own)."""
    inner = np.linspace(0.0, 1.0, n_channels + 2)[1:-1]
    colours = np.vstack([np.zeros(3), matplotlib.colormaps["cubehelix"](inner)[:, :3]])
    return np.round(colours * 255).astype(np.uint8)


def picture(observation: np.ndarray, colours: np.ndarray, cell: int = CELL) -> np.ndarray:
    """``(10 cell, 10 cell, 3)`` uint8: each cell in the colour of the highest channel set in it."""
    channels = observation.shape[-1]
    index = np.max(observation.astype(np.int64) * np.arange(1, channels + 1), axis=-1)
    return np.repeat(np.repeat(colours[index], cell, axis=0), cell, axis=1)


@dataclass(frozen=True)
class Played:
    """One episode per stage, played in lockstep."""

    observations: np.ndarray
    """(stages, max_steps + 1, 10, 10, channels) bool; an ended episode keeps its last observation."""
    returns: np.ndarray
    """(stages, max_steps + 1) return so far."""
    lengths: np.ndarray
    """(stages,) steps each episode took before it ended or the video's limit."""
    ended: np.ndarray
    """(stages,) the game ended within the limit."""


def first(key: jax.Array) -> jax.Array:
    """The first of the keys :func:`~rlcompare.deep.rollout.evaluate` splits ``key`` into for its episodes."""
    return jax.random.split(key, 1)[0]


@float64
def play_stages(results: DeepResults, seed: int, max_steps: int = MAX_STEPS, key: int = EPISODE_KEY) -> Played:
    """Every stage's greedy network of ``seed`` playing one episode from ``jax.random.key(key)``."""
    config = results.config
    env = config.environment
    act = deep_method(config.algorithm).module.act(config.method_config(), env)
    template = params_template(config)
    stacked = jax.tree.map(lambda *leaves: jnp.stack(leaves),
                           *[results.seed_params(seed, template, stage) for stage in results.stages])

    def episode(params: Any, episode_key: jax.Array) -> tuple:
        """The first episode :func:`~rlcompare.deep.rollout.evaluate` plays from ``episode_key``, to its end or
        ``max_steps``."""
        step_key = jax.random.fold_in(episode_key, 1)

        def one_step(carry: tuple, t: jax.Array) -> tuple:
            state, running, total = carry
            observation = env.observe(state)
            action = act(params, observation[None])[0]
            after, reward, terminated, truncated = env.step(state, action, first(jax.random.fold_in(step_key, t)))
            state = jax.tree.map(lambda new, old: jnp.where(running, new, old), after, state)
            total = total + jnp.where(running, reward, 0.0)
            ended = running & (terminated | truncated)
            return (state, running & ~ended, total), (env.observe(state), total, running, ended)

        start = env.reset(first(episode_key))
        carry = (start, jnp.ones((), bool), jnp.zeros((), jnp.float32))
        _, (observations, totals, running, ended) = jax.lax.scan(one_step, carry, jnp.arange(max_steps))
        return (jnp.concatenate([env.observe(start)[None], observations]),
                jnp.concatenate([jnp.zeros(1, jnp.float32), totals]), running.sum(), ended.any())

    played = jax.jit(jax.vmap(episode, in_axes=(0, None)))(stacked, jax.random.key(key))
    observations, returns, lengths, ended = (np.asarray(x) for x in played)
    return Played(observations.astype(bool), returns.astype(np.float64), lengths, ended)


def stage_steps(results: DeepResults) -> dict[str, int]:
    """Training steps behind each stage's network."""
    after = results.evaluations.groupby("round")["after_step"].first()
    rounds = results.config.eval_rounds
    kept = dict(zip(results.stages, [*stage_rounds(rounds), rounds - 1], strict=True))
    return {stage: int(after[index]) for stage, index in kept.items()}


def frames_of(results: DeepResults, played: Played) -> Iterator[np.ndarray]:
    """The video's packed frames: one captioned panel per stage, side by side."""
    colours = palette(played.observations.shape[-1])
    steps = stage_steps(results)
    for t in range(int(played.lengths.max()) + 1):
        panels = []
        for index, stage in enumerate(results.stages):
            at = min(t, int(played.lengths[index]))
            over = played.ended[index] and t >= played.lengths[index]
            state = f"game over at step {at:,}" if over else f"step {at:,}"
            panel = picture(played.observations[index, at], colours)
            panels.append(captions.add_caption(panel, f"{stage} ({steps[stage]:,} steps)",
                                               f"return {played.returns[index, at]:g} · {state}"))
        gutter = np.full((panels[0].shape[0], GUTTER, 3), 255, np.uint8)
        yield frames.pack(np.hstack([part for panel in panels for part in (panel, gutter)][:-1]))


def render_stages(results: DeepResults, seed: int, mp4: Path, gif: Path | None = None,
                  max_steps: int = MAX_STEPS) -> list[Path]:
    """Write one MP4 (and a small looping GIF) of ``seed``'s stages playing side by side."""
    played = play_stages(results, seed, max_steps)
    small = GifFrames(GIF_SCALE, GIF_EVERY) if gif is not None else None
    with warnings.catch_warnings():  # JAX warns of any fork; ffmpeg's is followed at once by exec
        warnings.filterwarnings("ignore", "os.fork", RuntimeWarning)
        with mp4_writer(Path(mp4), FPS) as writer:
            for packed in frames_of(results, played):
                writer.append(packed)
                if small is not None:
                    small.add(packed)
    return [Path(mp4)] if small is None or gif is None else [Path(mp4), small.save(gif, FPS)]
