"""A trained deep agent that acts inside Gymnasium's own environment, loaded from a run directory."""

from __future__ import annotations

from typing import Any

import jax
import numpy as np

from rlcompare.deep import float64
from rlcompare.deep.methods import deep_method
from rlcompare.deep.results import DeepResults
from rlcompare.deep.train import params_template
from rlcompare.envs.observations import check_box_observation


class DeepAgent:
    """The greedy policy of one seed's network at one stage of learning: ``act(observation) -> action``."""

    def __init__(self, results: DeepResults, seed: int, stage: str = "final") -> None:
        config = results.config
        self.config, self.seed, self.stage = config, seed, stage
        self.params: Any = results.seed_params(seed, params_template(config), stage)
        self._act = jax.jit(deep_method(config.algorithm).module.act(config.method_config(), config.environment))
        self._shape = tuple(config.environment.observation_shape)

    @float64
    def act(self, observation: np.ndarray) -> int:
        """The greedy action for one observation as Gymnasium's ``env.step`` returns it."""
        if isinstance(observation, np.ndarray) and observation.dtype == np.bool_:  # MinAtar's images
            observation = observation.astype(np.float32)
        checked = check_box_observation(observation, self._shape, self.config.env).astype(np.float32)
        return int(self._act(self.params, checked[None])[0])


def agent(results: DeepResults, seed: int, stage: str = "final") -> DeepAgent:
    """The greedy agent of ``seed``'s network at ``stage`` (``results.stages``)."""
    return DeepAgent(results, seed, stage)


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
