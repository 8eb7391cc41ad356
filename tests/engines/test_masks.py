"""Legal-move masks: an illegal move holds −∞ in every table, so no policy picks it and no target reads it.

1. the uniform legal choice, ε-greedy and greedy on rows with −∞;
2. each one-step update on a two-state table whose next state has an illegal move: the max or expectation over the
   legal moves, worked out by hand;
3. the compiled engine on a masked chain, every method that acts on a masked table: no illegal move taken, no
   illegal weight touched, no NaN.

Tables without a mask keep their results bit for bit: ``test_golden.py``.
"""

from __future__ import annotations

import numpy as np
import pytest

from rlcompare.algorithms.policies import (
    epsilon_greedy_action,
    greedy_action,
    greedy_action_random_ties,
    legal_count,
    uniform_legal_action,
)
from rlcompare.algorithms.registry import METHODS
from rlcompare.algorithms.schedules import linear_decay_epsilon
from rlcompare.algorithms.td import (
    DoubleExpectedSarsa,
    DoubleQLearning,
    ExpectedSarsa,
    QLearning,
    Rates,
    Sarsa,
    Transition,
    double_expected_sarsa_update,
    double_q_update,
    expected_sarsa_update,
    expected_value,
    q_learning_update,
    sarsa_update,
)
from rlcompare.envs.features import OneHot
from rlcompare.envs.table import make_table_env
from rlcompare.rng import next_below, next_double, stream_state
from rlcompare.tabular.runs import train_runs
from rlcompare.tabular.state import Settings, allocate_records, initial_state

IMPLS = ["compiled", "py_func"]
NEG_INF = -np.inf
N_DRAWS = 20_000


def _impl(name: str, fn):
    """The compiled dispatcher or the plain Python function it compiles."""
    return fn if name == "compiled" else fn.py_func


# --- 1. choosing among the legal moves --------------------------------------------------------------------


@pytest.mark.parametrize("impl", IMPLS)
@pytest.mark.parametrize(("row", "count"), [([NEG_INF, 0.0, NEG_INF, 3.0, -1.0], 3), ([1.0, 2.0], 2),
                                            ([NEG_INF, NEG_INF, -7.0], 1), ([NEG_INF, NEG_INF], 0)])
def test_legal_count(impl, row, count):
    assert _impl(impl, legal_count)(np.array(row)) == count


@pytest.mark.parametrize("impl", IMPLS)
@pytest.mark.parametrize("row", [[NEG_INF, 0.0, NEG_INF, 3.0, -1.0], [5.0, NEG_INF, NEG_INF, -2.0],
                                 [NEG_INF, NEG_INF, NEG_INF, 0.0]])
def test_uniform_legal_action_is_uniform_over_the_legal_moves(impl, row):
    """20,000 draws: only legal moves, each within two percentage points of 1/k (about six binomial standard
    deviations for k = 3); and each draw is the ``next_below(k)``-th legal move of an identical stream."""
    fn = _impl(impl, uniform_legal_action)
    q_row = np.array(row)
    legal = np.flatnonzero(q_row != NEG_INF)
    state, twin = stream_state(13), stream_state(13)
    picks = np.array([fn(q_row, state) for _ in range(N_DRAWS)])
    expected = np.array([legal[next_below(twin, legal.size)] for _ in range(N_DRAWS)])
    np.testing.assert_array_equal(picks, expected)
    np.testing.assert_array_equal(state, twin)
    counts = np.bincount(picks, minlength=q_row.size)
    assert counts[q_row == NEG_INF].sum() == 0, counts
    np.testing.assert_allclose(counts[legal] / N_DRAWS, 1 / legal.size, atol=0.02)


