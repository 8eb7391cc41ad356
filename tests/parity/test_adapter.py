"""The Gymnasium adapter: the same engine stepping ``gymnasium.make(env_id)`` through Gymnasium's own API."""

from __future__ import annotations

from dataclasses import replace

import numba
import numpy as np
import pytest

from rlcompare import ConfigError, ExperimentConfig, run
from rlcompare.stats.intervals import interval
from rlcompare.tabular.state import Records

PORTED = ["MountainCar-v0", "CartPole-v1", "Acrobot-v1", "CliffWalking-v1", "FrozenLake-v1", "Taxi-v4"]


def _assert_same_records(a: Records, b: Records) -> None:
    for name in Records._fields:
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


@pytest.mark.slow("steps Gymnasium's environments at Python speed")
@pytest.mark.parametrize("env", PORTED)
def test_adapter_gives_each_ports_results_bit_for_bit(env: str) -> None:
    """Each port and Gymnasium's own environment, stepped by the same engine from the same streams, give
    equal records: training and evaluation returns, lengths, terminations, tables and visits."""
    config = ExperimentConfig(env=env, algorithm="q_learning", seeds=(0, 1, 2), episodes=24, eval_every=8,
                              eval_episodes=2)
    port, adapter = run(config), run(replace(config, adapter=True))
    assert port.meta["stepped_by"] == "compiled port"
    assert adapter.meta["stepped_by"] == "Gymnasium adapter (Python speed)"
    _assert_same_records(port.records, adapter.records)


@pytest.mark.parametrize("algorithm", ["random", "sarsa", "n_step_sarsa", "sarsa_lambda", "reinforce_baseline"])
def test_every_episode_loop_through_the_adapter_equals_the_port(algorithm: str) -> None:
    """Every family's episode loop (the baseline, one-step with A' drawn before the update, where Q-Learning's above
    draws it after, n-step, traces, policy gradient), on tiles where it is a function approximator's: the methods of
    a family differ only in their update, which never reaches the environment. The baseline's and REINFORCE's
    evaluations draw their actions from their own stream, so they match too."""
    features = "tiles" if algorithm in ("sarsa_lambda", "reinforce_baseline") else "grid"
    config = ExperimentConfig(env="MountainCar-v0", algorithm=algorithm, features=features, seeds=(3, 4),
                              episodes=4, eval_every=2, eval_episodes=1, alpha=0.05)
    _assert_same_records(run(config).records, run(replace(config, adapter=True)).records)


@pytest.mark.slow("steps Gymnasium's environments at Python speed")
def test_adapter_on_mountain_car_learns_as_the_port_over_ten_seeds() -> None:
    """SARSA through Gymnasium equals the compiled port in the paper's setting on 10 seeds, so its greedy
    success and mean returns lie inside each other's intervals (they are the same numbers)."""
    config = ExperimentConfig(algorithm="sarsa", schedule="constant", seeds=tuple(range(10)), episodes=12,
                              eval_every=6, eval_episodes=1)
    port, adapter = run(config), run(replace(config, adapter=True))
    _assert_same_records(port.records, adapter.records)
    for metric in (lambda r: r.records.returns.mean(axis=1), lambda r: r.records.eval_terminated[:, -1, 0] * 1.0):
        a, b = interval(metric(port)), interval(metric(adapter))
        assert a.low <= b.value <= a.high
        assert b.low <= a.value <= b.high


@pytest.mark.slow("steps Gymnasium's environments at Python speed")
def test_adapter_results_do_not_depend_on_the_thread_count() -> None:
    """Q-Learning on the adapter's tables: the compiled program of test_adapter_gives_each_ports_results_bit_for_bit
    (CliffWalking-v1), not one of its own."""
    config = ExperimentConfig(env="CliffWalking-v1", adapter=True, algorithm="q_learning", seeds=(0, 1, 2, 3),
                              episodes=20, eval_every=10, eval_episodes=1)
    previous = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = run(config)
        numba.set_num_threads(2)
        two = run(config)
    finally:
        numba.set_num_threads(previous)
    _assert_same_records(one.records, two.records)


