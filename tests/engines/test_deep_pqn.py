"""PQN-style Q(λ), SARSA(λ) and Expected SARSA(λ): targets by hand, learning, determinism."""

import numpy as np
import pytest

pytest.importorskip("jax")

import jax
import jax.numpy as jnp

from rlcompare.deep import use_compilation_cache
from rlcompare.deep.classic import CARTPOLE
from rlcompare.deep.pqn import (
    PQNConfig,
    bootstrap_values,
    expected_value,
    lambda_returns,
    make_train,
    sarsa_actions,
)
from rlcompare.validation import ConfigError

GAMMA, LAM = 0.9, 0.5


@pytest.fixture(autouse=True, scope="module")
def _compilation_cache() -> None:
    """JAX's persistent compilation cache, as the deep engine's own entry points use it: the programs below compile
    once on a machine, not in every run of this file."""
    use_compilation_cache()


def returns_by_hand(rewards, terminated, truncated, values, gamma=GAMMA, lam=LAM):
    """The λ-return of each step of one environment, from its definition, forwards, one step at a time."""
    steps = len(rewards)
    out = []
    for t in range(steps):
        weight, total = 1.0, 0.0
        # G^λ_t = Σ_n (1-λ) λ^(n-1) G_t:t+n, the last return carrying the remaining weight
        for n in range(1, steps - t + 1):
            end = t + n - 1
            g_n = sum(gamma ** k * rewards[t + k] for k in range(n))
            stop = terminated[end] or truncated[end] or end == steps - 1
            bootstrap = 0.0 if terminated[end] else gamma ** n * values[end]
            if stop:
                total += weight * (g_n + bootstrap)
                break
            total += weight * (1 - lam) * (g_n + bootstrap)
            weight *= lam
        out.append(total)
    return np.array(out)


@pytest.mark.slow("trains networks on classic control")
@pytest.mark.parametrize(("terminated", "truncated"), [
    ([0, 0, 0, 0, 0], [0, 0, 0, 0, 0]),
    ([0, 1, 0, 0, 0], [0, 0, 0, 0, 0]),
    ([0, 0, 0, 0, 0], [0, 0, 1, 0, 0]),
    ([1, 0, 0, 0, 1], [0, 0, 1, 0, 0]),
])
def test_lambda_returns_equal_the_forward_view(terminated, truncated):
    rewards = np.array([1.0, -2.0, 0.5, 3.0, -1.0])
    values = np.array([10.0, 4.0, -3.0, 2.0, 7.0])
    got = lambda_returns(jnp.asarray(rewards)[:, None], jnp.asarray(terminated, bool)[:, None],
                         jnp.asarray(truncated, bool)[:, None], jnp.asarray(values)[:, None], GAMMA, LAM)
    expected = returns_by_hand(rewards, terminated, truncated, values)
    np.testing.assert_allclose(np.asarray(got)[:, 0], expected, rtol=1e-12)


def test_lambda_zero_is_the_one_step_target_of_algorithms_1_and_2():
    rewards = jnp.array([[1.0], [2.0], [3.0]])
    terminated = jnp.array([[False], [True], [False]])
    truncated = jnp.zeros((3, 1), bool)
    values = jnp.array([[5.0], [6.0], [7.0]])
    got = lambda_returns(rewards, terminated, truncated, values, GAMMA, 0.0)
    np.testing.assert_allclose(np.asarray(got)[:, 0], [1 + 0.9 * 5, 2.0, 3 + 0.9 * 7])


def test_the_three_targets_differ_only_in_the_bootstrap():
    q_next = jnp.array([[1.0, 4.0, 2.0], [3.0, 0.0, -1.0]])
    taken = jnp.array([2, 1])
    epsilon = jnp.asarray(0.3)
    assert np.asarray(bootstrap_values("max", q_next, taken, epsilon)).tolist() == [4.0, 3.0]
    assert np.asarray(bootstrap_values("sample", q_next, taken, epsilon)).tolist() == [2.0, 0.0]
    # ε-greedy over 3 actions: 0.1 each, plus 0.7 on the greedy one
    np.testing.assert_allclose(np.asarray(bootstrap_values("expected", q_next, taken, epsilon)),
                               [0.1 * 7 + 0.7 * 4, 0.1 * 2 + 0.7 * 3])
    np.testing.assert_allclose(np.asarray(expected_value(q_next, jnp.asarray(0.0))), [4.0, 3.0])


def test_sarsa_bootstraps_from_the_next_action_taken_in_the_same_episode():
    actions = jnp.array([[0], [1], [2], [0]])
    done = jnp.array([[False], [True], [False], [False]])
    drawn = jnp.array([[9], [8], [7], [6]])
    carried = jnp.array([5])
    got = sarsa_actions(actions, done, drawn, carried)
    assert np.asarray(got)[:, 0].tolist() == [1, 8, 0, 5]


@pytest.mark.parametrize(("field", "value"), [("target", "greedy"), ("lam", 1.5), ("gamma", 0.0),
                                              ("next_action", "soon"), ("n_minibatches", 3), ("learning_rate", -1.0)])