@pytest.mark.parametrize("impl", IMPLS)
@pytest.mark.parametrize("row", [[0.0, 0.0, 0.0], [-3.0, 10.0, 2.5, -1.0], [7.0]])
def test_uniform_legal_action_with_every_move_legal_is_next_below(impl, row):
    """With no −∞ the draw is bit for bit the old ``uniform_action``: ``next_below(rng, n)``, the stream left where
    it leaves it."""
    fn = _impl(impl, uniform_legal_action)
    q_row = np.array(row)
    state, twin = stream_state(21), stream_state(21)
    for _ in range(2000):
        assert fn(q_row, state) == next_below(twin, q_row.size)
    np.testing.assert_array_equal(state, twin)


@pytest.mark.parametrize("impl", IMPLS)
@pytest.mark.parametrize("row", [[NEG_INF, -3.0, -1.0, NEG_INF, -2.0], [NEG_INF, 10.0, NEG_INF]])
def test_epsilon_one_never_picks_an_illegal_move(impl, row):
    """ε = 1 explores on every step: every legal move comes up, no illegal one, each legal one about 1/k."""
    fn = _impl(impl, epsilon_greedy_action)
    q_row = np.array(row)
    state = stream_state(5)
    counts = np.bincount([fn(q_row, 1.0, state, True) for _ in range(N_DRAWS)], minlength=q_row.size)
    legal = q_row != NEG_INF
    assert counts[~legal].sum() == 0, counts
    np.testing.assert_allclose(counts[legal] / N_DRAWS, 1 / legal.sum(), atol=0.02)
    unmasked = np.bincount([fn(q_row, 1.0, state) for _ in range(2000)], minlength=q_row.size)
    assert unmasked[~legal].sum() > 0  # without the mask flag, the plain draw over every action


@pytest.mark.parametrize("impl", IMPLS)
def test_epsilon_zero_is_the_greedy_legal_move(impl):
    """ε = 0, −∞ at index 0 (the first maximum a scan starts from) and every legal value negative: the greedy legal
    move, always; with two tied legal maxima, each of them and nothing else. ``greedy_action`` (evaluation) takes
    the first legal maximum."""
    fn = _impl(impl, epsilon_greedy_action)
    state = stream_state(6)
    row = np.array([NEG_INF, -3.0, -1.0, -2.0])
    assert {fn(row, 0.0, state, True) for _ in range(500)} == {2}
    tied = np.array([NEG_INF, -1.0, NEG_INF, -1.0, -4.0])
    counts = np.bincount([fn(tied, 0.0, state, True) for _ in range(4000)], minlength=tied.size)
    assert counts[[0, 2, 4]].sum() == 0, counts
    assert counts[1] > 1800, counts
    assert counts[3] > 1800, counts
    ties = _impl(impl, greedy_action_random_ties)
    assert {ties(np.array([NEG_INF, NEG_INF, -5.0]), state) for _ in range(50)} == {2}
    greedy = _impl(impl, greedy_action)
    assert greedy(row) == 2
    assert greedy(tied) == 1
    assert greedy(np.array([NEG_INF, NEG_INF, -5.0])) == 2


@pytest.mark.parametrize("impl", IMPLS)
@pytest.mark.parametrize("row", [[NEG_INF, -3.0, -1.0, NEG_INF, -2.0], [-1.0, NEG_INF, -1.0, -9.0]])
def test_epsilon_greedy_draw_order_with_a_mask(impl, row):
    """Step by step as NumPy's ``Generator`` on the same seed: one double to decide exploring, then
    ``legal[int(random() * k)]`` to explore, or ``maxima[int(random() * ties)]`` among tied maxima."""
    fn = _impl(impl, epsilon_greedy_action)
    q_row = np.array(row)
    legal = np.flatnonzero(q_row != NEG_INF)
    maxima = np.flatnonzero(q_row == q_row.max())
    state, generator = stream_state(8), np.random.Generator(np.random.PCG64(8))
    for _ in range(2000):
        if generator.random() < 0.3:
            expected = int(legal[int(generator.random() * legal.size)])
        elif maxima.size == 1:
            expected = int(maxima[0])
        else:
            expected = int(maxima[int(generator.random() * maxima.size)])
        assert fn(q_row, 0.3, state, True) == expected
    assert (int(state[0]) << 64 | int(state[1])) == generator.bit_generator.state["state"]["state"]


