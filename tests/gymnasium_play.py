"""Agents played in Gymnasium's own environments, to compare with what the kernels recorded."""

from __future__ import annotations

import gymnasium as gym
import numpy as np


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
