"""One training episode loop per family of methods, written once for every environment, features and method of the
family; :mod:`rlcompare.tabular.loops` picks the method's loop by the type of its rule when the run loop compiles.

The one-step loop is built for each method with its update and the values it acts on compiled in
(:func:`one_step_loop`), as the evaluation loop is with the action of its target policy: a call chosen by type on
every step would cost a third of the speed, and inlining it at numba's level several times the compile time.

- one-step: Q-Learning (the paper's Algorithm 1), SARSA (Algorithm 2), Expected SARSA, Double Q-Learning;
- n-step SARSA (7.2); SARSA(λ) and Watkins's Q(λ) (12.7, 12.10); REINFORCE (13.3, 13.4; Algorithm 3);
- the random baseline.

Every loop draws from the same streams in the same order: the start state from ``env_rng``, the agent's choices
from ``agent_rng``, stochastic outcomes from ``transitions``. A time-limit cut is not terminal: the last target
bootstraps unless ``settings.truncation_as_terminal``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

from rlcompare.algorithms import nstep, traces
from rlcompare.algorithms.linear import action_value, action_values, add_to_action, count_visit
from rlcompare.algorithms.policies import (
    epsilon_greedy_action,
    largest,
    uniform_action,
    uniform_legal_action,
)
from rlcompare.algorithms.registry import METHODS
from rlcompare.algorithms.reinforce import episode_update
from rlcompare.algorithms.softmax import sample_softmax
from rlcompare.algorithms.td import Rates, Transition
from rlcompare.compiled import njit
from rlcompare.tabular.borrowed import borrowed, kept
from rlcompare.tabular.state import Settings
from rlcompare.tabular.steps import (
    COMPILED_ONLY,
    by_type,
    features_of,
    observe,
    reset,
    states_buffer,
    step,
)

Episode = Callable[..., tuple[float, int, bool]]
"""An episode loop (compiled): ``(return, steps, terminated)``."""
Values = Callable[..., np.ndarray]
"""``values(rule, w, w2, s, out, scratch)``: the action values a method acts on."""
TargetAction = Callable[..., int]
"""``target_action(rule, w, w2, s, q, scratch, rng)``: the action of a target policy."""


class Traces(NamedTuple):
    """The eligibility traces of a run and the list of the pairs they are non-zero on
    (:mod:`rlcompare.algorithms.traces`); a stub for the other families."""

    z: np.ndarray  # (features * actions,) float64: the trace of w[i, a] at i * actions + a
    touched: np.ndarray  # (features * actions,) int64: the listed pairs first
    listed: np.ndarray  # (features * actions,) bool


@njit(inline="always")
def _outcome(settings: Settings, steps: int, terminated: bool) -> tuple[bool, bool]:
    """``(truncated, terminal)`` after ``steps`` steps: cut by the limit, and whether the target stops there."""
    truncated = not terminated and steps >= settings.max_steps
    return truncated, terminated or (truncated and settings.truncation_as_terminal)


# --- one-step methods -----------------------------------------------------------------------------------


@njit(inline="always")
def values_of_w(rule: Any, w: np.ndarray, w2: np.ndarray, s: int | np.ndarray, out: np.ndarray,
                scratch: np.ndarray) -> np.ndarray:
    """``q(s, .)``: what a method acts on unless its entry says otherwise (Double Q-Learning's ``Q1 + Q2``)."""
    return action_values(w, s, out)


def one_step_loop(update: Callable[..., None], values: Values = values_of_w, target_takes_next_action: bool = False,
                  ) -> Episode:
    """The one-step loop (6.4-6.7) of a method with this update of ``q(S, A)`` and these behaviour values;
    ``target_takes_next_action``: its update reads the A' drawn before it (SARSA)."""

    @njit
    def one_step_episode(rule: Any, settings: Settings, env: Any, features: Any, w: np.ndarray, w2: np.ndarray,
                         work: Traces, epsilon: float, env_rng: np.ndarray, agent_rng: np.ndarray,
                         transitions: np.ndarray, visits: np.ndarray) -> tuple[float, int, bool]:
        """One episode. The next action A' is drawn before the update of ``q(S, A)`` (SARSA's box) or after it,
        at the top of the loop (Algorithm 1's), as ``rule.draw_before`` says."""
        w, w2, agent_rng, transitions, visits = borrowed((w, w2, agent_rng, transitions, visits))
        n_actions = w.shape[1]
        owners = (states_buffer(features, 2), np.empty(n_actions), np.empty(n_actions), np.empty(n_actions))
        buffer, q, q_next, scratch = borrowed(owners)  # the buffer holds S and S' in turn
        now = 0
        state = reset(env, env_rng)
        s = features_of(features, observe(env, state), buffer, now)
        masked = settings.legal_moves
        action = epsilon_greedy_action(values(rule, w, w2, s, q, scratch), epsilon, agent_rng, masked)
        episode_return, steps = 0.0, 0
        while True:
            count_visit(visits, s)
            state, reward, terminated = step(env, state, action, transitions)
            episode_return += reward
            steps += 1
            truncated, terminal = _outcome(settings, steps, terminated)
            now = 1 - now
            s_next = features_of(features, observe(env, state), buffer, now)
            next_action = 0
            if (rule.draw_before or target_takes_next_action) and not terminal:
                next_action = epsilon_greedy_action(values(rule, w, w2, s_next, q, scratch), epsilon, agent_rng,
                                                    masked)
            update(rule, w, w2, Transition(s, action, reward, s_next, next_action, terminal),
                   Rates(settings.alpha, settings.gamma, epsilon), agent_rng, q_next, scratch)
            if terminated or truncated:
                break
            if not rule.draw_before:  # after the update, which may have changed q(S', .)
                next_action = epsilon_greedy_action(values(rule, w, w2, s_next, q, scratch), epsilon, agent_rng,
                                                    masked)
            s, action = s_next, next_action
        kept(owners)
        return episode_return, steps, terminated

    return one_step_episode


# --- the random baseline --------------------------------------------------------------------------------


@njit
def random_episode(rule: Any, settings: Settings, env: Any, features: Any, w: np.ndarray, w2: np.ndarray,
                   work: Traces, epsilon: float, env_rng: np.ndarray, agent_rng: np.ndarray, transitions: np.ndarray,
                   visits: np.ndarray) -> tuple[float, int, bool]:
    """One episode of uniformly random legal actions; nothing is learned, the visits are counted."""
    w, w2, agent_rng, transitions, visits = borrowed((w, w2, agent_rng, transitions, visits))
    owners = (states_buffer(features, 1), np.empty(w.shape[1]))
    buffer, q = borrowed(owners)
    state = reset(env, env_rng)
    episode_return, steps, terminated = 0.0, 0, False
    s = features_of(features, observe(env, state), buffer, 0)
    action = _uniform(settings.legal_moves, w, s, q, agent_rng)
    while True:
        count_visit(visits, s)
        state, reward, terminated = step(env, state, action, transitions)
        episode_return += reward
        steps += 1
        if terminated or steps >= settings.max_steps:
            break
        s = features_of(features, observe(env, state), buffer, 0)
        action = _uniform(settings.legal_moves, w, s, q, agent_rng)
    kept(owners)
    return episode_return, steps, terminated


@njit(inline="always")
def _uniform(masked: bool, w: np.ndarray, s: int | np.ndarray, q: np.ndarray, rng: np.ndarray) -> int:
    """A uniform action; a uniform legal one where the environment has legal-move ``masked`` (read in ``q(s, .)``)."""
    if masked:
        return uniform_legal_action(action_values(w, s, q), rng)
    return uniform_action(w.shape[1], rng)


# --- n-step SARSA ---------------------------------------------------------------------------------------


@njit
def n_step_episode(rule: Any, settings: Settings, env: Any, features: Any, w: np.ndarray, w2: np.ndarray,
                   work: Traces, epsilon: float, env_rng: np.ndarray, agent_rng: np.ndarray, transitions: np.ndarray,
                   visits: np.ndarray) -> tuple[float, int, bool]:
    """n-step SARSA (7.2): the n-step return updates ``q(S_τ, A_τ)``. States, actions and rewards live in ring
    buffers of ``n + 1`` entries. A time-limit cut bootstraps from ``q(S_T, A_T)``, with ``A_T`` drawn from the
    behaviour policy, unless it is treated as terminal."""
    w, w2, agent_rng, transitions, visits = borrowed((w, w2, agent_rng, transitions, visits))
    n, alpha, gamma = rule.n, settings.alpha, settings.gamma
    size = n + 1
    owners = (states_buffer(features, size), np.zeros(size, np.int64), np.zeros(size), np.empty(w.shape[1]),
              nstep.powers(gamma, n))
    states, actions, rewards, q, discounts = borrowed(owners)
    state = reset(env, env_rng)
    masked = settings.legal_moves
    actions[0] = epsilon_greedy_action(action_values(w, features_of(features, observe(env, state), states, 0), q),
                                       epsilon, agent_rng, masked)
    horizon = np.iinfo(np.int64).max  # T
    bootstrap_end = False  # whether the return at T is completed by q(S_T, A_T) (a time-limit cut)
    episode_return, t, terminated = 0.0, 0, False
    while True:
        if t < horizon:
            now, later = t % size, (t + 1) % size
            count_visit(visits, states[now])
            state, reward, terminated = step(env, state, actions[now], transitions)
            episode_return += reward
            rewards[later] = reward
            s_later = features_of(features, observe(env, state), states, later)
            truncated, terminal = _outcome(settings, t + 1, terminated)
            if terminated or truncated:
                horizon = t + 1
                bootstrap_end = not terminal
            if not terminal:
                actions[later] = epsilon_greedy_action(action_values(w, s_later, q), epsilon, agent_rng, masked)
        tau = t - n + 1
        if tau >= 0:
            ret = nstep.n_step_rewards(rewards, tau, n, horizon, discounts)
            end = min(tau + n, horizon)
            if tau + n < horizon or bootstrap_end:
                ret += discounts[end - tau] * action_value(w, states[end % size], actions[end % size])
            start = tau % size
            s_tau, a_tau = states[start], actions[start]
            add_to_action(w, s_tau, a_tau, alpha * (ret - action_value(w, s_tau, a_tau)))
        if tau == horizon - 1:
            break
        t += 1
    kept(owners)
    return episode_return, horizon, terminated


# --- eligibility traces ---------------------------------------------------------------------------------


@njit
def lambda_episode(rule: Any, settings: Settings, env: Any, features: Any, w: np.ndarray, w2: np.ndarray,
                   work: Traces, epsilon: float, env_rng: np.ndarray, agent_rng: np.ndarray, transitions: np.ndarray,
                   visits: np.ndarray) -> tuple[float, int, bool]:
    """SARSA(λ) (12.7) or Watkins's Q(λ) (12.10) with binary features; Q(λ) cuts every trace after an
    exploratory (non-greedy) action."""
    alpha, gamma = settings.alpha, settings.gamma
    watkins = cuts_traces(rule)
    w, w2, agent_rng, transitions, visits = borrowed((w, w2, agent_rng, transitions, visits))
    z, touched, listed = borrowed(work)
    w_flat, n_actions = w.reshape(w.size), w.shape[1]
    owners = (states_buffer(features, 2), np.empty(n_actions))
    buffer, q_next = borrowed(owners)  # the buffer holds S and S' in turn
    n_touched, now = 0, 0
    state = reset(env, env_rng)
    s = features_of(features, observe(env, state), buffer, now)
    masked = settings.legal_moves
    action = epsilon_greedy_action(action_values(w, s, q_next), epsilon, agent_rng, masked)
    episode_return, steps = 0.0, 0
    while True:
        count_visit(visits, s)
        state, reward, terminated = step(env, state, action, transitions)
        episode_return += reward
        steps += 1
        truncated, terminal = _outcome(settings, steps, terminated)
        delta = reward - action_value(w, s, action)
        n_touched = traces.mark(z, touched, listed, n_touched, s, action, n_actions, rule.replacing)
        now = 1 - now
        s_next = features_of(features, observe(env, state), buffer, now)
        next_action, exploratory = 0, False
        if not terminal:
            values = action_values(w, s_next, q_next)
            next_action = epsilon_greedy_action(values, epsilon, agent_rng, masked)
            best = largest(values)
            exploratory = values[next_action] < best
            delta += gamma * (best if watkins else values[next_action])
        traces.apply(w_flat, z, touched, n_touched, alpha * delta)
        if terminated or truncated:
            break
        if watkins and exploratory:
            n_touched = traces.clear(z, touched, listed, n_touched)
        else:
            traces.decay(z, touched, n_touched, gamma * rule.lam)
        s, action = s_next, next_action
    traces.clear(z, touched, listed, n_touched)  # fresh traces for the next episode
    kept(owners)
    return episode_return, steps, terminated


@njit(inline="always")
def _false(rule: Any) -> bool:
    return False


@njit(inline="always")
def _true(rule: Any) -> bool:
    return True


@by_type({m.rule: _true for m in METHODS.values() if m.cuts_traces}, default=_false)
def cuts_traces(rule: Any) -> bool:
    """Whether the rule's method cuts every trace after an exploratory action (Watkins's Q(λ))."""
    raise NotImplementedError(COMPILED_ONLY)


# --- REINFORCE ------------------------------------------------------------------------------------------


@njit
def reinforce_episode(rule: Any, settings: Settings, env: Any, features: Any, w: np.ndarray, w2: np.ndarray,
                      work: Traces, epsilon: float, env_rng: np.ndarray, agent_rng: np.ndarray, transitions: np.ndarray,
                      visits: np.ndarray) -> tuple[float, int, bool]:
    """REINFORCE (13.3, 13.4): a softmax policy over the preferences ``w`` acts for a whole episode, then
    :func:`~rlcompare.algorithms.reinforce.episode_update` learns from it (the baseline's weights in
    ``w2[:, 0]``)."""
    w, w2, agent_rng, transitions, visits = borrowed((w, w2, agent_rng, transitions, visits))
    n_actions, limit = w.shape[1], settings.max_steps
    owners = (states_buffer(features, limit), np.empty(limit, np.int64), np.empty(limit), np.empty(n_actions),
              np.empty(n_actions))
    states, actions, rewards, h, pi = borrowed(owners)
    state = reset(env, env_rng)
    episode_return, steps, terminated = 0.0, 0, False
    while not terminated and steps < limit:
        s = features_of(features, observe(env, state), states, steps)
        count_visit(visits, s)
        action = sample_softmax(action_values(w, s, h), pi, agent_rng)
        actions[steps] = action
        state, reward, terminated = step(env, state, action, transitions)
        rewards[steps] = reward
        episode_return += reward
        steps += 1
    episode_update(rule, w, w2, states, actions, rewards, steps, settings.alpha, settings.gamma, h, pi)
    kept(owners)
    return episode_return, steps, terminated
