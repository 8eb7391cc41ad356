"""The algorithms beyond the paper, checked against answers known independently of the engine.

- single targets worked out by hand: Expected SARSA (6.6), Double Q-Learning (6.7), the softmax policy (13.1);
- single episodes worked out by hand on a two-state chain, for every episode loop of the engine (one-step, n-step
  SARSA 7.2, SARSA(λ) and Watkins's Q(λ) 12.7 / 12.10, REINFORCE 13.3 / 13.4), called directly (compiled) and
  through the engine's ``train_block`` (its choice of the loop by the rule's type included);
- convergence to the known ``q*`` of a chain and to the better arm of a two-armed bandit, for every algorithm;
- the engine's one-step and random runs against a plain-Python reference written here, bit for bit, and equalities
  between algorithms that must coincide (n-step SARSA with n = 1 and SARSA; SARSA(λ) with λ = 0 and SARSA);
- REINFORCE's update is an unbiased estimate of the policy gradient (finite differences, many episodes);
- every new algorithm through ``rlcompare.run`` with grid and tile features, and the configuration's checks.

Chain used by the hand-worked episodes (``chain(2)``): states 0 and 1, start in 0; action 0 ("stay") keeps the
state with reward 0; action 1 ("right") moves 0 -> 1 with reward 0, and from 1 ends the episode with reward 1.
Neither the start nor a step of this chain depends on the environment or transition streams (each draws once).
Unless a test says otherwise the hand-worked episodes use α = 0.5, γ = 0.5, ε = 0 and the initial weights ``W0``
below, under which every greedy choice is strict (no tie, so no tie-breaking draw).
"""

from __future__ import annotations

import math

import numba
import numpy as np
import pytest
from helpers import one_episode

from rlcompare import ConfigError, ExperimentConfig, run
from rlcompare.algorithms import td, traces
from rlcompare.algorithms.policies import RandomActions, epsilon_greedy_action, uniform_action
from rlcompare.algorithms.registry import BEFORE_UPDATE, METHODS
from rlcompare.algorithms.reinforce import Reinforce
from rlcompare.algorithms.schedules import constant_epsilon, linear_decay_epsilon
from rlcompare.algorithms.softmax import sample_softmax, softmax
from rlcompare.algorithms.td import double_q_target, expected_sarsa_target, q_learning_target
from rlcompare.envs import mountain_car
from rlcompare.envs.discretize import UniformGrid, cell_indices
from rlcompare.envs.features import OneHot, make_features
from rlcompare.envs.registry import environment, make_env
from rlcompare.envs.table import TableEnv, chain, two_armed_bandit
from rlcompare.rng import next_double, stream_state
from rlcompare.tabular import loops
from rlcompare.tabular.runs import train_runs
from rlcompare.tabular.state import (
    AGENT_STREAM,
    ENV_STREAM,
    EVAL_AGENT_STREAM,
    EVAL_ENV_STREAM,
    TRANSITION_STREAM,
    Records,
    RunState,
    Settings,
    allocate_records,
    initial_state,
)

IMPLS = ["compiled", "py_func"]
ALPHA, GAMMA = 0.5, 0.5
W0 = [[0.25, 0.2], [0.1, 0.6]]  # state 0 prefers "stay" (0.25 > 0.2) until one update lowers it; state 1 "right"
ENV_SEED = 1000  # the chain's one start and deterministic steps do not depend on the environment stream
TRANSITION_SEED = 2000


def _impl(name: str, fn):
    """The compiled dispatcher or the plain Python function it compiles."""
    return fn if name == "compiled" else fn.py_func


_CACHED: dict = {}


def _compiled(fn):
    """An episode loop compiled by numba with the same (default) options, but cached on disk.

    The engine's loops are not cached on disk (only ``train_block`` is), and compiling them takes about a minute,
    every session; this compiles the same Python function once, and later sessions load it. The engine's own
    compiled code runs the same episodes under the ``train_block`` impl (the cached entry point that production
    calls). A loop's inner calls are numba overloads, so it cannot run as plain Python (``py_func``).
    """
    if fn not in _CACHED:
        _CACHED[fn] = numba.njit(cache=True)(fn.py_func)
    return _CACHED[fn]


def _settings(*, alpha: float = ALPHA, gamma: float = GAMMA, max_steps: int = 100,
              truncation_as_terminal: bool = False, eval_every: int = 0) -> Settings:
    """Settings with the scalar types the engine is compiled for (another type would compile anew)."""
    return Settings(alpha=float(alpha), gamma=float(gamma), max_steps=int(max_steps),
                    truncation_as_terminal=bool(truncation_as_terminal), eval_every=int(eval_every))


def _rule(algorithm: str, *, draw_before: bool | None = None, n: int = 1, lam: float = 0.0, replacing: bool = True,
          target_epsilon: float = -1.0, baseline_alpha: float = 0.0, n_actions: int = 2) -> tuple:
    """The rule of the method called ``algorithm``, with the scalar types the engine is compiled for; a one-step
    method draws A' as its box does unless ``draw_before`` says otherwise."""
    chosen = METHODS[algorithm]
    values = {
        "draw_before": chosen.next_action == BEFORE_UPDATE if draw_before is None else bool(draw_before),
        "target_epsilon": float(target_epsilon), "n": int(n), "lam": float(lam), "replacing": bool(replacing),
        "discount_gradient": chosen.discount_gradient, "baseline_alpha": float(baseline_alpha),
        "n_actions": int(n_actions),
    }
    return chosen.rule(**{name: values[name] for name in chosen.rule._fields})


def _draws(seed: int, count: int) -> list[float]:
    """The first ``count`` uniforms of the stream ``stream_state(seed)``, drawn in plain Python."""
    state = stream_state(seed)
    return [next_double.py_func(state) for _ in range(count)]


def _advanced(seed: int, count: int) -> np.ndarray:
    """The stream ``stream_state(seed)`` after ``count`` draws."""
    state = stream_state(seed)
    for _ in range(count):
        next_double.py_func(state)
    return state


EPISODE_IMPLS = ["compiled", "train_block"]
"""For the trace methods, whose episode loop must also leave its trace arrays fresh (``compiled`` checks them);
the others' episodes run through ``train_block`` alone, the entry point production calls."""
def _no_traces() -> loops.Traces:
    """The stub the loops of methods without traces are given."""
    return loops.Traces(np.zeros(1), np.empty(1, np.int64), np.zeros(1, np.bool_))


