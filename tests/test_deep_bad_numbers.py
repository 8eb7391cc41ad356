"""Bad numbers in a deep configuration: each is refused in one line naming the field and the allowed values (NaN,
infinities, zero sizes, seeds beyond 2**63), before anything is compiled or written."""

from __future__ import annotations

import math

import pytest

pytest.importorskip("jax")

from rlcompare.deep.run import DeepConfig
from rlcompare.experiment.config import ConfigError


@pytest.mark.parametrize(("algorithm", "settings", "field", "allowed"), [
    ("pqn_q_lambda", {"learning_rate": math.nan}, "learning_rate", "a positive finite number"),
    ("pqn_q_lambda", {"learning_rate": math.inf}, "learning_rate", "a positive finite number"),
    ("pqn_q_lambda", {"reward_scale": math.inf}, "reward_scale", "a positive finite number"),
    ("pqn_q_lambda", {"max_grad_norm": -1.0}, "max_grad_norm", "a positive finite number"),
    ("pqn_q_lambda", {"lam": math.nan}, "lam", "[0, 1]"),
    ("pqn_q_lambda", {"gamma": math.inf}, "gamma", "(0, 1]"),
    ("pqn_q_lambda", {"epsilon_end": -0.1}, "epsilon_end", "[0, 1]"),
    ("pqn_q_lambda", {"hidden": [0]}, "hidden", "positive layer widths"),
    ("pqn_q_lambda", {"n_envs": 0}, "n_envs", "a positive integer"),
    ("dqn", {"batch_size": 0}, "batch_size", "an integer >= 1"),
    ("dqn", {"learning_rate": math.inf}, "learning_rate", "a finite number > 0"),
    ("dqn", {"learning_rate": math.nan}, "learning_rate", "a finite number > 0"),
    ("dqn", {"max_grad_norm": math.inf}, "max_grad_norm", "a finite number >= 0"),
    ("dqn", {"hidden": [0]}, "hidden", "integers >= 1"),
    ("ppo", {"learning_rate": math.inf}, "learning_rate", "a finite number > 0"),
    ("ppo", {"ent_coef": math.nan}, "ent_coef", "a finite number >= 0"),
    ("ppo", {"batch_size": 0}, "batch_size", ""),
])
def test_a_bad_setting_is_refused_naming_it(algorithm: str, settings: dict, field: str, allowed: str) -> None:
    with pytest.raises(ConfigError) as refused:
        DeepConfig(algorithm=algorithm, env="CartPole-v1", hyperparameters=settings)
    assert refused.value.field_name == field
    assert allowed in str(refused.value)
    assert "\n" not in str(refused.value)


@pytest.mark.parametrize("seeds", [(2**63,), (-1,), (0, 0), (), (True,)])
def test_seeds_outside_0_to_2_63_are_refused(seeds: tuple) -> None:
    with pytest.raises(ConfigError, match=r"seeds: .*distinct integers in \[0, 2\*\*63\)"):
        DeepConfig(algorithm="pqn_q_lambda", env="CartPole-v1", seeds=seeds)
