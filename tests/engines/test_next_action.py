"""``next_action``: whether a one-step method draws A' before or after updating Q(S, A).

The order only matters when the update changes the values A' is drawn from, that is when S' = S. On the
chain below the "stay" action keeps the state, so the hand-worked episodes differ between the two orders.

Chain (``chain(2)``): states 0 and 1, start in 0; action 0 ("stay") keeps the state with reward 0; action 1
("right") moves 0 -> 1 with reward 0 and from 1 ends the episode with reward 1. α = 0.5, γ = 0.5, ε = 0,
initial weights ``W0``: state 0 prefers "stay" (0.25 > 0.2) until an update lowers it. With ε = 0 every
ε-greedy choice draws one uniform (the exploration test) and, with no tie, nothing else.
"""

from __future__ import annotations

import numpy as np
import pytest
from helpers import one_episode

from rlcompare import ConfigError, ExperimentConfig, run
from rlcompare.algorithms.registry import METHODS
from rlcompare.algorithms.registry import rule_for as method_rule
from rlcompare.algorithms.reinforce import Reinforce
from rlcompare.algorithms.schedules import linear_decay_epsilon
from rlcompare.envs import mountain_car
from rlcompare.envs.features import OneHot, make_features
from rlcompare.envs.registry import environment, make_env
from rlcompare.envs.table import chain
from rlcompare.rng import stream_state
from rlcompare.tabular.runs import train_runs
from rlcompare.tabular.state import (
    AGENT_STREAM,
    Settings,
    allocate_records,
    initial_state,
)

W0 = [[0.25, 0.2], [0.1, 0.6]]
COIN_SEED = 343
"""An agent stream whose uniforms 1 to 7 all fall below 0.5: Double Q-Learning's coin always updates Q1."""


def _rule(algorithm: str, before: bool, target_epsilon: float = -1.0) -> tuple:
    """The one-step method's rule, drawing A' before or after its update."""
    rule = METHODS[algorithm].rule
    return rule(before, float(target_epsilon)) if "target_epsilon" in rule._fields else rule(before)


SETTINGS = Settings(alpha=0.5, gamma=0.5, max_steps=100, truncation_as_terminal=False, eval_every=0)


def _chain_episode(algorithm: str, before: bool, seed: int = 0, w2=None):
    """One training episode of one run on ``chain(2)`` through the engine's ``train_block`` (its choice of the
    loop by the rule's type included; compiled once and cached on disk, as test_algorithms_beyond_paper.py's
    episodes are): the weights, steps, visits and agent stream it left."""
    w = np.array(W0)
    w2 = np.zeros_like(w) if w2 is None else np.array(w2)
    state, records = one_episode(_rule(algorithm, before), SETTINGS, chain(2), OneHot(2), w, w2, 0.0,
                                 stream_state(seed))
    assert (records.returns[0, 0], records.terminated[0, 0]) == (1.0, True)
    return state.w[0], state.w2[0], int(records.lengths[0, 0]), records.visits[0], state.rng[0, AGENT_STREAM]


def _after(seed: int, draws: int) -> np.ndarray:
    """The agent stream of ``seed`` after ``draws`` uniforms, from NumPy's own generator."""
    bit_generator = np.random.PCG64(seed)
    np.random.Generator(bit_generator).random(draws)
    s, inc, mask = bit_generator.state["state"]["state"], bit_generator.state["state"]["inc"], (1 << 64) - 1
    return np.array([s >> 64, s & mask, inc >> 64, inc & mask], dtype=np.uint64)