class Episode:
    """One episode of the engine on ``chain(2)``; what it returned and left behind.

    ``compiled`` calls the rule's episode loop directly; ``train_block`` runs one episode of one run through the
    engine's cached entry point (its choice of the loop, trace allocation and snapshot included).
    """

    def __init__(self, impl: str, rule: tuple, w, *, w2=None, epsilon: float = 0.0, seed: int = 0, **kwargs):
        table_env = chain(2)
        features = OneHot(table_env.n_states)
        self.transitions = stream_state(TRANSITION_SEED)
        settings = _settings(**kwargs)
        self.w = np.array(w, dtype=np.float64)
        self.w2 = np.zeros_like(self.w) if w2 is None else np.array(w2, dtype=np.float64)
        self.env_rng, self.agent_rng = stream_state(ENV_SEED), stream_state(seed)
        self.visits = np.zeros(table_env.n_states, dtype=np.int64)
        has_traces = isinstance(rule, traces.SarsaLambda | traces.QLambda)
        self.work = loops.Traces(np.zeros(self.w.size), np.empty(self.w.size, np.int64),
                                 np.zeros(self.w.size, np.bool_)) if has_traces else _no_traces()
        if impl == "train_block":
            out = self._train_block(rule, settings, table_env, features, epsilon)
        else:
            out = _compiled(loops.LOOPS[type(rule)][0])(rule, settings, table_env, features, self.w, self.w2, self.work,
                                               epsilon, self.env_rng, self.agent_rng, self.transitions, self.visits)
        self.ret, self.steps, self.terminated = float(out[0]), int(out[1]), bool(out[2])

    def _train_block(self, rule, settings, table_env, features, epsilon):
        state, records = one_episode(rule, settings, table_env, features, self.w, self.w2, epsilon, self.agent_rng,
                                     self.env_rng, self.transitions)
        self.w, self.w2 = state.w[0], state.w2[0]
        self.env_rng, self.agent_rng, self.transitions = (state.rng[0, ENV_STREAM], state.rng[0, AGENT_STREAM],
                                                          state.rng[0, TRANSITION_STREAM])
        self.visits = records.visits[0]
        snapshot = (self.w + self.w2) / 2 if isinstance(rule, td.DoubleQLearning | td.DoubleExpectedSarsa) else self.w
        np.testing.assert_array_equal(records.snapshots[0, 0], snapshot)
        return records.returns[0, 0], records.lengths[0, 0], records.terminated[0, 0]

    def check(self, *, steps: int, visits, w, w2=None, draws: int, seed: int = 0) -> None:
        """Every episode here reaches the goal once (return 1); the environment stream made one draw, for the
        reset, and the transition stream one per step, as Gymnasium's tables do; the agent stream made exactly
        ``draws`` draws."""
        assert (self.ret, self.steps, self.terminated) == (1.0, steps, True)
        np.testing.assert_array_equal(self.visits, visits)
        np.testing.assert_allclose(self.w, w, rtol=1e-12, atol=1e-15)
        if w2 is not None:
            np.testing.assert_allclose(self.w2, w2, rtol=1e-12, atol=1e-15)
        np.testing.assert_array_equal(self.env_rng, _advanced(ENV_SEED, 1))
        np.testing.assert_array_equal(self.transitions, _advanced(TRANSITION_SEED, steps))
        np.testing.assert_array_equal(self.agent_rng, _advanced(seed, draws))
        assert np.all(self.work.z == 0.0)  # traces are left fresh for the next episode
        assert not self.work.listed.any()


# --- 1. single targets by hand ------------------------------------------------------------------------


@pytest.mark.parametrize("impl", IMPLS)
def test_expected_sarsa_target_by_hand(impl):
    target = _impl(impl, expected_sarsa_target)
    # One maximum: ε = 0.3 over 3 actions gives 0.1 each, the greedy one (value 3) another 0.7:
    # E = 0.1*1 + 0.8*3 + 0.1*2 = 2.7; target = -1 + 0.5*2.7 = 0.35.
    assert target(-1.0, np.array([1.0, 3.0, 2.0]), 0.3, 0.5, False) == pytest.approx(0.35, rel=1e-14)
    # Two tied maxima share the greedy 0.7: 0.1 + 0.35 = 0.45 each; E = 0.45*3 + 0.1*1 + 0.45*3 = 2.8;
    # target = -1 + 0.5*2.8 = 0.4.
    assert target(-1.0, np.array([3.0, 1.0, 3.0]), 0.3, 0.5, False) == pytest.approx(0.4, rel=1e-14)
    # ε = 1: the uniform mean (1 + 3 + 2) / 3 = 2; target = 2 + 0.9*2 = 3.8.
    assert target(2.0, np.array([1.0, 3.0, 2.0]), 1.0, 0.9, False) == pytest.approx(3.8, rel=1e-14)
    # A terminal next state: R alone, whatever the values.
    assert target(-1.0, np.array([1.0, 3.0, 2.0]), 0.3, 0.5, True) == -1.0


@pytest.mark.parametrize("impl", IMPLS)
@pytest.mark.parametrize("row", [[1.0, 3.0, 2.0], [3.0, 1.0, 3.0], [-3.0, -1.0, -2.0], [0.0, 0.0], [-2.0]])
def test_expected_sarsa_with_greedy_target_is_q_learning(impl, row):
    """ε = 0: all the probability on the maxima, so the expectation is the max (ties included)."""
    q_next = np.array(row)
    for terminal in (False, True):
        assert _impl(impl, expected_sarsa_target)(-1.0, q_next, 0.0, 0.9, terminal) == pytest.approx(
            _impl(impl, q_learning_target)(-1.0, q_next, 0.9, terminal), rel=1e-15)


@pytest.mark.parametrize("impl", IMPLS)
def test_double_q_target_by_hand(impl):
    target = _impl(impl, double_q_target)
    q1, q2 = np.array([1.0, 5.0, 5.0]), np.array([10.0, 2.0, 7.0])
    # Q1 picks its first maximum, action 1 (not 2), and Q2 values it: -1 + 0.5*2 = 0.
    assert target(-1.0, q1, q2, 0.5, False) == 0.0
    # The other way round: Q2 picks action 0 (value 10), Q1 values it: -1 + 0.5*1 = -0.5.
    assert target(-1.0, q2, q1, 0.5, False) == -0.5
    # Not Q-Learning's max of either estimate: max Q1 = 5, max Q2 = 10.
    assert target(-1.0, q1, q2, 0.5, False) not in (-1.0 + 0.5 * 5.0, -1.0 + 0.5 * 10.0)
    assert target(-1.0, q1, q2, 0.5, True) == -1.0


@pytest.mark.parametrize("impl", IMPLS)
def test_softmax_by_hand(impl):
    fn = _impl(impl, softmax)
    # Preferences [0, ln 2]: weights e^0 = 1 and e^(ln 2) = 2, so [1/3, 2/3].
    np.testing.assert_allclose(fn(np.array([0.0, math.log(2.0)]), np.empty(2)), [1 / 3, 2 / 3], rtol=1e-14)
    preferences = np.array([0.3, -1.2, 2.0, 0.0])
    pi = fn(preferences, np.empty(4))
    assert pi.sum() == pytest.approx(1.0, rel=1e-15)
    assert np.all(pi > 0.0)
    expected = np.exp(preferences) / np.exp(preferences).sum()
    np.testing.assert_allclose(pi, expected, rtol=1e-14)
    # Shift invariance, and no overflow for preferences whose exponentials overflow.
    np.testing.assert_allclose(fn(preferences + 1000.0, np.empty(4)), pi, rtol=1e-12)
    np.testing.assert_allclose(fn(preferences - 1000.0, np.empty(4)), pi, rtol=1e-12)