# --- 2. one-step updates: targets over the legal moves ------------------------------------------------------
# The transition updated: S = 0, A = 2 -> S' = 1, R = -1, α = 0.5, γ = 0.9. State 0 has an illegal move (index 1),
# and so has S' (index 0); every legal value of S' is negative, so a max or an expectation that counted the
# illegal move as anything but absent (0, or ε/4 of the weight) would differ.

ALPHA, GAMMA, REWARD = 0.5, 0.9, -1.0
Q1 = np.array([[1.0, NEG_INF, 0.5, 2.0],
               [NEG_INF, -3.0, -1.0, -2.0]])
Q2 = np.array([[0.25, NEG_INF, -0.75, 1.0],
               [NEG_INF, -5.0, -4.0, 0.5]])


def _update(impl: str, update, rule: tuple, w: np.ndarray, w2: np.ndarray, *, epsilon: float = 0.0,
            next_action: int = 0, seed: int = 0) -> np.ndarray:
    """One update of ``q(0, 2)`` toward S' = 1 (not terminal); the agent stream it drew from."""
    rng = stream_state(seed)
    _impl(impl, update)(rule, w, w2, Transition(0, 2, REWARD, 1, next_action, False), Rates(ALPHA, GAMMA, epsilon),
                        rng, np.empty(w.shape[1]), np.empty(w.shape[1]))
    return rng


def _only_changed(after: np.ndarray, before: np.ndarray, expected: float) -> None:
    """``after`` is ``before`` with ``q(0, 2)`` replaced by ``expected``: every −∞ is still −∞, nothing is NaN."""
    assert after[0, 2] == pytest.approx(expected, rel=1e-13, abs=1e-15)
    reference = before.copy()
    reference[0, 2] = after[0, 2]
    np.testing.assert_array_equal(after, reference)
    assert not np.isnan(after).any()


@pytest.mark.parametrize("impl", IMPLS)
def test_q_learning_update_takes_the_legal_max(impl):
    """max over the legal moves of S' = -1 (an illegal move counted as 0 would give 0):
    target = -1 + 0.9 * -1 = -1.9; q(0, 2) = 0.5 + 0.5 * (-1.9 - 0.5) = -0.7."""
    w, w2 = Q1.copy(), Q2.copy()
    legal_max = -1.0
    expected = 0.5 + ALPHA * (REWARD + GAMMA * legal_max - 0.5)
    assert expected == pytest.approx(-0.7)
    rng = _update(impl, q_learning_update, QLearning(False), w, w2)
    _only_changed(w, Q1, expected)
    np.testing.assert_array_equal(w2, Q2)
    np.testing.assert_array_equal(rng, stream_state(0))


@pytest.mark.parametrize("impl", IMPLS)
@pytest.mark.parametrize("next_action", [1, 2, 3])
def test_sarsa_update_takes_the_legal_next_move(impl, next_action):
    """q(1, A') for the legal A' drawn: -1 + 0.9 * q(1, A'), and nothing drawn."""
    w, w2 = Q1.copy(), Q2.copy()
    expected = 0.5 + ALPHA * (REWARD + GAMMA * Q1[1, next_action] - 0.5)
    rng = _update(impl, sarsa_update, Sarsa(True), w, w2, next_action=next_action)
    _only_changed(w, Q1, expected)
    np.testing.assert_array_equal(rng, stream_state(0))


