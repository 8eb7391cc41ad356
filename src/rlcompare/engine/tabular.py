"""The fast path: one-step tabular control on Mountain Car's grid, the paper's setting.

The general kernel (:mod:`rlcompare.engine.kernel`) runs every algorithm on any features; this one runs
the one-step tabular methods (Q-Learning, SARSA, Expected SARSA, Double Q-Learning and the random
baseline) with the state as two scalars and the cell as one integer, which makes it two to three times
as fast per step (``rlcompare bench``). Both give bit-identical results for these configurations
(tested), share the run state and records, and draw from the same streams in the same order.

A run is one seed of one configuration. :func:`train_runs` spreads runs over threads (the compiled runs
release the GIL); each run owns its Q-table and six random streams (environment resets, the agent's
choices, stochastic transitions, and the same three for evaluation), so a run's result is the same
whatever thread runs it, however many threads there are, and however the episodes are split into chunks
between calls. Because the environment stream only draws start states, every algorithm sees the same start
state at the same episode of the same seed: common random numbers for paired comparisons.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rlcompare.algorithms.policies import epsilon_greedy_action, greedy_action, uniform_action
from rlcompare.algorithms.registry import DOUBLE_Q, EXPECTED_SARSA, METHODS, Q_LEARNING, RANDOM, SARSA
from rlcompare.algorithms.td import (
    double_q_target,
    expected_sarsa_target,
    q_learning_target,
    sarsa_target,
    td_update,
)
from rlcompare.engine.kernel import (  # noqa: F401 - the run state and records are shared by both kernels
    AGENT_STREAM,
    ENV_STREAM,
    EVAL_AGENT_STREAM,
    EVAL_ENV_STREAM,
    Records,
    RunState,
    Settings,
    allocate_records,
    draws_before_update,
    evaluation_round,
    initial_state,
    keep_snapshots,
    over_runs,
    record_episode,
)
from rlcompare.envs import mountain_car
from rlcompare.envs.discretize import UniformGrid, cell_index_2d
from rlcompare.rng import next_double

ALGORITHM_CODES = {name: m.code for name, m in METHODS.items() if m.one_step or m.family == "baseline"}
"""The methods this kernel runs: the random baseline and the one-step learners."""


@njit(cache=True)
def train_episode(
    settings: Settings,
    q: np.ndarray,
    q2: np.ndarray,
    grid: UniformGrid,
    epsilon: float,
    env_rng: np.ndarray,
    agent_rng: np.ndarray,
    visits: np.ndarray,
) -> tuple[float, int, bool]:
    """One training episode of Algorithm 1 (Q-Learning), Algorithm 2 (SARSA), Expected SARSA (6.6), Double
    Q-Learning (6.7, with ``q2``) or the random baseline, drawing the next action before or after the
    update as ``settings.next_action`` says (the general kernel's ``one_step_episode`` explains)."""
    algorithm, alpha, gamma = settings.algorithm, settings.alpha, settings.gamma
    before = draws_before_update(settings)
    n_actions = q.shape[1]
    target_epsilon = epsilon if settings.target_epsilon < 0 else settings.target_epsilon
    both = np.empty(n_actions)  # Double Q-Learning's behaviour values, Q1 + Q2
    position, velocity = mountain_car.reset(env_rng)
    state = cell_index_2d(grid, position, velocity)
    if algorithm == RANDOM:
        action = uniform_action(n_actions, agent_rng)
    elif algorithm == DOUBLE_Q:
        action = epsilon_greedy_action(_sum_rows(q[state], q2[state], both), epsilon, agent_rng)
    else:
        action = epsilon_greedy_action(q[state], epsilon, agent_rng)
    episode_return, steps = 0.0, 0
    while True:
        visits[state] += 1
        position, velocity, terminated = mountain_car.step(position, velocity, action)
        reward = mountain_car.REWARD
        episode_return += reward
        steps += 1
        truncated = not terminated and steps >= settings.max_steps
        terminal = terminated or (truncated and settings.truncation_is_terminal)
        next_state = cell_index_2d(grid, position, velocity)
        next_action = 0
        if algorithm == Q_LEARNING:
            if before and not terminal:
                next_action = epsilon_greedy_action(q[next_state], epsilon, agent_rng)
            td_update(q, state, action, q_learning_target(reward, q[next_state], gamma, terminal), alpha)
        elif algorithm == SARSA:
            taken = 0 if terminal else epsilon_greedy_action(q[next_state], epsilon, agent_rng)
            next_action = taken
            td_update(q, state, action, sarsa_target(reward, q[next_state, taken], gamma, terminal), alpha)
        elif algorithm == EXPECTED_SARSA:
            if before and not terminal:
                next_action = epsilon_greedy_action(q[next_state], epsilon, agent_rng)
            target = expected_sarsa_target(reward, q[next_state], target_epsilon, gamma, terminal)
            td_update(q, state, action, target, alpha)
        elif algorithm == DOUBLE_Q:
            if before and not terminal:
                next_action = epsilon_greedy_action(_sum_rows(q[next_state], q2[next_state], both), epsilon,
                                                    agent_rng)
            learner, other = (q, q2) if next_double(agent_rng) < 0.5 else (q2, q)
            target = double_q_target(reward, learner[next_state], other[next_state], gamma, terminal)
            td_update(learner, state, action, target, alpha)
        if terminated or truncated:
            break
        if algorithm == RANDOM:
            next_action = uniform_action(n_actions, agent_rng)
        elif not before:  # after the update, which may have changed Q(S', .)
            both_or_q = _sum_rows(q[next_state], q2[next_state], both) if algorithm == DOUBLE_Q else q[next_state]
            next_action = epsilon_greedy_action(both_or_q, epsilon, agent_rng)
        action = next_action
        state = next_state
    return episode_return, steps, terminated


@njit(inline="always")
def _sum_rows(a: np.ndarray, b: np.ndarray, out: np.ndarray) -> np.ndarray:
    for action in range(out.size):
        out[action] = a[action] + b[action]
    return out


@njit(cache=True)
def evaluation_episode(
    algorithm: int, q: np.ndarray, grid: UniformGrid, max_steps: int, env_rng: np.ndarray, agent_rng: np.ndarray
) -> tuple[float, int, bool]:
    """One episode of the target policy: greedy (first maximum) in ``q`` for the learners (Double
    Q-Learning passes ``Q1 + Q2``), uniform for the baseline."""
    position, velocity = mountain_car.reset(env_rng)
    episode_return, steps, terminated = 0.0, 0, False
    while not terminated and steps < max_steps:
        if algorithm == RANDOM:
            action = uniform_action(q.shape[1], agent_rng)
        else:
            action = greedy_action(q[cell_index_2d(grid, position, velocity)])
        position, velocity, terminated = mountain_car.step(position, velocity, action)
        episode_return += mountain_car.REWARD
        steps += 1
    return episode_return, steps, terminated


@njit(cache=True, nogil=True)
def train_run(
    run: int,
    settings: Settings,
    state: RunState,
    grid: UniformGrid,
    epsilons: np.ndarray,
    first_episode: int,
    stop_episode: int,
    records: Records,
) -> None:
    """Episodes ``[first_episode, stop_episode)`` of one run, with its evaluations and snapshots."""
    q, q2 = state.w[run], state.w2[run]
    double = settings.algorithm == DOUBLE_Q
    env_rng, agent_rng = state.rng[run, ENV_STREAM], state.rng[run, AGENT_STREAM]
    eval_env_rng, eval_agent_rng = state.rng[run, EVAL_ENV_STREAM], state.rng[run, EVAL_AGENT_STREAM]
    eval_episodes = records.eval_returns.shape[2]
    for episode in range(first_episode, stop_episode):
        ret, length, terminated = train_episode(
            settings, q, q2, grid, epsilons[episode], env_rng, agent_rng, records.visits[run]
        )
        record_episode(records.returns, records.lengths, records.terminated, (run, episode), ret, length, terminated)
        completed = episode + 1
        round_ = evaluation_round(settings, completed)
        if round_ >= 0:
            greedy_in = q + q2 if double else q
            for k in range(eval_episodes):
                ret, length, terminated = evaluation_episode(
                    settings.algorithm, greedy_in, grid, settings.max_steps, eval_env_rng, eval_agent_rng
                )
                record_episode(records.eval_returns, records.eval_lengths, records.eval_terminated, (run, round_, k),
                               ret, length, terminated)
        keep_snapshots(records, run, completed, q, q2, double)


def train_runs(
    settings: Settings,
    state: RunState,
    grid: UniformGrid,
    epsilons: np.ndarray,
    first_episode: int,
    stop_episode: int,
    records: Records,
) -> None:
    """Every run over episodes ``[first_episode, stop_episode)``, runs spread over threads."""
    over_runs(lambda run: train_run(run, settings, state, grid, epsilons, first_episode, stop_episode, records),
              state.w.shape[0])