@pytest.mark.parametrize("impl", IMPLS)
def test_sample_softmax_follows_its_probabilities(impl):
    """Preferences [0, ln 2]: action 1 with probability 2/3 (within 5 standard errors over 20 000 draws);
    the probabilities are left in ``out``."""
    rng, out = stream_state(5), np.empty(2)
    draws = 20_000
    ones = sum(_impl(impl, sample_softmax)(np.array([0.0, math.log(2.0)]), out, rng) for _ in range(draws))
    np.testing.assert_allclose(out, [1 / 3, 2 / 3], rtol=1e-14)
    assert abs(ones / draws - 2 / 3) < 5 * math.sqrt(2 / 9 / draws)


# --- 2. single episodes by hand on chain(2) ------------------------------------------------------------


def test_q_learning_episode_by_hand():
    """S=0, A=0 (0.25 > 0.2) -> S'=0: target 0.5*max(0.25, 0.2) = 0.125; w[0,0] = 0.25 + 0.5*(0.125-0.25) = 0.1875.
    The next action is drawn after the update, from [0.1875, 0.2]: right.
    S=0, A=1 -> S'=1: target 0.5*max(0.1, 0.6) = 0.3; w[0,1] = 0.2 + 0.5*(0.3-0.2) = 0.25. Next: right (0.6 > 0.1).
    S=1, A=1 -> goal, R=1: target 1; w[1,1] = 0.6 + 0.5*(1-0.6) = 0.8. Three steps, three draws (one per choice)."""
    episode = Episode("train_block", _rule("q_learning"), W0)
    episode.check(steps=3, visits=[2, 1], w=[[0.1875, 0.25], [0.1, 0.8]], draws=3)


def test_sarsa_episode_by_hand():
    """SARSA draws A' before its update (Algorithm 2), so in the self-loop it stays once more than Q-Learning.
    S=0, A=0 -> S'=0: A' from [0.25, 0.2] = stay; target 0.5*0.25 = 0.125; w[0,0] = 0.1875.
    S=0, A=0 -> S'=0: A' from [0.1875, 0.2] = right; target 0.5*0.2 = 0.1; w[0,0] = 0.1875 + 0.5*(0.1-0.1875) = 0.14375.
    S=0, A=1 -> S'=1: A' = right; target 0.5*0.6 = 0.3; w[0,1] = 0.2 + 0.5*(0.3-0.2) = 0.25.
    S=1, A=1 -> goal: w[1,1] = 0.8. Four steps; four draws (no draw after the terminal step)."""
    episode = Episode("train_block", _rule("sarsa"), W0)
    episode.check(steps=4, visits=[3, 1], w=[[0.14375, 0.25], [0.1, 0.8]], draws=4)


def test_expected_sarsa_episode_by_hand():
    """Behaviour ε = 0, target ε = 0.5 (off-policy): 0.25 per action plus 0.5 on the greedy one.
    S=0, A=0 -> S'=0: E = 0.75*0.25 + 0.25*0.2 = 0.2375; target 0.11875; w[0,0] = 0.25 + 0.5*(0.11875-0.25) = 0.184375.
    Next from [0.184375, 0.2]: right.
    S=0, A=1 -> S'=1: E = 0.25*0.1 + 0.75*0.6 = 0.475; target 0.2375; w[0,1] = 0.2 + 0.5*(0.2375-0.2) = 0.21875.
    S=1, A=1 -> goal: w[1,1] = 0.8."""
    episode = Episode("train_block", _rule("expected_sarsa", target_epsilon=0.5), W0)
    episode.check(steps=3, visits=[2, 1], w=[[0.184375, 0.21875], [0.1, 0.8]], draws=3)


def test_on_policy_expected_sarsa_with_greedy_behaviour_is_q_learning():
    """target_epsilon < 0 takes the behaviour's ε = 0: the Q-Learning episode above, weights and all."""
    episode = Episode("train_block", _rule("expected_sarsa", target_epsilon=-1.0), W0)
    episode.check(steps=3, visits=[2, 1], w=[[0.1875, 0.25], [0.1, 0.8]], draws=3)


DOUBLE_Q_SEED = 9  # agent draws 0.87 (first action), 0.29 (coin: update Q1), 0.60 (action), 0.78 (coin: Q2)


def test_double_q_episode_by_hand():
    """Q1 = [[0, 0.5], [0.5, 0.25]], Q2 = [[0, 0.25], [0, 0.75]]; behaviour greedy in Q1 + Q2, which says
    right in both states ([0, 0.75] and [0.5, 1.0]).
    Step 1, S=0, A=1 -> S'=1, coin 0.29 < 0.5: Q1 learns. Q1 picks argmax [0.5, 0.25] = stay, Q2 values it: 0;
    target 0 + 0.5*0 = 0; Q1[0,1] = 0.5 + 0.5*(0-0.5) = 0.25. (Q-Learning on Q1 would have used 0.5.)
    Next action from Q1[1] + Q2[1] = [0.5, 1.0]: right.
    Step 2, S=1, A=1 -> goal, coin 0.78 >= 0.5: Q2 learns. Q2[1,1] = 0.75 + 0.5*(1-0.75) = 0.875.
    Draws: action, coin, action, coin = 4."""
    d = _draws(DOUBLE_Q_SEED, 4)
    assert d[1] < 0.5 <= d[3]  # the coins the comments above rely on
    episode = Episode("train_block", _rule("double_q_learning"), [[0.0, 0.5], [0.5, 0.25]],
                      w2=[[0.0, 0.25], [0.0, 0.75]], seed=DOUBLE_Q_SEED)
    episode.check(steps=2, visits=[1, 1], w=[[0.0, 0.25], [0.5, 0.25]], w2=[[0.0, 0.25], [0.0, 0.875]], draws=4,
                  seed=DOUBLE_Q_SEED)


def test_double_expected_sarsa_episode_by_hand():
    """Exercise 6.13 on the Double Q-Learning episode above, target ε = 0.5 (behaviour ε = 0).
    Step 1, S=0, A=1 -> S'=1, coin 0.29: Q1 learns. Its target policy, ε-greedy in Q1[1] = [0.5, 0.25], is
    [0.75, 0.25]; Q2[1] = [0, 0.75] values it: E = 0.1875; target 0.5*0.1875 = 0.09375;
    Q1[0,1] = 0.5 + 0.5*(0.09375-0.5) = 0.296875. Next from [0.5, 1.0]: right.
    Step 2, S=1, A=1 -> goal, coin 0.78: Q2[1,1] = 0.75 + 0.5*(1-0.75) = 0.875.
    With a greedy target policy (target ε = 0) the episode is Double Q-Learning's: Q1[0,1] = 0.25."""
    for target_epsilon, learned in ((0.5, 0.296875), (0.0, 0.25)):
        episode = Episode("train_block", _rule("double_expected_sarsa", target_epsilon=target_epsilon),
                          [[0.0, 0.5], [0.5, 0.25]], w2=[[0.0, 0.25], [0.0, 0.75]], seed=DOUBLE_Q_SEED)
        episode.check(steps=2, visits=[1, 1], w=[[0.0, learned], [0.5, 0.25]], w2=[[0.0, 0.25], [0.0, 0.875]],
                      draws=4, seed=DOUBLE_Q_SEED)