@pytest.mark.parametrize("impl", IMPLS)
@pytest.mark.parametrize(("target_epsilon", "behaviour_epsilon", "expectation"), [
    # ε = 0.3 over the k = 3 legal moves: 0.1 each, 0.7 more to the greedy (-1):
    # 0.1 * -3 + 0.8 * -1 + 0.1 * -2 = -1.3 (over four moves: 0.075 * -3 + 0.775 * -1 + 0.075 * -2 = -1.15)
    (-1.0, 0.3, 0.1 * -3.0 + (0.1 + 0.7) * -1.0 + 0.1 * -2.0),
    (0.3, 0.9, 0.1 * -3.0 + (0.1 + 0.7) * -1.0 + 0.1 * -2.0),  # the rule's own ε, not the behaviour's
    # ε = 1: the plain mean of the legal moves, (-3 - 1 - 2) / 3 = -2 (over four moves: -1.5)
    (1.0, 0.0, (-3.0 + -1.0 + -2.0) / 3),
    (0.0, 0.5, -1.0),  # ε = 0: the legal max, Q-Learning's target
])
def test_expected_sarsa_update_expects_over_the_legal_moves(impl, target_epsilon, behaviour_epsilon, expectation):
    w, w2 = Q1.copy(), Q2.copy()
    expected = 0.5 + ALPHA * (REWARD + GAMMA * expectation - 0.5)
    rng = _update(impl, expected_sarsa_update, ExpectedSarsa(False, target_epsilon), w, w2, epsilon=behaviour_epsilon)
    _only_changed(w, Q1, expected)
    np.testing.assert_array_equal(w2, Q2)
    np.testing.assert_array_equal(rng, stream_state(0))


@pytest.mark.parametrize("impl", IMPLS)
def test_expected_value_splits_the_greedy_share_among_tied_legal_maxima(impl):
    """Row [-2, −∞, -2, -5], ε = 0.3, k = 3: 0.1 to explore each, 0.35 more to each tied maximum:
    0.45 * -2 + 0.45 * -2 + 0.1 * -5 = -2.3."""
    row = np.array([-2.0, NEG_INF, -2.0, -5.0])
    expected = (0.1 + 0.7 / 2) * -2.0 + (0.1 + 0.7 / 2) * -2.0 + 0.1 * -5.0
    assert _impl(impl, expected_value)(row, row, 0.3) == pytest.approx(expected, rel=1e-13)
    assert _impl(impl, expected_value)(np.array([NEG_INF, -4.0]), np.array([NEG_INF, -4.0]), 0.6) == -4.0


def _coin(seed: int) -> float:
    """The double learner's coin: the first uniform of the stream ``stream_state(seed)``."""
    return float(np.random.Generator(np.random.PCG64(seed)).random())


@pytest.mark.slow("compiles Double Q-Learning's update, both learners (about a second)")
@pytest.mark.parametrize("impl", IMPLS)
@pytest.mark.parametrize("seed", [2, 0], ids=["Q1-learns", "Q2-learns"])
def test_double_q_update_picks_and_values_among_the_legal_moves(impl, seed):
    """Q1 learns (coin < 0.5): argmax Q1(1, .) over the legal moves is 2 (-1), Q2(1, 2) = -4:
    q1(0, 2) = 0.5 + 0.5 * (-1 + 0.9 * -4 - 0.5) = -2.05.
    Q2 learns: argmax Q2(1, .) is 3 (0.5), Q1(1, 3) = -2: q2(0, 2) = -0.75 + 0.5 * (-1 + 0.9 * -2 + 0.75) = -1.775.
    (With −∞ at index 0 a scan from index 0 must still move on: an illegal move read as 0 would be Q1's argmax.)"""
    w, w2 = Q1.copy(), Q2.copy()
    rng = _update(impl, double_q_update, DoubleQLearning(False), w, w2, seed=seed)
    if _coin(seed) < 0.5:
        assert seed == 2
        _only_changed(w, Q1, 0.5 + ALPHA * (REWARD + GAMMA * Q2[1, 2] - 0.5))
        np.testing.assert_array_equal(w2, Q2)
    else:
        assert seed == 0
        _only_changed(w2, Q2, -0.75 + ALPHA * (REWARD + GAMMA * Q1[1, 3] - -0.75))
        np.testing.assert_array_equal(w, Q1)
    twin = stream_state(seed)
    next_double(twin)  # one coin drawn, nothing else
    np.testing.assert_array_equal(rng, twin)


