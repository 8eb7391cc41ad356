"""A deep run's networks at their stages of learning, each playing one greedy episode from the same start and with
the same environment draws (one key for all), so that what differs between them is only what the agent has learned:
the episodes the stage videos show (:mod:`rlcompare.report.stage_video`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from rlcompare.deep import float64
from rlcompare.deep.envs import is_batched
from rlcompare.deep.methods import deep_method
from rlcompare.deep.results import DeepResults
from rlcompare.deep.rollout import stage_rounds
from rlcompare.deep.train import params_template

MAX_STEPS = 1_000
"""An episode plays at most this many steps (50 seconds of video)."""
EPISODE_KEY = 10_000
"""The episode's key, ``jax.random.key(EPISODE_KEY)``: apart from every training and evaluation key."""


@dataclass(frozen=True)
class Played:
    """One episode per stage, played in lockstep."""

    observations: np.ndarray
    """(stages, max_steps + 1, ...): MinAtar's (10, 10, channels) bool images, or an Atari game's screens
    (:mod:`rlcompare.studies.atari.play`); an ended episode keeps its last."""
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
    if is_batched(env):
        raise ValueError(f"{config.env}: an emulator's games are not played stage by stage here")
    act = deep_method(config.algorithm).module.act(config.method_config(), env)
    template = params_template(config)
    stacked = jax.tree.map(lambda *leaves: jnp.stack(leaves),
                           *[results.seed_params(seed, template, stage) for stage in results.stages])

    def episode(params: Any, episode_key: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array, jax.Array]:
        """The first episode :func:`~rlcompare.deep.rollout.evaluate` plays from ``episode_key``, to its end or
        ``max_steps``."""
        step_key = jax.random.fold_in(episode_key, 1)

        def one_step(carry: tuple[Any, jax.Array, jax.Array], t: jax.Array
                     ) -> tuple[tuple[Any, jax.Array, jax.Array], tuple[jax.Array, jax.Array, jax.Array, jax.Array]]:
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


def stage_titles(results: DeepResults) -> list[str]:
    """Each stage with the training steps behind its network: ``early (512 steps)``."""
    return [f"{stage} ({steps:,} steps)" for stage, steps in stage_steps(results).items()]