# Each case: (algorithm, before, final weights, steps, visits of states 0 and 1, agent draws).
# After the update (Q-Learning's box): stay, Q(0, stay) = 0.25 + 0.5 (0.5 * 0.25 - 0.25) = 0.1875 < 0.2, so the
# draw after the update goes right; Q(0, right) = 0.2 + 0.5 (0.5 * 0.6 - 0.2) = 0.25; Q(1, right) = 0.8.
# Before the update (SARSA's box): A' is drawn from [0.25, 0.2] before Q(0, stay) falls, so the car stays once
# more: Q(0, stay) = 0.1875 + 0.5 (0.5 * max(0.1875, 0.2) - 0.1875) = 0.14375, then right as above.
HAND_CASES = [
    ("q_learning", False, [[0.1875, 0.25], [0.1, 0.8]], 3, [2, 1], 3),
    ("q_learning", True, [[0.14375, 0.25], [0.1, 0.8]], 4, [3, 1], 4),
    ("sarsa", True, [[0.14375, 0.25], [0.1, 0.8]], 4, [3, 1], 4),
    # SARSA after the update: the target's A' (stay) comes from the values before it, 0.5 * 0.25; the action
    # taken is drawn again after it, from [0.1875, 0.2]: right. Two draws per non-terminal step.
    ("sarsa", False, [[0.1875, 0.25], [0.1, 0.8]], 3, [2, 1], 5),
    # ε = 0: Expected SARSA's target is the max, so it moves as Q-Learning does, in either order.
    ("expected_sarsa", False, [[0.1875, 0.25], [0.1, 0.8]], 3, [2, 1], 3),
    ("expected_sarsa", True, [[0.14375, 0.25], [0.1, 0.8]], 4, [3, 1], 4),
]


@pytest.mark.parametrize(("algorithm", "before", "w", "steps", "visits", "draws"), HAND_CASES)
def test_one_step_episode_by_hand(algorithm, before, w, steps, visits, draws):
    w_out, _, steps_out, visits_out, agent_rng = _chain_episode(algorithm, before)
    np.testing.assert_allclose(w_out, w, rtol=1e-15)
    assert steps_out == steps
    np.testing.assert_array_equal(visits_out, visits)
    np.testing.assert_array_equal(agent_rng, _after(0, draws))


@pytest.mark.parametrize("before", [False, True])
def test_double_q_learning_episode_by_hand(before):
    """Q2 = 0 and every coin updates Q1, so each target is R + γ Q2(S', argmax Q1) = R.

    After: Q1(0, stay) = 0.25 / 2 = 0.125 < 0.2, right: Q1(0, right) = 0.1, Q1(1, right) = 0.8; draws: the first
    action, then a coin and an action per step, a coin at the end (6).
    Before: stay is drawn again from [0.25, 0.2]; Q1(0, stay) = 0.125 / 2 = 0.0625, then right as above; draws:
    the first action, an action and a coin per non-terminal step, a coin at the end (8).
    """
    draws = np.random.Generator(np.random.PCG64(COIN_SEED)).random(8)
    assert (draws[1:] < 0.5).all()
    w1, w2, steps, visits, agent_rng = _chain_episode("double_q_learning", before, seed=COIN_SEED)
    expected = [[0.0625, 0.1], [0.1, 0.8]] if before else [[0.125, 0.1], [0.1, 0.8]]
    np.testing.assert_allclose(w1, expected, rtol=1e-15)
    np.testing.assert_array_equal(w2, 0.0)
    assert steps == (4 if before else 3)
    np.testing.assert_array_equal(visits, [3, 1] if before else [2, 1])
    np.testing.assert_array_equal(agent_rng, _after(COIN_SEED, 8 if before else 6))


# --- Mountain Car: the order changes what is learned ---------------------------------------------------------
# (The engine's runs in either order, bit for bit against a plain-Python reference:
# test_algorithms_beyond_paper.py::test_engine_equals_plain_python_reference.)

ONE_STEP = [("q_learning", -1.0), ("sarsa", -1.0), ("expected_sarsa", -1.0), ("expected_sarsa", 0.0),
            ("double_q_learning", -1.0)]


def _mountain_car_runs(algorithm: str, before: bool, target_epsilon: float, episodes: int = 60,
                       epsilon_start: float = 1.0):
    feats = make_features(environment("MountainCar-v0"), "grid", 20, 1, 1, 0)
    epsilons = linear_decay_epsilon(episodes, epsilon_start, 0.0, 0.5)
    state = initial_state([0, 1], feats.n_features, mountain_car.N_ACTIONS)
    records = allocate_records(2, episodes, 2, 2, np.array([episodes], np.int64), state.w.shape[1:])
    settings = Settings(alpha=0.05, gamma=0.9, max_steps=1000, truncation_as_terminal=False, eval_every=30)
    train_runs(_rule(algorithm, before, target_epsilon), settings, make_env(environment("MountainCar-v0")), feats,
               state, epsilons, 0, episodes, records)
    return state, records