@pytest.mark.slow("compiles Double Expected SARSA's update, both learners (about a second)")
@pytest.mark.parametrize("impl", IMPLS)
@pytest.mark.parametrize("seed", [2, 0], ids=["Q1-learns", "Q2-learns"])
def test_double_expected_sarsa_update_expects_over_the_legal_moves(impl, seed):
    """ε = 0.3 over k = 3 legal moves. Q1 learns: π1 = (-, 0.1, 0.8, 0.1) (greedy 2) and Q2 values it:
    0.1 * -5 + 0.8 * -4 + 0.1 * 0.5 = -3.65; q1(0, 2) = 0.5 + 0.5 * (-1 + 0.9 * -3.65 - 0.5).
    Q2 learns: π2 = (-, 0.1, 0.1, 0.8) (greedy 3) and Q1 values it: 0.1 * -3 + 0.1 * -1 + 0.8 * -2 = -2.0;
    q2(0, 2) = -0.75 + 0.5 * (-1 + 0.9 * -2.0 + 0.75). (0 * −∞ at the illegal move would be NaN.)"""
    w, w2 = Q1.copy(), Q2.copy()
    _update(impl, double_expected_sarsa_update, DoubleExpectedSarsa(False, -1.0), w, w2, epsilon=0.3, seed=seed)
    if _coin(seed) < 0.5:
        expectation = 0.1 * Q2[1, 1] + (0.1 + 0.7) * Q2[1, 2] + 0.1 * Q2[1, 3]
        assert expectation == pytest.approx(-3.65)
        _only_changed(w, Q1, 0.5 + ALPHA * (REWARD + GAMMA * expectation - 0.5))
        np.testing.assert_array_equal(w2, Q2)
    else:
        expectation = 0.1 * Q1[1, 1] + 0.1 * Q1[1, 2] + (0.1 + 0.7) * Q1[1, 3]
        assert expectation == pytest.approx(-2.0)
        _only_changed(w2, Q2, -0.75 + ALPHA * (REWARD + GAMMA * expectation - -0.75))
        np.testing.assert_array_equal(w, Q1)


# --- 3. the engine on a masked chain ---------------------------------------------------------------------------
# States 0 .. 4 in a row, a trap 5; actions 0 left, 1 stay, 2 right. Each legal step costs 0.05; right from 4 ends the
# episode with +1. Illegal: left in 0 (index 0), stay in 2, left and stay in 3 (a forced move). An illegal move would
# lead into the trap, 5, whose every move ends the episode with -100: a masked run never visits it, never loses
# 100, and never touches its table (all legal, 0). Episodes start anywhere in 0 .. 4.

TRAP = 5
LEGAL = np.ones((6, 3), dtype=np.bool_)
LEGAL[0, 0] = LEGAL[2, 1] = LEGAL[3, 0] = LEGAL[3, 1] = False
EPISODES = 200
SEEDS = [0, 1, 2]
ENGINE_METHODS = ["random", "q_learning", "sarsa", "expected_sarsa", "double_q_learning", "double_expected_sarsa",
                  "n_step_sarsa", "sarsa_lambda", "q_lambda"]


def _masked_chain():
    outcomes = {}
    for s in range(5):
        for a, target in enumerate((s - 1, s, s + 1)):
            if not LEGAL[s, a]:
                outcomes[(s, a)] = [(1.0, TRAP, -100.0, False)]
            elif target == 5:
                outcomes[(s, a)] = [(1.0, s, 1.0, True)]
            else:
                outcomes[(s, a)] = [(1.0, target, -0.05, False)]
    for a in range(3):
        outcomes[(TRAP, a)] = [(1.0, TRAP, -100.0, True)]
    return make_table_env(outcomes, 6, 3, {s: 0.2 for s in range(5)})


