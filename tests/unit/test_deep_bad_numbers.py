"""Bad numbers in a deep configuration: each is refused in one line naming the field and the allowed values (NaN,
infinities, zero sizes, seeds beyond 2**63), before anything is compiled or written."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("jax")

from helpers import invoke

from rlcompare.deep.config import DeepConfig
from rlcompare.validation import ConfigError


@pytest.mark.parametrize(("algorithm", "settings", "field", "allowed"), [
    ("pqn_q_lambda", {"learning_rate": math.nan}, "learning_rate", "a finite number > 0"),
    ("pqn_q_lambda", {"learning_rate": math.inf}, "learning_rate", "a finite number > 0"),
    ("pqn_q_lambda", {"reward_scale": math.inf}, "reward_scale", "a finite number > 0"),
    ("pqn_q_lambda", {"max_grad_norm": -1.0}, "max_grad_norm", "a finite number > 0"),
    ("pqn_q_lambda", {"lam": math.nan}, "lam", "[0, 1]"),
    ("pqn_q_lambda", {"gamma": math.inf}, "gamma", "(0, 1]"),
    ("pqn_q_lambda", {"epsilon_end": -0.1}, "epsilon_end", "[0, 1]"),
    ("pqn_q_lambda", {"hidden": [0]}, "hidden", "each an integer >= 1"),
    ("pqn_q_lambda", {"n_envs": 0}, "n_envs", "an integer >= 1"),
    ("dqn", {"batch_size": 0}, "batch_size", "an integer >= 1"),
    ("dqn", {"learning_rate": math.inf}, "learning_rate", "a finite number > 0"),
    ("dqn", {"learning_rate": math.nan}, "learning_rate", "a finite number > 0"),
    ("dqn", {"max_grad_norm": math.inf}, "max_grad_norm", "a finite number >= 0"),
    ("dqn", {"hidden": [0]}, "hidden", "each an integer >= 1"),
    ("ppo", {"learning_rate": math.inf}, "learning_rate", "a finite number > 0"),
    ("ppo", {"ent_coef": math.nan}, "ent_coef", "a finite number >= 0"),
    ("ppo", {"batch_size": 0}, "batch_size", ""),
    ("ppo", {"batch_size": 7}, "batch_size", "dividing n_envs * n_steps"),
    ("dqn", {"buffer_size": 0}, "buffer_size", "an integer >= 1"),
])
def test_a_bad_setting_is_refused_naming_it(algorithm: str, settings: dict, field: str, allowed: str) -> None:
    with pytest.raises(ConfigError) as refused:
        DeepConfig(algorithm=algorithm, env="CartPole-v1", hyperparameters=settings)
    assert refused.value.field_name == field
    assert allowed in str(refused.value)
    assert "\n" not in str(refused.value)


@pytest.mark.parametrize(("algorithm", "settings"), [
    ("pqn_q_lambda", {"lam": np.float32(0.5), "n_envs": np.int64(16), "anneal_lr": np.bool_(False)}),
    ("dqn", {"learning_rate": np.float64(1e-3), "batch_size": np.int32(64)}),
    ("ppo", {"gamma": np.float32(0.98), "n_epochs": np.int16(4)}),
])
def test_numpy_scalars_are_settings_like_any_other_and_kept_as_python_values(algorithm: str, settings: dict) -> None:
    """Every config takes NumPy's scalars for what they hold (one rule, :mod:`rlcompare.validation`), and stores
    Python's, so that ``config.json`` and a configuration's hash read them alike."""
    plain = {name: value.item() for name, value in settings.items()}
    given = DeepConfig(algorithm=algorithm, env="CartPole-v1", hyperparameters=settings).method_config()
    expected = DeepConfig(algorithm=algorithm, env="CartPole-v1", hyperparameters=plain).method_config()
    assert given == expected
    assert all(type(getattr(given, name)) is type(value) for name, value in plain.items())


@pytest.mark.parametrize("seeds", [(2**63,), (-1,), (0, 0), (), (True,)])
def test_seeds_outside_0_to_2_63_are_refused(seeds: tuple) -> None:
    with pytest.raises(ConfigError, match=r"seeds: .*distinct integers in \[0, 2\*\*63\)"):
        DeepConfig(algorithm="pqn_q_lambda", env="CartPole-v1", seeds=seeds)


@pytest.fixture(scope="module")
def deep_run(tmp_path_factory: pytest.TempPathFactory):
    from rlcompare.experiment.runner import run

    out = tmp_path_factory.mktemp("deep") / "run"
    run(DeepConfig(algorithm="pqn_q_lambda", env="CartPole-v1", hyperparameters={"total_steps": 16 * 128 * 2},
                   seeds=(0,), eval_rounds=2, eval_episodes=2, vmap_width=1), out=out)
    return out


@pytest.mark.slow("trains a deep run to damage")
@pytest.mark.parametrize("name", ["params.npz", "episodes.parquet", "evaluations.parquet"])
def test_a_tampered_file_of_a_deep_run_is_refused_naming_it(deep_run, name: str, tmp_path) -> None:
    import shutil

    from rlcompare.experiment import store
    from rlcompare.experiment.engines import load_agent, load_run

    copy = tmp_path / "run"
    shutil.copytree(deep_run, copy)
    data = bytearray((copy / name).read_bytes())
    data[len(data) // 2] ^= 0xFF  # one byte flipped
    (copy / name).write_bytes(bytes(data))
    for load in (load_run, load_agent):
        with pytest.raises(store.StoreError, match=rf"{name}: does not belong to this run"):
            load(copy)
    result = invoke("report", str(copy), columns=300)
    assert result.exit_code == 2
    assert f"{name}: does not belong to this run" in result.output
    assert "Traceback" not in result.output


@pytest.mark.parametrize(("settings", "field", "allowed"), [
    ({"reward_scale": 1e300}, "hyperparameters.reward_scale", "float32"),
    ({"learning_rate": 1e39}, "hyperparameters.learning_rate", "float32"),
    ({"n_envs": 2**31}, "hyperparameters.n_envs", "int32"),
    ({"hidden": [2**40]}, "hyperparameters.hidden", "int32"),
    ({"total_steps": 99999999999999999999}, "hyperparameters.total_steps", "int32"),
    ({"total_steps": 2**31 - 1}, "total_steps", "records fit in memory"),
])
def test_a_setting_the_engine_cannot_represent_is_refused_before_tracing(settings: dict, field: str, allowed: str
                                                                         ) -> None:
    with pytest.raises(ConfigError) as refused:
        DeepConfig(algorithm="pqn_q_lambda", env="CartPole-v1", hyperparameters=settings, seeds=tuple(range(10**3)))
    assert refused.value.field_name == field
    assert allowed in str(refused.value)


def test_an_unknown_hyperparameter_is_an_unknown_key_naming_the_fields() -> None:
    with pytest.raises(ConfigError, match=r"^hyperparameters.learning_rat: unknown key; allowed: the fields of "
                                          r"PQNConfig: .*learning_rate"):
        DeepConfig(algorithm="pqn_q_lambda", env="CartPole-v1", hyperparameters={"learning_rat": 0.1})
