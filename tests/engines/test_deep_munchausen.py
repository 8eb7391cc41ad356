"""Munchausen DQN, a deep method added as a module and a registry record: its target by hand, its limits (no
Munchausen term and a cold policy give DQN's target), its settings refused by name, and a short training whose
greedy returns are recorded seeded values."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

pytest.importorskip("jax")

import jax.numpy as jnp

from rlcompare.deep import dqn, munchausen
from rlcompare.deep.config import DeepConfig
from rlcompare.deep.methods import DEEP_METHODS
from rlcompare.deep.replay import Transitions
from rlcompare.experiment.runner import run
from rlcompare.validation import ConfigError

Q_NOW = np.array([[1.0, 2.0, 0.5], [0.0, 0.0, 3.0]], np.float32)
Q_NEXT = np.array([[0.5, 1.5, 1.0], [2.0, -1.0, 0.0]], np.float32)
BATCH = Transitions(observations=jnp.asarray(Q_NOW), actions=jnp.array([0, 2], jnp.int32),
                    rewards=jnp.array([1.0, -1.0], jnp.float32), next_observations=jnp.asarray(Q_NEXT),
                    terminated=jnp.array([False, True]))


def identity(params: object, observations: jnp.ndarray) -> jnp.ndarray:
    """A "network" whose Q-values are its input: the batch's observations are the Q-values themselves."""
    return observations


def by_hand(config: munchausen.MunchausenConfig) -> np.ndarray:
    """Vieillard et al. 2020, eq. 2, written out in float64."""
    tau, alpha, floor, gamma = config.tau, config.scale, config.log_floor, config.gamma
    out = []
    for q, action, reward, q_next, ended in zip(Q_NOW.astype(float), (0, 2), (1.0, -1.0), Q_NEXT.astype(float),
                                                (False, True), strict=True):
        log_pi = q / tau - np.log(np.sum(np.exp(q / tau)))
        log_pi_next = q_next / tau - np.log(np.sum(np.exp(q_next / tau)))
        soft = np.sum(np.exp(log_pi_next) * (q_next - tau * log_pi_next))
        out.append(reward + alpha * tau * min(max(log_pi[action], floor), 0.0) + (0.0 if ended else gamma * soft))
    return np.array(out)


@pytest.mark.parametrize("settings", [{}, {"tau": 0.5, "scale": 0.3, "log_floor": -0.2, "gamma": 0.9}])
def test_the_target_is_the_papers_equation(settings: dict) -> None:
    config = dataclasses.replace(munchausen.Config(), **settings)
    found = munchausen.munchausen_targets(None, None, BATCH, identity, config)
    np.testing.assert_allclose(np.asarray(found), by_hand(config), rtol=1e-5, atol=1e-6)


def test_without_its_term_and_with_a_cold_policy_it_is_dqns_target() -> None:
    """α = 0 and τ -> 0: the soft value is the max, the Munchausen term vanishes."""
    cold = dataclasses.replace(munchausen.Config(), scale=0.0, tau=1e-4)
    found = munchausen.munchausen_targets(None, None, BATCH, identity, cold)
    dqns = dqn.dqn_targets(None, None, BATCH, identity, cold)
    np.testing.assert_allclose(np.asarray(found), np.asarray(dqns), atol=1e-3)



def test_the_munchausen_term_is_the_clipped_log_policy_of_the_action_taken() -> None:
    """At τ = 0.03 the first transition's action is far from greedy (ln π = -33: clipped to l0 = -1), the second's is
    the greedy one (ln π = 0): the term is α τ l0 on the first and nothing on the second."""
    config = munchausen.Config()
    with_term = munchausen.munchausen_targets(None, None, BATCH, identity, config)
    without = munchausen.munchausen_targets(None, None, BATCH, identity, dataclasses.replace(config, scale=0.0))
    np.testing.assert_allclose(np.asarray(with_term - without), [0.9 * 0.03 * -1.0, 0.0], atol=1e-6)


@pytest.mark.parametrize(("field", "value", "allowed"), [
    ("tau", 0.0, "a finite number > 0"), ("scale", 1.5, "a number in [0, 1]"),
    ("log_floor", 0.0, "a finite number < 0"), ("double", True, "False only"),
])
def test_a_bad_setting_is_refused_naming_it(field: str, value: float, allowed: str) -> None:
    with pytest.raises(ConfigError) as refused:
        DeepConfig(algorithm="munchausen_dqn", env="CartPole-v1", hyperparameters={field: value})
    assert field in refused.value.field_name
    assert allowed in str(refused.value)


def test_it_is_one_record_of_the_registry_on_the_off_policy_side() -> None:
    method = DEEP_METHODS["munchausen_dqn"]
    assert method.module is munchausen
    assert method.policy == "off-policy"
    assert set(munchausen.PRESETS["default"]) == set(dqn.PRESETS["default"])


RECORDED = [[122.8, 135.8, 210.6, 123.0], [107.8, 225.0, 157.4, 159.8]]
"""Each seed's mean greedy return at each of four evaluations over 30,000 steps on CartPole (the default preset,
seeds 0 and 1 side by side); a uniformly random policy lasts about 22 steps."""


@pytest.mark.slow("trains networks on classic control")
def test_a_short_training_gives_its_recorded_returns() -> None:
    config = DeepConfig(algorithm="munchausen_dqn", env="CartPole-v1", seeds=(0, 1), vmap_width=2, eval_rounds=4,
                        eval_episodes=5, hyperparameters={"total_steps": 30_000})
    curves = run(config).evaluations.groupby(["seed", "round"])["return"].mean().unstack()
    assert curves.round(2).to_numpy().tolist() == RECORDED