@pytest.mark.slow("steps Gymnasium's environments at Python speed")
def test_q_learning_learns_taxi_and_frozen_lake_through_the_adapter() -> None:
    """Gymnasium's Taxi-v4 and the slippery FrozenLake-v1, stepped through Gymnasium: the greedy policy
    delivers the passenger from (nearly) every start, and reaches the goal of the lake about as often as the
    optimal policy does (74%)."""
    taxi = run(ExperimentConfig(env="Taxi-v4", adapter=True, algorithm="q_learning", schedule="constant",
                                epsilon=0.1, alpha=0.5, gamma=0.99, seeds=(0, 1), episodes=800, eval_every=800,
                                eval_episodes=20))
    # Recorded from these seeds, compared exactly (Gymnasium's toy text holds no floating point): 19 of each seed's
    # 20 greedy episodes deliver, scoring -3.2 and -1.7 an episode, where the random baseline scores about -770.
    np.testing.assert_array_equal(taxi.records.eval_terminated[:, -1].sum(axis=1), [19, 19])
    np.testing.assert_array_equal(taxi.records.eval_returns[:, -1].sum(axis=1), [-63, -34])
    lake = run(ExperimentConfig(env="FrozenLake-v1", adapter=True, algorithm="q_learning", alpha=0.1, gamma=0.99,
                                seeds=(0,), episodes=2000, eval_every=2000, eval_episodes=200))
    np.testing.assert_array_equal(lake.records.eval_returns[:, -1].sum(axis=1), [143])  # 72% of 200, optimal 74%


@pytest.mark.slow("steps Gymnasium's environments at Python speed")
@pytest.mark.filterwarnings("ignore:.*out of date:DeprecationWarning")
def test_environments_without_a_port_run_through_the_adapter() -> None:
    """A Discrete-observation environment with no port (CliffWalkingSlippery-v1, one feature per state) and a
    Box one (CartPole-v0, over bounds the user gives) run, reproducibly, with Gymnasium's defaults (the cliff
    registers no limit: 1000)."""
    cliff = ExperimentConfig(env="CliffWalkingSlippery-v1", algorithm="q_learning", seeds=(0, 1), episodes=30,
                             eval_every=0)
    assert not cliff.environment.is_ported
    assert (cliff.max_steps, cliff.environment.n_states) == (1000, 48)
    first, again = run(cliff), run(cliff)
    _assert_same_records(first.records, again.records)
    assert first.records.visits.shape == (2, 48)
    assert np.all(first.records.lengths <= 1000)
    cartpole = ExperimentConfig(env="CartPole-v0", algorithm="sarsa", seeds=(0,), episodes=20, eval_every=0,
                                bounds=((-2.4, 2.4), (-3.0, 3.0), (-0.21, 0.21), (-3.5, 3.5)), bins=(1, 1, 6, 12))
    results = run(cartpole)
    assert cartpole.max_steps == 200
    assert results.records.visits.shape == (1, 72)
    assert np.all(results.records.returns == results.records.lengths)  # +1 per step


@pytest.mark.parametrize(("env", "field", "reason"), [
    ("Pendulum-v1", "env", "actions Box"),
    ("MountainCarContinuous-v0", "env", "actions Box"),
    ("Blackjack-v1", "env", "observations Tuple"),
    ("NoSuchEnv-v0", "env", "not a registered Gymnasium environment"),
    ("MountainCar-book", "env", "not a registered Gymnasium environment"),
])
def test_environments_the_adapter_cannot_run_are_named_with_the_reason(env: str, field: str, reason: str) -> None:
    with pytest.raises(ConfigError, match=reason) as caught:
        ExperimentConfig(env=env, adapter=env == "MountainCar-book")
    assert caught.value.field_name == field
    assert "registered Gymnasium environment with Discrete actions" in caught.value.allowed


@pytest.mark.filterwarnings("ignore:.*out of date:DeprecationWarning")
def test_unbounded_observations_need_bounds() -> None:
    with pytest.raises(ConfigError, match=r"unbounded in dimensions \[1, 3\]") as caught:
        ExperimentConfig(env="CartPole-v0")
    assert caught.value.field_name == "bounds"
    with pytest.raises(ConfigError, match="4 pairs of finite numbers") as caught:
        ExperimentConfig(env="CartPole-v0", bounds=((-1.0, 1.0),))
    assert caught.value.field_name == "bounds"
