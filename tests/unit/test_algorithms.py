"""TD targets and updates worked out by hand, action selection, and exploration schedules."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chisquare

from rlcompare.algorithms.policies import (
    epsilon_greedy_action,
    greedy_action,
    greedy_action_random_ties,
    uniform_action,
)
from rlcompare.algorithms.schedules import constant_epsilon, linear_decay_epsilon
from rlcompare.algorithms.td import (
    QLearning,
    Rates,
    Sarsa,
    Transition,
    q_learning_target,
    q_learning_update,
    sarsa_target,
    sarsa_update,
)
from rlcompare.rng import stream_state

IMPLS = ["compiled", "py_func"]
N_DRAWS = 30_000  # seeded draws: the chi-square tests below are deterministic, not flaky


def _impl(name: str, fn):
    """The compiled dispatcher or the plain Python function it compiles."""
    return fn if name == "compiled" else fn.py_func


def _assert_uniform(counts: np.ndarray) -> None:
    """Counts consistent with a uniform distribution: chi-square test at p = 0.001."""
    assert chisquare(np.asarray(counts, dtype=np.float64)).pvalue > 1e-3, counts


# A tiny table: two states, three actions. The transition updated is s=0, a=0 -> s'=1, R=-1.
Q_TABLE = np.array([[2.0, 0.0, 0.0], [1.0, 3.0, -2.0]])


@pytest.fixture
def q() -> np.ndarray:
    return Q_TABLE.copy()


def _update(impl: str, update, rule: tuple, q: np.ndarray, *, reward: float = -1.0, gamma: float = 0.5,
            alpha: float = 0.25, terminal: bool = False, next_action: int = 0, now: int = 0, action: int = 0,
            epsilon: float = 0.0, rng: np.ndarray | None = None) -> np.ndarray:
    """One update of ``q(S, A)`` on the table ``q``, S = ``now`` and S' = ``1 - now`` (a table's state is its one
    active feature); returns the agent stream it was given (a fresh ``stream_state(0)`` unless one is passed)."""
    rng = stream_state(0) if rng is None else rng
    _impl(impl, update)(rule, q, np.zeros_like(q), Transition(now, action, reward, 1 - now, next_action, terminal),
                        Rates(alpha, gamma, epsilon), rng, np.empty(q.shape[1]), np.empty(q.shape[1]))
    return rng


@pytest.mark.parametrize("impl", IMPLS)
def test_q_learning_update_by_hand(q, impl):
    """Q(0,0)=2, max_a Q(1,a)=3, α=0.25, γ=0.5: target -1+0.5*3 = 0.5; Q(0,0) <- 2+0.25*(0.5-2) = 1.625."""
    target = _impl(impl, q_learning_target)(-1.0, q[1], 0.5, False)
    assert target == 0.5
    rng = _update(impl, q_learning_update, QLearning(False), q)
    assert q[0, 0] == 1.625
    q[0, 0] = Q_TABLE[0, 0]
    np.testing.assert_array_equal(q, Q_TABLE)  # nothing else moved
    np.testing.assert_array_equal(rng, stream_state(0))  # and nothing was drawn


@pytest.mark.parametrize("impl", IMPLS)
def test_q_learning_update_paper_parameters(q, impl):
    """α=0.05, γ=0.9: target -1+0.9*3 = 1.7; Q(0,0) <- 2+0.05*(1.7-2) = 1.985."""
    target = _impl(impl, q_learning_target)(-1.0, q[1], 0.9, False)
    assert target == pytest.approx(1.7, rel=1e-15)
    _update(impl, q_learning_update, QLearning(False), q, gamma=0.9, alpha=0.05)
    assert q[0, 0] == pytest.approx(1.985, rel=1e-15)


@pytest.mark.parametrize("impl", IMPLS)
@pytest.mark.parametrize(
    ("row", "expected"),
    [
        ([-3.0, -1.0, -2.0], -1.0 + 0.5 * -1.0),  # all negative: the max is -1, not 0 nor |-3|
        ([0.0, 0.0, 0.0], -1.0),
        ([4.0, -8.0, 4.0], -1.0 + 0.5 * 4.0),
        ([-2.0], -1.0 + 0.5 * -2.0),  # one action
    ],
)
def test_q_learning_target_uses_the_max(impl, row, expected):
    """``R + γ max_a Q(s', a)`` with R=-1, γ=0.5 on rows whose max is easy to get wrong."""
    assert _impl(impl, q_learning_target)(-1.0, np.array(row), 0.5, False) == expected


@pytest.mark.parametrize("impl", IMPLS)
@pytest.mark.parametrize("before", [True, False])
@pytest.mark.parametrize(
    ("next_action", "expected_target", "expected_q"),
    [
        (0, -0.5, 1.375),  # Q(1,0)=1: target -1+0.5*1 = -0.5; 2+0.25*(-0.5-2) = 1.375
        (1, 0.5, 1.625),  # the greedy action: the same as Q-learning
        (2, -2.0, 1.0),  # Q(1,2)=-2: target -1+0.5*(-2) = -2; 2+0.25*(-2-2) = 1.0
    ],
)
def test_sarsa_update_uses_the_action_taken(q, impl, before, next_action, expected_target, expected_q):
    """SARSA values s' by the action actually taken next, which need not be the greedy one. The loop draws it
    before the update in either order (``tests/engines/test_next_action.py`` works both through): the update itself
    draws nothing."""
    target = _impl(impl, sarsa_target)(-1.0, q[1, next_action], 0.5, False)
    assert target == expected_target
    rng = _update(impl, sarsa_update, Sarsa(before), q, next_action=next_action)
    assert q[0, 0] == expected_q
    np.testing.assert_array_equal(rng, stream_state(0))
    q_learning = _impl(impl, q_learning_target)(-1.0, q[1], 0.5, False)
    assert (target == q_learning) == (next_action == int(np.argmax(q[1])))


@pytest.mark.parametrize("impl", IMPLS)
def test_terminal_transitions_do_not_bootstrap(q, impl):
    """At a terminal s' both targets are R=-1 whatever Q(s') holds; Q(0,0) <- 2+0.25*(-1-2) = 1.25."""
    big = np.array([100.0, 200.0, 300.0])
    assert _impl(impl, q_learning_target)(-1.0, big, 0.5, True) == -1.0
    assert _impl(impl, sarsa_target)(-1.0, 300.0, 0.5, True) == -1.0
    assert _impl(impl, q_learning_target)(-1.0, big, 0.5, False) == -1.0 + 150.0
    for update, rule in ((q_learning_update, QLearning(False)), (sarsa_update, Sarsa(True)),
                         (sarsa_update, Sarsa(False))):
        table = q.copy()
        table[1] = big  # Q(s') large: bootstrapping would show
        rng = _update(impl, update, rule, table, next_action=2, epsilon=1.0, terminal=True)
        assert table[0, 0] == 1.25
        np.testing.assert_array_equal(rng, stream_state(0))  # no A' is drawn for a terminal s'


@pytest.mark.parametrize("impl", IMPLS)
def test_update_alpha_one_and_zero(q, impl):
    """α=1 replaces the value by the target; α=0 leaves it. S = 1, terminal, R = 7.5:
    the target is 7.5."""
    _update(impl, q_learning_update, QLearning(False), q, now=1, action=2, reward=7.5, terminal=True, alpha=1.0)
    assert q[1, 2] == 7.5
    _update(impl, q_learning_update, QLearning(False), q, now=1, action=1, reward=7.5, terminal=True, alpha=0.0)
    assert q[1, 1] == 3.0
    q[1, 2] = Q_TABLE[1, 2]
    np.testing.assert_array_equal(q, Q_TABLE)


# --- action selection ------------------------------------------------------------------------------


@pytest.mark.parametrize("impl", IMPLS)
@pytest.mark.parametrize(
    ("row", "expected"),
    [([1.0, 3.0, 3.0], 1), ([5.0, 5.0, 5.0], 0), ([-1.0, -2.0, -3.0], 0), ([-3.0, -2.0, -1.0], 2), ([0.0], 0)],
)
def test_greedy_takes_the_first_max(impl, row, expected):
    """Ties go to the lowest action, as ``np.argmax``."""
    assert _impl(impl, greedy_action)(np.array(row)) == expected


@pytest.mark.parametrize("impl", IMPLS)
def test_greedy_equals_argmax_on_random_rows(impl):
    """Small integer values make ties frequent."""
    rows = np.random.default_rng(0).integers(-2, 3, size=(500, 4)).astype(np.float64)
    got = [_impl(impl, greedy_action)(row) for row in rows]
    assert got == np.argmax(rows, axis=1).tolist()


TIE_ROWS = {
    "two-of-three": ([0.0, 2.0, 2.0], [1, 2]),
    "three-of-three": ([-1.0, -1.0, -1.0], [0, 1, 2]),
    "three-of-four": ([3.0, -1.0, 3.0, 3.0], [0, 2, 3]),
    "max-after-tied-lower": ([1.0, 1.0, 4.0, 0.0, 4.0], [2, 4]),
}


@pytest.mark.parametrize("impl", IMPLS)
@pytest.mark.parametrize(("row", "maxima"), list(TIE_ROWS.values()), ids=list(TIE_ROWS))
def test_random_ties_are_uniform_over_the_maxima(impl, row, maxima):
    """30,000 draws: only maximal actions, each about equally often (chi-square)."""
    fn = _impl(impl, greedy_action_random_ties)
    q_row = np.array(row)
    state = stream_state(17)
    picks = np.array([fn(q_row, state) for _ in range(N_DRAWS)])
    counts = np.bincount(picks, minlength=q_row.size)
    assert set(np.flatnonzero(counts)) == set(maxima)
    _assert_uniform(counts[maxima])


@pytest.mark.parametrize("impl", IMPLS)
def test_unique_max_draws_nothing(impl):
    """A unique maximum is returned without advancing the stream."""
    state = stream_state(3)
    before = state.copy()
    assert _impl(impl, greedy_action_random_ties)(np.array([0.0, -1.0, 0.5]), state) == 2
    np.testing.assert_array_equal(state, before)


def _epsilon_greedy_counts(impl: str, row, epsilon: float, seed: int = 5) -> np.ndarray:
    fn = _impl(impl, epsilon_greedy_action)
    q_row = np.array(row)
    state = stream_state(seed)
    picks = np.array([fn(q_row, epsilon, state) for _ in range(N_DRAWS)])
    return np.bincount(picks, minlength=q_row.size)


@pytest.mark.parametrize("impl", IMPLS)
def test_epsilon_zero_is_greedy(impl):
    """ε=0: always the greedy action; with ties, only (and each of) the tied maxima."""
    assert _epsilon_greedy_counts(impl, [0.0, 1.0, -1.0], 0.0).tolist() == [0, N_DRAWS, 0]
    counts = _epsilon_greedy_counts(impl, [2.0, 0.0, 2.0], 0.0)
    assert counts[1] == 0
    _assert_uniform(counts[[0, 2]])


@pytest.mark.parametrize("impl", IMPLS)
def test_epsilon_one_is_uniform(impl):
    """ε=1: uniform over all actions, the greedy one included."""
    counts = _epsilon_greedy_counts(impl, [0.0, 10.0, -1.0], 1.0)
    assert counts.sum() == N_DRAWS
    _assert_uniform(counts)


@pytest.mark.parametrize("impl", IMPLS)
def test_epsilon_half_frequencies(impl):
    """ε=0.5, unique max: greedy with probability 0.5 + 0.5/3 = 2/3, each other action 0.5/3 = 1/6."""
    counts = _epsilon_greedy_counts(impl, [0.0, 10.0, -1.0], 0.5)
    for action, p in enumerate([1 / 6, 2 / 3, 1 / 6]):
        bound = 5 * np.sqrt(p * (1 - p) / N_DRAWS)  # five binomial standard deviations
        assert abs(counts[action] / N_DRAWS - p) < bound, (action, counts)


@pytest.mark.parametrize("impl", IMPLS)
@pytest.mark.parametrize("row", [[0.0, 10.0, -1.0], [2.0, 0.0, 2.0], [0.0, 0.0, 0.0]])
def test_epsilon_greedy_draw_order(impl, row):
    """The draws, step by step, as a NumPy ``Generator`` on the same seed makes them: one double to
    decide exploring, then ``int(random() * n)`` for the uniform action or among the tied maxima."""
    fn = _impl(impl, epsilon_greedy_action)
    q_row = np.array(row)
    maxima = np.flatnonzero(q_row == q_row.max())
    state, generator = stream_state(8), np.random.Generator(np.random.PCG64(8))
    for _ in range(2000):
        if generator.random() < 0.3:
            expected = int(generator.random() * q_row.size)
        elif maxima.size == 1:
            expected = int(maxima[0])
        else:
            expected = int(maxima[int(generator.random() * maxima.size)])
        assert fn(q_row, 0.3, state) == expected
    assert (int(state[0]) << 64 | int(state[1])) == generator.bit_generator.state["state"]["state"]


@pytest.mark.parametrize("impl", IMPLS)
def test_uniform_action_covers_all_actions(impl):
    """The random baseline's action: uniform over ``n_actions``."""
    state = stream_state(21)
    fn = _impl(impl, uniform_action)
    counts = np.bincount([fn(3, state) for _ in range(N_DRAWS)], minlength=3)
    assert counts.size == 3
    _assert_uniform(counts)


# --- schedules ---------------------------------------------------------------------------------------


def test_constant_schedule():
    """The same ε for every episode, float64."""
    schedule = constant_epsilon(250, 0.5)
    assert schedule.shape == (250,)
    assert schedule.dtype == np.float64
    assert np.all(schedule == 0.5)


def test_linear_decay_endpoints_and_flat_tail():
    """ε=1 at episode 0, 0.5 halfway through the decay, 0 from episode 50 of 100 (fraction 0.5) on."""
    schedule = linear_decay_epsilon(100, 1.0, 0.0, 0.5)
    assert schedule.shape == (100,)
    assert schedule[0] == 1.0
    assert schedule[25] == 0.5
    assert schedule[49] == pytest.approx(1 / 50)
    assert np.all(schedule[50:] == 0.0)
    assert np.all(np.diff(schedule[:51]) < 0)  # strictly decreasing during the decay


@pytest.mark.parametrize(
    ("episodes", "start", "end", "fraction"),
    [(100, 1.0, 0.1, 0.5), (1000, 1.0, 0.01, 0.9), (7, 0.8, 0.2, 1.0), (50, 1.0, 0.05, 0.0), (30, 0.1, 0.6, 0.3)],
)
def test_linear_decay_is_monotone_and_bounded(episodes, start, end, fraction):
    """Monotone from ``start`` toward ``end``, never beyond either; ``end`` reached once the decay is over."""
    schedule = linear_decay_epsilon(episodes, start, end, fraction)
    assert schedule.shape == (episodes,)
    assert schedule[0] == start
    low, high = min(start, end), max(start, end)
    assert np.all((schedule >= low - 1e-12) & (schedule <= high + 1e-12))
    steps = np.diff(schedule) * np.sign(end - start)
    assert np.all(steps >= 0)
    decay_episodes = max(round(fraction * episodes), 1)
    if decay_episodes < episodes:
        assert schedule[decay_episodes:] == pytest.approx(end, abs=1e-12)
        assert np.all(schedule[decay_episodes:] == schedule[-1])
