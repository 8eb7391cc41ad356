"""Agents played in Gymnasium's own environments, to compare with what the kernels recorded; Gymnasium's resets
beside a port's."""

from __future__ import annotations

import itertools
from collections.abc import Iterator

import gymnasium as gym
import numpy as np

from rlcompare.rng import stream_state


def gymnasium_returns(agent, stream: np.random.SeedSequence, episodes: int, *, env_id: str = "MountainCar-v0",
                      limit: int = 1000) -> list[float]:
    """Returns of ``agent`` in ``gym.make(env_id)``, its resets drawn from ``stream`` (an evaluation stream)."""
    env = gym.make(env_id, max_episode_steps=limit)
    env.reset(seed=0)
    env.unwrapped.np_random = np.random.Generator(np.random.PCG64(stream))
    returns = []
    for _ in range(episodes):
        observation, _ = env.reset()
        total, done = 0.0, False
        while not done:
            observation, reward, terminated, truncated, _ = env.step(agent.act(observation))
            total, done = total + reward, terminated or truncated
        returns.append(total)
    env.close()
    return returns


def resets(env: gym.Env, generator: np.random.Generator, every: int) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """Gymnasium's resets of ``env``, one an episode, each with the stream a port's ``reset`` is given beside it:
    a fresh seed drawn from ``generator`` every ``every``-th episode (the first included), plain resets in between,
    which draw on from the seed's stream as the port's do. Yields ``(observation, stream)``."""
    stream = None
    for episode in itertools.count():
        if episode % every == 0:
            seed = int(generator.integers(2**31))
            observation, _ = env.reset(seed=seed)
            stream = stream_state(seed)
        else:
            observation, _ = env.reset()
        yield observation, stream