def test_bad_hyperparameters_name_the_field(field, value):
    with pytest.raises(ConfigError, match=field):
        PQNConfig(**{field: value})


SMALL = PQNConfig(total_steps=40 * 16 * 32, n_envs=16, n_steps=32, n_epochs=2, n_minibatches=4, hidden=(32, 32),
                  learning_rate=3e-3, anneal_lr=False, decay_fraction=0.5)


@pytest.fixture(scope="module")
def trained():
    """Q(λ) and SARSA(λ) on CartPole, three seeds side by side, and the first seed with other neighbours."""
    outputs = {}
    for target in ("max", "sample"):
        config = PQNConfig(**{**SMALL.__dict__, "target": target})
        train = jax.jit(jax.vmap(make_train(config, CARTPOLE, rounds=4, eval_episodes=4)))
        outputs[target] = train(jnp.stack([jax.random.key(s) for s in (0, 1, 2)]))
        if target == "max":
            outputs["neighbours"] = train(jnp.stack([jax.random.key(s) for s in (0, 7, 9)]))
    return outputs


@pytest.mark.slow("trains networks on classic control")
def test_q_lambda_and_sarsa_lambda_learn_cartpole(trained):
    """The last round's four greedy episodes, summed per seed, as recorded from these seeds (integer step counts,
    the same bits on every x86-64 CPU as the golden records): from 72 to 208 steps an episode, where a random
    policy lasts about 22."""
    recorded = {"max": [783, 289, 830], "sample": [417, 458, 370]}
    for target, sums in recorded.items():
        np.testing.assert_array_equal(np.asarray(trained[target].eval_returns)[:, -1].sum(axis=-1), sums,
                                      err_msg=target)
        assert min(sums) / 4 > 3 * 22


@pytest.mark.slow("trains networks on classic control")
def test_a_seed_does_not_depend_on_the_seeds_beside_it(trained):
    alone, beside = trained["max"], trained["neighbours"]
    assert np.array_equal(np.asarray(alone.eval_returns)[0], np.asarray(beside.eval_returns)[0])
    for a, b in zip(jax.tree.leaves(alone.params), jax.tree.leaves(beside.params), strict=True):
        assert np.array_equal(np.asarray(a)[0], np.asarray(b)[0])


@pytest.mark.slow("trains networks on classic control")
def test_training_episodes_are_recorded_as_they_end(trained):
    finished = trained["max"].finished
    done = np.asarray(finished.done)
    returns, lengths = np.asarray(finished.returns)[done], np.asarray(finished.lengths)[done]
    assert done.sum() > 50
    np.testing.assert_array_equal(returns, lengths)  # CartPole pays 1 per step
    assert lengths.max() <= CARTPOLE.max_steps


@pytest.mark.parametrize("cut", [[0, 0, 0, 0, 0], [1, 0, 0, 0, 0], [0, 1, 0, 1, 0], [1, 1, 1, 1, 1]])
def test_watkins_cuts_the_trace_where_the_next_action_was_not_greedy(cut):
    """Sutton and Barto 12.10: after an exploratory action the return bootstraps from max Q alone, as at a
    time-limit cut; nothing else changes."""
    rewards = np.array([1.0, -2.0, 0.5, 3.0, -1.0])
    values = np.array([10.0, 4.0, -3.0, 2.0, 7.0])
    terminated = np.array([0, 0, 0, 0, 1], bool)
    got = lambda_returns(jnp.asarray(rewards)[:, None], jnp.asarray(terminated)[:, None], jnp.zeros((5, 1), bool),
                         jnp.asarray(values)[:, None], GAMMA, LAM, jnp.asarray(cut, bool)[:, None])
    expected = returns_by_hand(rewards, terminated, np.asarray(cut, bool), values)
    np.testing.assert_allclose(np.asarray(got)[:, 0], expected, rtol=1e-12)
    if cut == [1, 0, 0, 0, 0]:
        assert float(got[0, 0]) == pytest.approx(1.0 + GAMMA * 10.0)  # by hand: r_0 + γ max Q(s_1) alone


def test_peng_and_watkins_agree_where_every_action_taken_was_greedy_and_at_lambda_zero():
    rewards, values = jnp.array([[1.0], [2.0], [3.0]]), jnp.array([[5.0], [6.0], [7.0]])
    terminated, truncated = jnp.zeros((3, 1), bool), jnp.zeros((3, 1), bool)
    greedy = jnp.zeros((3, 1), bool)  # no step cut: every next action greedy
    np.testing.assert_array_equal(lambda_returns(rewards, terminated, truncated, values, GAMMA, LAM),
                                  lambda_returns(rewards, terminated, truncated, values, GAMMA, LAM, greedy))
    np.testing.assert_array_equal(lambda_returns(rewards, terminated, truncated, values, GAMMA, 0.0),
                                  lambda_returns(rewards, terminated, truncated, values, GAMMA, 0.0, ~greedy))
