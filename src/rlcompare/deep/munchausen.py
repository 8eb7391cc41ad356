"""Munchausen DQN (Vieillard, Pietquin and Geist 2020, "Munchausen Reinforcement Learning", NeurIPS): DQN whose
target adds a scaled log-policy of the action taken and bootstraps from the next state's soft value, the policy
being the softmax of the target network's Q-values at a temperature τ (their eq. 2; "M-DQN"):

    r + α τ clip(ln π(a|s), l0, 0) + γ Σ_a' π(a'|s') (q̄(s', a') - τ ln π(a'|s')),   π = softmax(q̄ / τ).

Everything else is :mod:`rlcompare.deep.dqn`'s (replay, target network, Huber loss, ε-greedy collection). It is
off-policy, as DQN: it learns from replayed transitions of older policies. The presets are DQN's settings with the
paper's τ = 0.03, α = 0.9 and l0 = -1; departures from the paper (which ran on the Atari 2600 with Dopamine's
DQN) are DQN's own (``docs/deep.md``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass

import jax
import jax.numpy as jnp

from rlcompare.deep import dqn, rollout
from rlcompare.deep.envs import Environment
from rlcompare.deep.presets import dqn as dqn_config
from rlcompare.deep.presets.dqn import DQNConfig
from rlcompare.deep.replay import Transitions
from rlcompare.validation import POSITIVE, UNIT, Number, setting

__all__ = ["PRESETS", "Config", "act", "make_train", "network", "scores"]


@dataclass(frozen=True)
class MunchausenConfig(DQNConfig):
    """DQN's settings and the three of the Munchausen target."""

    tau: float = setting(0.03, POSITIVE)
    """τ, the temperature of the policy the target reads: π = softmax(q̄ / τ), > 0."""
    scale: float = setting(0.9, UNIT)
    """α, the weight of the Munchausen term α τ ln π(a|s), in [0, 1]; 0 leaves soft DQN."""
    log_floor: float = setting(-1.0, Number(high=0.0, high_open=True))
    """l0: ln π(a|s) is clipped to [l0, 0] in the Munchausen term, a finite number < 0."""


PRESETS = {preset: {env: MunchausenConfig(**dataclasses.asdict(settings)) for env, settings in table.items()}
           for preset, table in dqn_config.PRESETS.items()}
"""DQN's presets (:data:`rlcompare.deep.presets.dqn.PRESETS`) with the paper's Munchausen settings: τ = 0.03,
α = 0.9, l0 = -1 (Vieillard et al. 2020, section 4 and appendix B.1, the same on every game)."""
Config = MunchausenConfig
"""The method's settings (:class:`~rlcompare.deep.methods.MethodModule`)."""


def munchausen_targets(params: dqn.Params, target_params: dqn.Params, batch: Transitions, apply: dqn.Apply,
                       config: MunchausenConfig) -> jax.Array:
    """The M-DQN target of each transition (Vieillard et al. 2020, eq. 2), from the target network alone; the
    log-policy through ``log_softmax``, which subtracts the maximum first (their appendix B.1's stable form)."""
    log_policy = jax.nn.log_softmax(apply(target_params, batch.observations) / config.tau, axis=-1)
    taken = jnp.take_along_axis(log_policy, batch.actions[:, None], axis=-1)[:, 0]
    bonus = config.scale * config.tau * jnp.clip(taken, config.log_floor, 0.0)
    next_q = apply(target_params, batch.next_observations)
    next_log_policy = jax.nn.log_softmax(next_q / config.tau, axis=-1)
    soft_value = jnp.sum(jnp.exp(next_log_policy) * (next_q - config.tau * next_log_policy), axis=-1)
    return batch.rewards + bonus + config.gamma * jnp.where(batch.terminated, 0.0, soft_value)


def make_train(config: MunchausenConfig, env: Environment, rounds: int, eval_episodes: int
               ) -> Callable[[jax.Array], rollout.TrainOutput]:
    """DQN's training (:func:`rlcompare.deep.dqn.make_train`) learning toward :func:`munchausen_targets`."""
    return dqn.make_train(config, env, rounds, eval_episodes, targets=munchausen_targets)


act = dqn.act
"""The greedy policy of the Q-network, DQN's."""
scores = dqn.scores
"""The Q-values, DQN's."""
network = dqn.network
"""The Q-network, DQN's."""