def _engine_rule(algorithm: str) -> tuple:
    """The method's rule with the scalar types the engine is compiled for (as the other engine tests build them)."""
    chosen = METHODS[algorithm]
    values = {"draw_before": chosen.next_action == "before_update", "target_epsilon": -1.0, "n": 3, "lam": 0.8,
              "replacing": True, "n_actions": 3}
    return chosen.rule(**{name: values[name] for name in chosen.rule._fields})


def _train_masked(algorithm: str):
    table_env = _masked_chain()
    state = initial_state(SEEDS, table_env.n_states, table_env.n_actions, LEGAL)
    snapshots = np.array([EPISODES // 2, EPISODES], np.int64)
    records = allocate_records(len(SEEDS), EPISODES, 4, 3, snapshots, state.w.shape[1:])
    settings = Settings(alpha=0.2, gamma=0.9, max_steps=40, truncation_as_terminal=False, eval_every=EPISODES // 4,
                        legal_moves=True)
    train_runs(_engine_rule(algorithm), settings, table_env, OneHot(table_env.n_states), state,
               linear_decay_epsilon(EPISODES, 1.0, 0.1, 0.5), 0, EPISODES, records)
    return state, records


def test_masked_chain_is_what_the_engine_tests_read():
    """The chain itself: an illegal move leads to the trap, which costs 100; the start never is the trap."""
    table_env = _masked_chain()
    for s, a in zip(*np.nonzero(~LEGAL), strict=True):
        assert table_env.next_state[s, a, 0] == TRAP
        assert table_env.reward[s, a, 0] == -100.0
    assert table_env.start[TRAP - 1] == pytest.approx(1.0)  # cumulative: the trap has no share of the starts
    state = initial_state(SEEDS, 6, 3, LEGAL)
    for w in (state.w, state.w2):
        assert np.all(w[:, ~LEGAL] == NEG_INF)
        assert np.all(w[:, LEGAL] == 0.0)


@pytest.mark.parametrize("algorithm", ENGINE_METHODS)
def test_engine_never_takes_or_touches_an_illegal_move(algorithm):
    """200 episodes from ε = 1 down to 0.1, three seeds, evaluations every 50: the trap is never entered, in training
    or evaluation (no return as low as -100); every illegal weight is still −∞ in both tables and in the snapshots,
    every legal one finite, none NaN; every legal move of the chain was taken (its weight moved) in some run, so
    the exploring branch ran over all of them; the baseline learns nothing."""
    state, records = _train_masked(algorithm)
    assert np.all(records.visits[:, TRAP] == 0), records.visits
    assert np.all(records.visits[:, :TRAP] > 0), records.visits
    assert records.returns.min() > -100.0
    assert records.eval_returns.min() > -100.0
    assert np.all(records.eval_lengths >= 1)
    for name, tables in (("w", state.w), ("w2", state.w2), ("snapshots", records.snapshots)):
        assert not np.isnan(tables).any(), name
        assert np.all(tables[..., ~LEGAL] == NEG_INF), name
        assert np.all(np.isfinite(tables[..., LEGAL])), name
    assert np.all(state.w[:, TRAP] == 0.0)
    chain_legal = LEGAL.copy()
    chain_legal[TRAP] = False
    if algorithm == "random":
        assert np.all(state.w[:, LEGAL] == 0.0)
        assert records.eval_returns.max() > records.eval_returns.min()  # the evaluation did act, and randomly
    else:
        moved = np.zeros(LEGAL.shape, dtype=np.bool_)
        for tables in (state.w, state.w2):
            moved |= ((tables != 0.0) & np.isfinite(tables)).any(axis=0)
        np.testing.assert_array_equal(moved, chain_legal)
        assert records.terminated.any()
