"""An Atari run's agents at their stages of learning, loaded by :func:`rlcompare.load_agent` and playing Gymnasium's
own ``ALE/<Game>-v5`` (:func:`rlcompare.envs.atari.games.gymnasium_env`): one episode a stage from the same start and
with the same draws, each frame the game's own screen, for the stage videos (:mod:`rlcompare.report.stage_video`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from rlcompare.deep.playback import Played
from rlcompare.deep.results import DeepResults
from rlcompare.envs.atari import games as atari
from rlcompare.experiment.engines import load_agent

STAGE_STEPS = 600
"""An episode plays at most this many agent steps (30 seconds of video at 20 frames a second)."""
EPISODE_SEED = 10_000
"""Every stage's episode starts from ``env.reset(seed=EPISODE_SEED)``, its ε draws from the same generator."""
SCALE = 2
"""Each screen pixel drawn as ``SCALE x SCALE``."""


def episode(agent: Any, env: Any, max_steps: int, seed: int) -> tuple[list[np.ndarray], list[float], bool]:
    """The screens and scores so far of one episode of ``agent`` in ``env``, from ``reset(seed=seed)``; and
    whether the game ended within ``max_steps``."""
    observation, _ = env.reset(seed=seed)
    screens, scores = [env.render()], [0.0]
    for _ in range(max_steps):
        observation, reward, terminated, truncated, _ = env.step(agent.act(observation))
        screens.append(env.render())
        scores.append(scores[-1] + float(reward))
        if terminated or truncated:
            return screens, scores, True
    return screens, scores, False


def play_stages(run_dir: Path, results: DeepResults, seed: int, max_steps: int = STAGE_STEPS,
                epsilon: float = atari.PROTOCOL.eval_epsilon) -> Played:
    """Every stage of ``seed``'s network in ``run_dir``, loaded by ``load_agent``, playing one episode of
    Gymnasium's game: its screens ``(stages, steps + 1, 210, 160, 3)``, each episode padded with its last."""
    env = atari.gymnasium_env(results.config.env, render_mode="rgb_array")
    try:
        episodes = [episode(load_agent(run_dir, seed, stage, epsilon=epsilon, exploration_seed=EPISODE_SEED), env,
                            max_steps, EPISODE_SEED)
                    for stage in results.stages]
    finally:
        env.close()
    longest = max(len(screens) for screens, _, _ in episodes)
    return Played(np.stack([np.stack(padded(screens, longest)) for screens, _, _ in episodes]),
                  np.stack([np.asarray(padded(scores, longest), np.float32) for _, scores, _ in episodes]),
                  np.asarray([len(screens) - 1 for screens, _, _ in episodes]),
                  np.asarray([ended for _, _, ended in episodes]))


def padded(values: list[Any], length: int) -> list[Any]:
    """``values`` continued with its last to ``length``."""
    return values + [values[-1]] * (length - len(values))


def upscaled(screen: np.ndarray) -> np.ndarray:
    """The game's screen with each pixel :data:`SCALE` times wider and taller."""
    return np.repeat(np.repeat(screen, SCALE, axis=0), SCALE, axis=1)