def test_n_step_sarsa_episode_by_hand():
    """n = 2. Each A_{t+1} is drawn when S_{t+1} is seen, before the update of τ = t - 1.
    t=0: S0=0, A0=stay -> S1=0, R1=0; A1 from [0.25, 0.2] = stay.
    t=1: -> S2=0, R2=0; A2 = stay. τ=0: G = 0 + 0.5*0 + 0.25*q(0,stay) = 0.0625;
         w[0,0] = 0.25 + 0.5*(0.0625-0.25) = 0.15625.
    t=2: -> S3=0, R3=0; A3 from [0.15625, 0.2] = right. τ=1: G = 0.25*q(0,right) = 0.05;
         w[0,0] = 0.15625 + 0.5*(0.05-0.15625) = 0.103125.
    t=3: -> S4=1, R4=0; A4 = right. τ=2: G = 0.25*q(1,right) = 0.15;
         w[0,0] = 0.103125 + 0.5*(0.15-0.103125) = 0.1265625.
    t=4: -> goal, R5=1, T=5. τ=3: G = R4 + 0.5*R5 = 0.5 (no bootstrap past T); w[0,1] = 0.2 + 0.5*(0.5-0.2) = 0.35.
    τ=4: G = R5 = 1; w[1,1] = 0.6 + 0.5*(1-0.6) = 0.8. Five steps, five draws."""
    episode = Episode("train_block", _rule("n_step_sarsa", n=2), W0)
    episode.check(steps=5, visits=[4, 1], w=[[0.1265625, 0.35], [0.1, 0.8]], draws=5)


@pytest.mark.parametrize("impl", EPISODE_IMPLS)
@pytest.mark.parametrize(
    ("replacing", "w00"),
    [
        # replacing:    step 2 z[0,0] = 1,    w[0,0] = 0.1875 - 0.04375 = 0.14375; z -> 0.25
        #               step 3 w[0,0] += 0.05*0.25 = 0.15625;  z[0,0] -> 0.0625
        #               step 4 w[0,0] += 0.2*0.0625 = 0.16875
        (True, 0.16875),
        # accumulating: step 2 z[0,0] = 1.25, w[0,0] = 0.1875 - 0.0546875 = 0.1328125; z -> 0.3125
        #               step 3 w[0,0] += 0.05*0.3125 = 0.1484375;  z[0,0] -> 0.078125
        #               step 4 w[0,0] += 0.2*0.078125 = 0.1640625
        (False, 0.1640625),
    ],
    ids=["replacing", "accumulating"],
)
@pytest.mark.parametrize("algorithm", ["sarsa_lambda", "q_lambda"])
def test_lambda_episode_by_hand(impl, algorithm, replacing, w00):
    """λ = 0.5, so traces decay by γλ = 0.25 after each step. δ = R + γ q(S',A') - q(S,A), with A' drawn before
    the update; Watkins's max equals q(S',A') here because every action taken is greedy, so no trace is cut.
    1: S=0, A=stay -> S'=0, A'=stay: δ = -0.25 + 0.5*0.25 = -0.125; z[0,0] = 1; w[0,0] = 0.25 - 0.0625 = 0.1875.
    2: S=0, A=stay -> S'=0, A'=right ([0.1875, 0.2]): δ = -0.1875 + 0.5*0.2 = -0.0875 (w[0,0]: see the cases).
    3: S=0, A=right -> S'=1, A'=right: δ = -0.2 + 0.5*0.6 = 0.1; z[0,1] = 1; w[0,1] = 0.2 + 0.05 = 0.25; z[0,1] -> 0.25.
    4: S=1, A=right -> goal: δ = 1 - 0.6 = 0.4; z[1,1] = 1; αδ = 0.2: w[0,1] += 0.2*0.25 = 0.3; w[1,1] = 0.8."""
    episode = Episode(impl, _rule(algorithm, lam=0.5, replacing=replacing), W0)
    episode.check(steps=4, visits=[3, 1], w=[[w00, 0.3], [0.1, 0.8]], draws=4)


Q_LAMBDA_SEED = 43  # agent draws 0.65 (greedy), 0.04 (explore), 0.02 (uniform: stay), 0.84 (greedy)


@pytest.mark.parametrize("impl", EPISODE_IMPLS)
@pytest.mark.parametrize(
    ("algorithm", "w01"),
    [
        # Watkins: step 1 δ = -0.2 + 0.5*max(0.1, 0.6) = 0.1, w[0,1] = 0.2 + 0.05 = 0.25; A' = stay is exploratory
        # (0.1 < 0.6), so every trace is cut and w[0,1] moves no more.
        ("q_lambda", 0.25),
        # SARSA(λ) on the same actions: step 1 δ = -0.2 + 0.5*0.1 = -0.15, w[0,1] = 0.2 - 0.075 = 0.125, z[0,1] -> 0.5;
        # step 2 (αδ = 0.1) w[0,1] += 0.1*0.5 = 0.175, z -> 0.25; step 3 (αδ = 0.2) w[0,1] += 0.2*0.25 = 0.225.
        ("sarsa_lambda", 0.225),
    ],
    ids=["q_lambda", "sarsa_lambda"],
)
def test_exploratory_action_cuts_watkins_traces(impl, algorithm, w01):
    """ε = 0.5, λ = 1 (traces decay by γ = 0.5), replacing traces, agent seed 43, w = [[0, 0.2], [0.1, 0.6]].
    The draws give the actions: 0.65 >= ε: greedy in [0, 0.2] = right; at S'=1, 0.04 < ε explores and 0.02 gives
    the uniform action int(2*0.02) = stay, which is not greedy (0.1 < 0.6); then 0.84 >= ε: greedy = right.
    1: S=0, A=right -> S'=1, A'=stay (w[0,1]: see the cases).
    2: S=1, A=stay -> S'=1, A'=right: δ = -0.1 + 0.5*0.6 = 0.2 (both rules: A' is greedy); z[1,0] = 1;
       w[1,0] = 0.1 + 0.5*0.2 = 0.2; z[1,0] -> 0.5.
    3: S=1, A=right -> goal: δ = 1 - 0.6 = 0.4, αδ = 0.2; w[1,0] = 0.2 + 0.2*0.5 = 0.3; w[1,1] = 0.6 + 0.2 = 0.8."""
    d = _draws(Q_LAMBDA_SEED, 4)
    assert d[0] >= 0.5 > d[1]  # greedy, then explore ...
    assert int(2 * d[2]) == 0  # ... with the uniform action stay
    assert d[3] >= 0.5  # then greedy
    episode = Episode(impl, _rule(algorithm, lam=1.0, replacing=True), [[0.0, 0.2], [0.1, 0.6]], epsilon=0.5,
                      seed=Q_LAMBDA_SEED)
    episode.check(steps=3, visits=[1, 2], w=[[0.0, w01], [0.3, 0.8]], draws=4, seed=Q_LAMBDA_SEED)