@pytest.mark.parametrize(("algorithm", "target_epsilon"), ONE_STEP)
def test_the_order_changes_what_is_learned_on_mountain_car(algorithm, target_epsilon):
    """On the 20 x 20 grid the car stays in its cell for most steps, so the two orders part at once (with
    ε < 1: at ε = 1 the values choose nothing)."""
    after = _mountain_car_runs(algorithm, False, target_epsilon, episodes=1, epsilon_start=0.5)
    before = _mountain_car_runs(algorithm, True, target_epsilon, episodes=1, epsilon_start=0.5)
    assert not np.array_equal(after[1].visits, before[1].visits)
    assert not np.array_equal(after[0].w, before[0].w)


# --- the configuration field ---------------------------------------------------------------------------------


@pytest.mark.parametrize(("algorithm", "default"), [("q_learning", "after_update"), ("sarsa", "before_update"),
                                                    ("expected_sarsa", "after_update"),
                                                    ("double_q_learning", "after_update")])
def test_each_method_defaults_to_its_book_box(algorithm, default):
    config = ExperimentConfig(algorithm=algorithm)
    assert config.next_action is None
    assert config.drawn_next == default
    rule = method_rule(config)
    assert type(rule) is METHODS[algorithm].rule
    assert rule.draw_before == (default == "before_update")
    assert rule == method_rule(ExperimentConfig(algorithm=algorithm, next_action=default))
    assert config.name == ExperimentConfig(algorithm=algorithm, next_action=default).name == f"{algorithm}-decay"
    other = "before_update" if default == "after_update" else "after_update"
    moved = ExperimentConfig(algorithm=algorithm, next_action=other)
    assert moved.name == f"{algorithm}-decay-{other}"
    assert method_rule(moved).draw_before == (other == "before_update")


@pytest.mark.parametrize(("algorithm", "value", "allowed"), [
    ("q_learning", "first", "before_update, after_update"),
    ("sarsa", 1, "before_update, after_update"),
    ("n_step_sarsa", "before_update", "none for n_step_sarsa"),
    ("random", "after_update", "none for random"),
])
def test_bad_next_action_names_the_field_and_the_allowed_values(algorithm, value, allowed):
    with pytest.raises(ConfigError, match="next_action") as error:
        ExperimentConfig(algorithm=algorithm, next_action=value)
    assert allowed in str(error.value)


def test_next_action_is_recorded_and_changes_results():
    short = {"episodes": 2, "seeds": (0, 1), "eval_every": 0, "schedule": "constant"}
    box = run(ExperimentConfig(algorithm="q_learning", **short))
    moved = run(ExperimentConfig(algorithm="q_learning", next_action="before_update", **short))
    assert box.config.drawn_next == "after_update"
    assert moved.config.to_dict()["next_action"] == "before_update"
    assert not np.array_equal(box.records.visits, moved.records.visits)


@pytest.mark.parametrize("variant", ["reinforce", "reinforce_book"])
def test_reinforce_variants_differ_only_by_the_discount_of_the_step(variant):
    """The paper's Algorithm 3 steps by α G_t; the book's 13.3 box by α γ^t G_t. With γ = 1 they coincide."""
    rule = method_rule(ExperimentConfig(algorithm=variant))
    assert type(rule) is Reinforce
    assert rule == Reinforce(discount_gradient=variant == "reinforce_book", baseline_alpha=0.0)
    short = {"episodes": 3, "seeds": (0,), "eval_every": 0, "env": "CliffWalking-v1", "alpha": 0.1}
    for gamma, same in ((1.0, True), (0.9, False)):
        paper = run(ExperimentConfig(algorithm="reinforce", gamma=gamma, **short)).records.snapshots
        book = run(ExperimentConfig(algorithm="reinforce_book", gamma=gamma, **short)).records.snapshots
        assert np.array_equal(paper, book) == same