REINFORCE_SEED = 61  # agent draws 0.37 (< 0.5: stay), 0.77 (right), 0.67 (right)


@pytest.mark.parametrize("baseline", [False, True], ids=["plain", "baseline"])
def test_reinforce_episode_by_hand(baseline):
    """θ = 0, so π = [0.5, 0.5] while acting: the draws give stay, right, right. α = 0.5, γ = 0.5.
    Returns: G2 = 1, G1 = 0.5*G2 = 0.5, G0 = 0.5*G1 = 0.25. θ is updated step by step (13.3's loop), so the
    gradient at t = 1 uses the θ after t = 0. ∇ ln π(A|s) w.r.t. h(s, a) is 1[a = A] - π(a).
    Plain: t=0: αγ^0 G0 = 0.125; θ[0] += 0.125*[0.5, -0.5] = [0.0625, -0.0625].
           t=1: αγ^1 G1 = 0.125; π(stay) = σ(0.125); θ[0] += 0.125*[-σ, σ].
           t=2: αγ^2 G2 = 0.125; θ[1] += 0.125*[-0.5, 0.5] = [-0.0625, 0.0625].
    Baseline (α_b = 0.5): t=0: δ = 0.25 - 0 = 0.25; b[0] = 0.125; θ step 0.5*0.25 = 0.125 as above.
           t=1: δ = 0.5 - 0.125 = 0.375; b[0] = 0.125 + 0.1875 = 0.3125; θ step 0.5*0.5*0.375 = 0.09375.
           t=2: δ = 1 - 0 = 1; b[1] = 0.5; θ step 0.5*0.25*1 = 0.125."""
    d = _draws(REINFORCE_SEED, 3)
    assert d[0] < 0.5 <= d[1]
    assert d[2] >= 0.5
    sigma = 1.0 / (1.0 + math.exp(-0.125))  # π(stay | θ[0] = [0.0625, -0.0625])
    step1 = 0.09375 if baseline else 0.125
    theta = [[0.0625 - step1 * sigma, -0.0625 + step1 * sigma], [-0.0625, 0.0625]]
    b = [[0.3125, 0.0], [0.5, 0.0]] if baseline else [[0.0, 0.0], [0.0, 0.0]]
    rule = Reinforce(discount_gradient=True, baseline_alpha=0.5 if baseline else 0.0)
    episode = Episode("train_block", rule, np.zeros((2, 2)), seed=REINFORCE_SEED)
    episode.check(steps=3, visits=[2, 1], w=theta, w2=b, draws=3, seed=REINFORCE_SEED)


# --- 3. convergence to known answers ----------------------------------------------------------------------

LEARNERS = [name for name in METHODS if name != "random"]
VALUE_METHODS = [a for a in LEARNERS if not a.startswith("reinforce")]


def _train_table(algorithm: str, table_env: TableEnv, epsilons: np.ndarray, *, seeds, alpha: float,
                 gamma: float, max_steps: int = 100, n: int = 2, lam: float = 0.8,
                 replacing: bool = True) -> tuple[RunState, Records]:
    """Train every seed with ``train_runs``; one snapshot, after the last episode."""
    rule = _rule(algorithm, n=n, lam=lam, replacing=replacing,
                 baseline_alpha=0.05 if METHODS[algorithm].baseline else 0.0, n_actions=table_env.n_actions)
    state = initial_state(list(seeds), table_env.n_states, table_env.n_actions)
    episodes = epsilons.size
    records = allocate_records(len(seeds), episodes, 0, 1, np.array([episodes], np.int64), state.w.shape[1:])
    train_runs(rule, _settings(alpha=alpha, gamma=gamma, max_steps=max_steps), table_env,
               OneHot(table_env.n_states), state, epsilons, 0, episodes, records)
    return state, records


CHAIN_SEEDS = range(4)
Q_STAR_RIGHT = 0.9 ** (3 - np.arange(4))  # chain(4), γ = 0.9: [0.729, 0.81, 0.9, 1]


@pytest.fixture(scope="module")
def chain_results():
    """Every learner on chain(4). The value methods: 600 episodes at α = 0.2, ε from 1 down to 0 over the first
    half, then greedy (so the on-policy methods end evaluating the greedy policy, whose values are q*).
    REINFORCE (which ignores ε): 2000 episodes at α = 0.2."""
    results = {}
    for algorithm in LEARNERS:
        episodes = 2000 if algorithm.startswith("reinforce") else 600
        results[algorithm] = _train_table(algorithm, chain(4), linear_decay_epsilon(episodes, 1.0, 0.0, 0.5),
                                          seeds=CHAIN_SEEDS, alpha=0.2, gamma=0.9)
    return results


@pytest.mark.parametrize("algorithm", LEARNERS)
def test_chain_greedy_policy_moves_right(chain_results, algorithm):
    _, records = chain_results[algorithm]
    final = records.snapshots[:, -1]
    assert np.all(final[:, :, 1] > final[:, :, 0]), final  # right preferred in every state, every seed
    assert np.all(records.terminated[:, -100:])  # the last episodes reach the goal ...
    if algorithm.startswith("reinforce"):
        assert records.lengths[:, -100:].mean() < 4.2  # ... the softmax policy in nearly the 4 steps of the path
    else:
        assert np.all(records.lengths[:, -100:] == 4)  # ... the greedy ones (ε = 0 by then) in exactly 4 steps


@pytest.mark.parametrize("algorithm", VALUE_METHODS)
def test_chain_values_converge_to_q_star(chain_results, algorithm):
    """q(s, right) = 0.9^(3 - s) once the policy is greedy (the Double methods: the mean of their two estimates, as
    kept in the snapshot). 300 greedy episodes at α = 0.2 shrink the error far below the tolerance."""
    state, records = chain_results[algorithm]
    final = records.snapshots[:, -1]
    np.testing.assert_allclose(final[:, :, 1], np.broadcast_to(Q_STAR_RIGHT, (len(CHAIN_SEEDS), 4)), atol=1e-6)
    if METHODS[algorithm].snapshot is not None:  # the Double methods keep the mean of their two estimates
        np.testing.assert_array_equal(final, (state.w + state.w2) / 2)
    else:
        np.testing.assert_array_equal(final, state.w)


def test_chain_reinforce_policy_is_near_deterministic(chain_results):
    """The learned softmax policy goes right with probability > 0.95 in every state, every seed."""
    for algorithm in ("reinforce", "reinforce_baseline"):
        theta = chain_results[algorithm][1].snapshots[:, -1]
        p_right = 1.0 / (1.0 + np.exp(theta[:, :, 0] - theta[:, :, 1]))
        assert np.all(p_right > 0.95), (algorithm, p_right)


BANDIT_SEEDS = range(8)


@pytest.mark.parametrize("algorithm", LEARNERS)
def test_bandit_prefers_the_better_arm(algorithm):
    """two_armed_bandit(0.2, 0.8), 1000 episodes, ε from 1 to 0 over the first half: the better arm (1) is
    preferred (greedy values, or preferences) in at least 7 of 8 seeds."""
    epsilons = linear_decay_epsilon(1000, 1.0, 0.0, 0.5)
    _, records = _train_table(algorithm, two_armed_bandit(0.2, 0.8), epsilons, seeds=BANDIT_SEEDS, alpha=0.1,
                              gamma=0.9)
    final = records.snapshots[:, -1, 0]
    assert np.sum(final[:, 1] > final[:, 0]) >= 7, final
    assert np.all(records.lengths == 1)


def test_bandit_q_learning_values_are_the_arm_probabilities():
    """Uniform exploration (ε = 1), α = 0.01, 5000 episodes: each arm is pulled ~2500 times, so q(arm) is
    an exponential average of Bernoulli(p) rewards with sd ~ sqrt(α/(2-α) p(1-p)) <= 0.036."""
    _, records = _train_table("q_learning", two_armed_bandit(0.2, 0.8), constant_epsilon(5000, 1.0),
                              seeds=BANDIT_SEEDS, alpha=0.01, gamma=0.9)
    q = records.snapshots[:, -1, 0]
    np.testing.assert_allclose(q, np.broadcast_to([0.2, 0.8], q.shape), atol=0.13)
    np.testing.assert_allclose(q.mean(axis=0), [0.2, 0.8], atol=0.05)


# --- 4. the engine against a plain-Python reference; algorithms that must coincide -----------------------------

MC_SEEDS = [0, 1, 2]
MC_EPISODES = 200


def _train_mountain_car(algorithm: str, *, features: str = "grid", episodes: int = MC_EPISODES,
                        max_steps: int = 1000, truncation_as_terminal: bool = False, n: int = 1, lam: float = 0.0,
                        replacing: bool = True) -> tuple[RunState, Records]:
    """Mountain Car with 20 bins (or 4x4 tiles x 4 tilings); ε from 1 to 0.01 over half the episodes; evaluation
    every 50 episodes; snapshots at 100 and 200."""
    feats = make_features(environment("MountainCar-v0"), features, 20, 4, 4, 0)
    epsilons = linear_decay_epsilon(episodes, 1.0, 0.01, 0.5)
    state = initial_state(MC_SEEDS, feats.n_features, mountain_car.N_ACTIONS)
    stages = np.array([e for e in (100, 200) if e <= episodes], dtype=np.int64)
    records = allocate_records(len(MC_SEEDS), episodes, episodes // 50, 3, stages, state.w.shape[1:])
    settings = _settings(alpha=0.05, gamma=0.9, max_steps=max_steps, truncation_as_terminal=truncation_as_terminal,
                         eval_every=50)
    rule = _rule(algorithm, n=n, lam=lam, replacing=replacing, n_actions=mountain_car.N_ACTIONS)
    train_runs(rule, settings, make_env(environment("MountainCar-v0")), feats, state, epsilons, 0, episodes, records)
    return state, records


def _assert_same_run(a, b) -> None:
    (state_a, records_a), (state_b, records_b) = a, b
    for name in Records._fields:
        np.testing.assert_array_equal(getattr(records_a, name), getattr(records_b, name), err_msg=name)
    np.testing.assert_array_equal(state_a.w, state_b.w)
    np.testing.assert_array_equal(state_a.w2, state_b.w2)
    np.testing.assert_array_equal(state_a.rng, state_b.rng)


class Reference:
    """Training and evaluation on Mountain Car with the grid, as plain Python: the paper's boxes (Algorithms 1 and
    2, and 6.6, 6.7) written out for a table, one cell per state, with the cells from NumPy (``cell_indices``) and
    the targets' and the policies' plain Python functions. It draws from the same streams in the same order as
    the engine says it does: the start from the reset stream, every choice and coin from the agent stream."""

    def __init__(self, rule: tuple, settings: Settings, grid: UniformGrid):
        self.rule, self.settings, self.grid = rule, settings, grid
        self.env = mountain_car.MountainCar()

    def cell(self, state: tuple[float, float]) -> int:
        return int(cell_indices(self.grid, np.array(mountain_car.observe.py_func(self.env, state)))[0])

    def values(self, w: np.ndarray, w2: np.ndarray, s: int) -> np.ndarray:
        """What the behaviour is ε-greedy in and the target policy greedy in: Q, or Q1 + Q2 for Double Q."""
        return w[s] + w2[s] if isinstance(self.rule, td.DoubleQLearning) else w[s].copy()

    def update(self, w: np.ndarray, w2: np.ndarray, s: int, a: int, s_next: int, a_next: int, reward: float,
               terminal: bool, epsilon: float, agent_rng: np.ndarray) -> None:
        """``Q(S, A) <- Q(S, A) + α (target - Q(S, A))``, the target as each box writes it."""
        rule, gamma, table = self.rule, self.settings.gamma, w
        if isinstance(rule, td.QLearning):
            target = q_learning_target.py_func(reward, w[s_next].copy(), gamma, terminal)
        elif isinstance(rule, td.Sarsa):
            if not rule.draw_before and not terminal:  # A' for the target, from the values before the update
                a_next = epsilon_greedy_action.py_func(w[s_next].copy(), epsilon, agent_rng)
            target = td.sarsa_target.py_func(reward, w[s_next, a_next], gamma, terminal)
        elif isinstance(rule, td.ExpectedSarsa):
            target_epsilon = epsilon if rule.target_epsilon < 0 else rule.target_epsilon
            target = expected_sarsa_target.py_func(reward, w[s_next].copy(), target_epsilon, gamma, terminal)
        else:  # Double Q-Learning: a fair coin picks the estimate that learns
            table, other = (w, w2) if next_double.py_func(agent_rng) < 0.5 else (w2, w)
            target = double_q_target.py_func(reward, table[s_next].copy(), other[s_next].copy(), gamma, terminal)
        table[s, a] += self.settings.alpha * (target - table[s, a])

    def training_episode(self, w, w2, epsilon, env_rng, agent_rng, visits) -> tuple[float, int, bool]:
        if isinstance(self.rule, RandomActions):
            return self.random_episode(env_rng, agent_rng, visits)
        max_steps, before = self.settings.max_steps, self.rule.draw_before
        state = mountain_car.reset.py_func(self.env, env_rng)
        s = self.cell(state)
        a = epsilon_greedy_action.py_func(self.values(w, w2, s), epsilon, agent_rng)
        ret, steps = 0.0, 0
        while True:
            visits[s] += 1
            state, reward, terminated = mountain_car.step.py_func(self.env, state, a, None)
            ret, steps = ret + reward, steps + 1
            truncated = not terminated and steps >= max_steps
            terminal = terminated or (truncated and self.settings.truncation_as_terminal)
            s_next, a_next = self.cell(state), 0
            if before and not terminal:
                a_next = epsilon_greedy_action.py_func(self.values(w, w2, s_next), epsilon, agent_rng)
            self.update(w, w2, s, a, s_next, a_next, reward, terminal, epsilon, agent_rng)
            if terminated or truncated:
                return ret, steps, terminated
            if not before:
                a_next = epsilon_greedy_action.py_func(self.values(w, w2, s_next), epsilon, agent_rng)
            s, a = s_next, a_next

    def random_episode(self, env_rng, agent_rng, visits) -> tuple[float, int, bool]:
        state = mountain_car.reset.py_func(self.env, env_rng)
        ret, steps, terminated = 0.0, 0, False
        while not terminated and steps < self.settings.max_steps:
            a = uniform_action.py_func(mountain_car.N_ACTIONS, agent_rng)
            visits[self.cell(state)] += 1
            state, reward, terminated = mountain_car.step.py_func(self.env, state, a, None)
            ret, steps = ret + reward, steps + 1
        return ret, steps, terminated

    def evaluation_episode(self, w, w2, env_rng, agent_rng) -> tuple[float, int, bool]:
        """Greedy (first maximum, ``np.argmax``) in the learned values; uniform for the baseline."""
        state = mountain_car.reset.py_func(self.env, env_rng)
        ret, steps, terminated = 0.0, 0, False
        while not terminated and steps < self.settings.max_steps:
            if isinstance(self.rule, RandomActions):
                a = uniform_action.py_func(mountain_car.N_ACTIONS, agent_rng)
            else:
                a = int(np.argmax(self.values(w, w2, self.cell(state))))
            state, reward, terminated = mountain_car.step.py_func(self.env, state, a, None)
            ret, steps = ret + reward, steps + 1
        return ret, steps, terminated

    def runs(self, state: RunState, epsilons: np.ndarray, records: Records) -> None:
        """Every run, every episode, with its evaluation rounds and snapshots."""
        eval_every, eval_episodes = self.settings.eval_every, records.eval_returns.shape[2]
        for run_, (w, w2, rng) in enumerate(zip(state.w, state.w2, state.rng, strict=True)):
            for episode, epsilon in enumerate(epsilons):
                at = (run_, episode)
                records.returns[at], records.lengths[at], records.terminated[at] = self.training_episode(
                    w, w2, epsilon, rng[ENV_STREAM], rng[AGENT_STREAM], records.visits[run_])
                completed = episode + 1
                if eval_every > 0 and completed % eval_every == 0:
                    for k in range(eval_episodes):
                        at = (run_, completed // eval_every - 1, k)
                        records.eval_returns[at], records.eval_lengths[at], records.eval_terminated[at] = (
                            self.evaluation_episode(w, w2, rng[EVAL_ENV_STREAM], rng[EVAL_AGENT_STREAM]))
                for stage in np.flatnonzero(records.snapshot_episodes == completed):
                    records.snapshots[run_, stage] = (w + w2) / 2 if isinstance(self.rule, td.DoubleQLearning) else w


REFERENCE_EPISODES, REFERENCE_SPLIT = 8, 3
REFERENCE_CASES = [("random", False, -1.0)] + [
    (algorithm, before, target_epsilon)
    for algorithm, target_epsilon in [("q_learning", -1.0), ("sarsa", -1.0), ("expected_sarsa", -1.0),
                                      ("expected_sarsa", 0.0), ("double_q_learning", -1.0)]
    for before in (False, True)
]


def _pumping_values() -> np.ndarray:
    """Initial values on the 20 x 20 grid (position bins, then velocity bins) of a policy that pumps energy into
    the car, so that greedy episodes reach the goal: 100 for pushing the way it moves, 0 for the other actions;
    at the two smallest speed bins every value is 0, so greedy choices there break ties."""
    w = np.zeros((20, 20, mountain_car.N_ACTIONS))
    w[:, :9, 0] = 100.0
    w[:, 11:, 2] = 100.0
    return w.reshape(400, mountain_car.N_ACTIONS)


def _mountain_car_reference_runs(rule: tuple, settings: Settings, engine: bool) -> tuple[RunState, Records]:
    """Two seeds of ``REFERENCE_EPISODES`` episodes from :func:`_pumping_values`, ε from 1 to 0 over half of them,
    two evaluation episodes every ``settings.eval_every``, snapshots at episodes 4 and 8: by the engine (in two
    chunks) or by the reference."""
    grid = make_features(environment("MountainCar-v0"), "grid", 20, 1, 1, 0)
    epsilons = linear_decay_epsilon(REFERENCE_EPISODES, 1.0, 0.0, 0.5)
    state = initial_state([0, 1], grid.n_features, mountain_car.N_ACTIONS)
    state.w[:] = _pumping_values()
    records = allocate_records(2, REFERENCE_EPISODES, REFERENCE_EPISODES // settings.eval_every, 2,
                               np.array([4, 8], np.int64), state.w.shape[1:])
    if engine:
        env = make_env(environment("MountainCar-v0"))
        for first, stop in ((0, REFERENCE_SPLIT), (REFERENCE_SPLIT, REFERENCE_EPISODES)):
            train_runs(rule, settings, env, grid, state, epsilons, first, stop, records)
    else:
        Reference(rule, settings, grid).runs(state, epsilons, records)
    return state, records


@pytest.mark.parametrize("truncation_as_terminal", [False, True], ids=["bootstrap", "terminal"])
@pytest.mark.parametrize(("algorithm", "before", "target_epsilon"), REFERENCE_CASES)
def test_engine_equals_plain_python_reference(algorithm, before, target_epsilon, truncation_as_terminal):
    """The one-step methods (drawing A' before or after the update) and the random baseline: the same records,
    tables and streams, bit for bit, as the plain-Python reference, the engine's run split into two chunks.
    Episodes both reach the goal and are cut by the limit, and a cut bootstraps (or not) as asked."""
    rule = _rule(algorithm, draw_before=before, target_epsilon=target_epsilon, n_actions=mountain_car.N_ACTIONS)
    settings = _settings(alpha=0.5, gamma=0.9, max_steps=400, truncation_as_terminal=truncation_as_terminal,
                         eval_every=4)
    engine = _mountain_car_reference_runs(rule, settings, engine=True)
    _assert_same_run(engine, _mountain_car_reference_runs(rule, settings, engine=False))
    state, records = engine
    assert not records.terminated.all()  # cut by the limit ...
    if algorithm != "random":  # ... and at the goal (the random baseline never reaches it in 400 steps)
        assert records.terminated.any()
        assert records.eval_terminated.any()
        assert np.any(state.w + state.w2 != _pumping_values())  # something was learned


@pytest.mark.parametrize(
    ("features", "max_steps", "truncation_as_terminal"),
    [("grid", 1000, False), ("grid", 150, False), ("grid", 150, True), ("tiles", 300, False)],
)
def test_one_step_n_step_sarsa_is_sarsa(features, max_steps, truncation_as_terminal):
    """n = 1: G = R + γ q(S', A') with A' drawn before the update, bootstrapping through a time-limit cut
    unless it is terminal: SARSA, bit for bit."""
    common = {"features": features, "max_steps": max_steps, "truncation_as_terminal": truncation_as_terminal}
    sarsa = _train_mountain_car("sarsa", **common)
    _assert_same_run(_train_mountain_car("n_step_sarsa", n=1, **common), sarsa)
    if max_steps < 1000:
        assert not sarsa[1].terminated.all()  # time-limit cuts were compared


@pytest.mark.parametrize("replacing", [True, False], ids=["replacing", "accumulating"])
@pytest.mark.parametrize("features", ["grid", "tiles"])
def test_sarsa_lambda_zero_is_sarsa_after_one_episode(features, replacing):
    """λ = 0 leaves a trace only on the pair just taken (replacing or accumulating: 0*z + 1 = 1), so the update is
    SARSA's. Not bit for bit: δ is computed as (R - q) + γ q' rather than (R + γ q') - q, so the tables agree to
    rounding only (and rounding could later break a tie differently), hence one episode and a tolerance."""
    common = {"features": features, "episodes": 1, "max_steps": 1000}
    sarsa_state, sarsa_records = _train_mountain_car("sarsa", **common)
    state, records = _train_mountain_car("sarsa_lambda", lam=0.0, replacing=replacing, **common)
    np.testing.assert_array_equal(records.lengths, sarsa_records.lengths)
    np.testing.assert_array_equal(records.visits, sarsa_records.visits)
    np.testing.assert_allclose(state.w, sarsa_state.w, rtol=1e-9, atol=1e-12)
    assert np.any(state.w != 0.0)
    # With λ > 0 the same episode updates earlier pairs too: the tables differ.
    other, _ = _train_mountain_car("sarsa_lambda", lam=0.9, replacing=replacing, **common)
    assert np.abs(other.w - sarsa_state.w).max() > 1e-3


# --- 5. REINFORCE follows the policy gradient ---------------------------------------------------------------

P_ARMS = np.array([0.2, 0.8])
THETA = np.array([0.3, -0.2])


def _j(theta: np.ndarray) -> float:
    """J(θ) = sum_a π(a | θ) p_a: the expected return of one pull."""
    pi = np.exp(theta - theta.max())
    return float(pi @ P_ARMS / pi.sum())


def _grad_j(theta: np.ndarray) -> np.ndarray:
    """∂J/∂θ_b = sum_a π(a) p_a (1[b = a] - π(b)): the expectation of REINFORCE's G ∇ ln π(A)."""
    pi = np.exp(theta - theta.max())
    pi /= pi.sum()
    return np.array([sum(pi[a] * P_ARMS[a] * ((b == a) - pi[b]) for a in range(2)) for b in range(2)])


def test_policy_gradient_matches_finite_differences():
    h = 1e-5
    numeric = np.array([(_j(THETA + h * e) - _j(THETA - h * e)) / (2 * h) for e in np.eye(2)])
    analytic = _grad_j(THETA)
    np.testing.assert_allclose(analytic, numeric, rtol=1e-6)
    # Two actions: ∂J/∂θ_0 = π0 π1 (p0 - p1), and the gradient sums to zero.
    pi0 = 1.0 / (1.0 + math.exp(-0.5))
    assert analytic[0] == pytest.approx(pi0 * (1 - pi0) * (0.2 - 0.8), rel=1e-12)
    assert analytic.sum() == pytest.approx(0.0, abs=1e-15)


@pytest.mark.slow("trains many episodes")
def test_mean_reinforce_update_is_alpha_times_the_gradient():
    """10 000 one-pull episodes of the engine from the same θ, each with its own streams: the mean update is
    α ∇J within 4 standard errors (and ∇J is tens of standard errors away from zero, so this has power)."""
    alpha, runs = 0.01, 10_000
    table_env = two_armed_bandit(*P_ARMS)
    rule, settings = Reinforce(discount_gradient=True, baseline_alpha=0.0), _settings(alpha=alpha, gamma=1.0,
                                                                                       max_steps=5)
    streams = initial_state(list(range(runs)), 1, 2).rng
    updates = np.empty((runs, 2))
    visits = np.zeros(1, dtype=np.int64)
    episode = _compiled(loops.reinforce_episode)
    for k in range(runs):
        theta = THETA[None, :].copy()
        ret, steps, terminated = episode(rule, settings, table_env, OneHot(1), theta, np.zeros((1, 2)), _no_traces(),
                                         0.0, streams[k, ENV_STREAM], streams[k, AGENT_STREAM],
                                         streams[k, TRANSITION_STREAM], visits)
        assert (steps, terminated) == (1, True)
        assert ret in (0.0, 1.0)
        updates[k] = theta[0] - THETA
    np.testing.assert_allclose(updates.sum(axis=1), 0.0, atol=1e-15)  # the softmax gradient sums to zero
    expected = alpha * _grad_j(THETA)
    standard_error = updates.std(axis=0, ddof=1) / math.sqrt(runs)
    assert np.all(np.abs(updates.mean(axis=0) - expected) < 4 * standard_error), (updates.mean(axis=0), expected)
    assert np.all(np.abs(expected) > 20 * standard_error)
    assert visits[0] == runs


# --- 6. through rlcompare.run ----------------------------------------------------------------------------

NEW_ALGORITHMS = ["expected_sarsa", "double_q_learning", "n_step_sarsa", "sarsa_lambda", "q_lambda", "reinforce",
                  "reinforce_baseline"]


@pytest.mark.parametrize(("features", "n_features"), [("grid", 10 * 10), ("tiles", 4 * (3 + 1) * (3 + 1))])
@pytest.mark.parametrize("algorithm", NEW_ALGORITHMS)
def test_run_every_new_algorithm(algorithm, features, n_features):
    """10 bins -> 100 cells; 4 tilings of 3x3 tiles, each with one extra tile per dimension for the offset ->
    4 * 16 = 64 features."""
    config = ExperimentConfig(algorithm=algorithm, features=features, bins=10, tilings=4, tiles=3, seeds=(0, 1),
                              episodes=8, max_steps=150, eval_every=4, eval_episodes=2, n=3, lam=0.5)
    results = run(config)
    records = results.records
    assert records.returns.shape == records.lengths.shape == records.terminated.shape == (2, 8)
    assert records.eval_returns.shape == records.eval_lengths.shape == (2, 2, 2)
    assert records.snapshots.shape == (2, 3, n_features, mountain_car.N_ACTIONS)
    assert records.visits.shape == (2, n_features)
    np.testing.assert_array_equal(records.returns, -records.lengths.astype(float))
    active = 1 if features == "grid" else 4  # one cell, or one tile per tiling
    np.testing.assert_array_equal(records.visits.sum(axis=1), records.lengths.sum(axis=1) * active)
    assert np.all((records.lengths >= 1) & (records.lengths <= 150))
    assert np.any(records.snapshots[:, -1] != 0.0)  # the weights moved
    assert results.q_table(1, "final").shape == (n_features, mountain_car.N_ACTIONS)


@pytest.mark.parametrize(
    ("field", "value"),
    [("lam", -0.1), ("lam", 1.5), ("n", 0), ("n", -2), ("tiles", 0), ("tilings", 0), ("features", "hex"),
     ("trace", "dutch")],
)
def test_bad_values_raise_config_error_naming_the_field(field, value):
    with pytest.raises(ConfigError) as caught:
        ExperimentConfig(**{"algorithm": "sarsa_lambda", "features": "tiles", field: value})
    assert caught.value.field_name == field
    assert str(caught.value).startswith(f"{field}:")
