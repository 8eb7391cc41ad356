"""Fused training kernels: every algorithm, many runs at once, one core each.

A run is one seed of one configuration. :func:`train_runs` spreads runs over threads (the compiled runs
release the GIL); each run owns its weights and six random streams (environment resets, the agent's
choices, stochastic transitions, and the same three for evaluation), so a run's result is the same
whatever thread runs it, however many threads there are, and however the episodes are split into chunks
between calls. The environment stream only draws start states (stochastic outcomes have a stream of their
own), so every algorithm sees the same start state at the same episode of the same seed, on every
environment: common random numbers for paired comparisons.

The environment is a port (Mountain Car, CartPole, Acrobot, a table) stepped here, or any other Gymnasium
environment stepped through its own API (:mod:`rlcompare.envs.gymnasium_env`); its state is a small
float64 vector ``x`` and what the agent sees is Gymnasium's observation of it, rounded to float32.

Values are linear in binary features, ``q(s, a) = sum of w[i, a] over the active features i of s``
(Sutton and Barto, 9.5 and 10.1). With the uniform grid one feature is active and ``w`` is the Q-table of
the paper; with tile coding one feature per tiling is active; a table environment's state is its own
feature. One episode loop per family of methods:

- one-step: Q-Learning (6.5, Algorithm 1), SARSA (6.4, Algorithm 2), Expected SARSA (6.6), Double
  Q-Learning (6.7) and the random baseline;
- n-step SARSA (7.2);
- SARSA(λ) and Watkins's Q(λ) with accumulating or replacing traces (12.7, 12.10);
- REINFORCE, with or without a learned state-value baseline (13.3, 13.4; the paper's Algorithm 3).
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import NamedTuple

import numba
import numpy as np
from numba import njit, objmode

from rlcompare.algorithms.policies import epsilon_greedy_action, greedy_action, uniform_action
from rlcompare.algorithms.registry import (  # noqa: F401 - the codes are the kernels' too
    DOUBLE_Q,
    EXPECTED_SARSA,
    METHODS,
    N_STEP_SARSA,
    Q_LAMBDA,
    Q_LEARNING,
    RANDOM,
    REINFORCE,
    SARSA,
    SARSA_LAMBDA,
)
from rlcompare.algorithms.softmax import sample_softmax, softmax
from rlcompare.algorithms.td import (
    double_q_target,
    expected_sarsa_target,
    q_learning_target,
    sarsa_target,
)
from rlcompare.envs import acrobot, cartpole, gymnasium_env, mountain_car, table
from rlcompare.envs.discretize import UniformGrid, cell_of
from rlcompare.envs.table import TableEnv
from rlcompare.envs.tiles import TileCoding, active_tiles_at
from rlcompare.rng import next_double, stream_state

ALGORITHM_CODES = {name: m.code for name, m in METHODS.items()}
MOUNTAIN_CAR, TABLE, CARTPOLE, ACROBOT, GYMNASIUM = range(5)
GRID, TILES, ONE_HOT = 0, 1, 2
DRAW_AS_BOX, DRAW_BEFORE_UPDATE, DRAW_AFTER_UPDATE = range(3)
"""Codes of ``Settings.next_action``: when a one-step method draws A'."""
ENV_STREAM, AGENT_STREAM, EVAL_ENV_STREAM, EVAL_AGENT_STREAM, TRANSITION_STREAM, EVAL_TRANSITION_STREAM = range(6)
STREAMS = 6


class Env(NamedTuple):
    """Which dynamics to step: a port, or a Gymnasium environment through the adapter."""

    kind: int
    max_position: float  # Mountain Car's right bound
    table: TableEnv
    n_actions: int
    transitions: np.ndarray  # TABLE: the stream (uint64[4]) its outcomes are drawn from; ``train_run`` gives each
    # run its own (``env_instance``)
    state_size: int = 2  # length of the state vector ``x``
    observation_size: int = 2  # length of the observation the features read
    handle: int = -1  # GYMNASIUM: the environments opened by ``gymnasium_env.opened``
    instance: int = 0  # GYMNASIUM: which of them, ``2 * run`` training and ``2 * run + 1`` evaluation


class Features(NamedTuple):
    """How a state becomes active feature indices."""

    kind: int
    grid: UniformGrid
    tiles: TileCoding
    n_features: int
    n_active: int


class Settings(NamedTuple):
    """Scalars of one configuration, as the kernels read them (the fast tabular one reads the first six).

    Keep the types as annotated: another type compiles the kernels anew."""

    algorithm: int
    alpha: float
    gamma: float
    max_steps: int
    truncation_is_terminal: bool
    eval_every: int
    n: int = 1  # n-step SARSA's n
    lam: float = 0.0  # λ of the trace methods
    replacing: bool = True  # replacing traces instead of accumulating ones
    target_epsilon: float = -1.0  # Expected SARSA's target-policy ε; negative: the behaviour ε (on-policy)
    baseline_alpha: float = 0.0  # REINFORCE's baseline step size; 0: no baseline
    next_action: int = DRAW_AS_BOX  # one-step methods: draw A' before or after updating Q(S, A), or as the
    # method's box does (SARSA before, the others after)
    discount_gradient: bool = True  # REINFORCE: scale the step at time t by γ^t (the book's 13.3 box)


class Records(NamedTuple):
    """What training writes, indexed by run first; filled in place, chunk by chunk."""

    returns: np.ndarray  # (runs, episodes) float64: behaviour return of each episode
    lengths: np.ndarray  # (runs, episodes) int64
    terminated: np.ndarray  # (runs, episodes) bool: reached a terminal state before the limit
    eval_returns: np.ndarray  # (runs, rounds, eval_episodes) float64: target-policy returns
    eval_lengths: np.ndarray  # (runs, rounds, eval_episodes) int64
    eval_terminated: np.ndarray  # (runs, rounds, eval_episodes) bool
    snapshots: np.ndarray  # (runs, stages, features, actions) float64: weights at named stages
    snapshot_episodes: np.ndarray  # (stages,) int64: episodes completed when each snapshot is taken
    visits: np.ndarray  # (runs, features) int64: training steps taken with each feature active


class RunState(NamedTuple):
    """What carries over from one chunk of episodes to the next."""

    w: np.ndarray  # (runs, features, actions) float64, initialised to 0 as in the paper
    w2: np.ndarray  # (runs, features, actions): Double Q-Learning's second estimate; REINFORCE's baseline in [:, :, 0]
    rng: np.ndarray  # (runs, 6, 4) uint64: the environment (resets), agent, evaluation environment and
    # evaluation agent streams of each run, then the transitions of training and of evaluation


def initial_state(seeds: list[int], n_features: int, n_actions: int) -> RunState:
    """Zero weights and per-run streams. The environment stream of seed ``s`` is ``PCG64(s)``, so its
    start states are those of Gymnasium's ``env.reset(seed=s)`` followed by plain resets; the others are
    the children of ``SeedSequence(s)``. Resets and transitions draw from separate streams, so the start
    state of episode k is the same for every method, stochastic environments included."""
    rng = np.empty((len(seeds), STREAMS, 4), dtype=np.uint64)
    for run, seed in enumerate(seeds):
        agent, eval_env, eval_agent, transition, eval_transition = np.random.SeedSequence(seed).spawn(5)
        rng[run, ENV_STREAM] = stream_state(seed)
        rng[run, AGENT_STREAM] = stream_state(agent)
        rng[run, EVAL_ENV_STREAM] = stream_state(eval_env)
        rng[run, EVAL_AGENT_STREAM] = stream_state(eval_agent)
        rng[run, TRANSITION_STREAM] = stream_state(transition)
        rng[run, EVAL_TRANSITION_STREAM] = stream_state(eval_transition)
    shape = (len(seeds), n_features, n_actions)
    return RunState(w=np.zeros(shape), w2=np.zeros(shape), rng=rng)


def allocate_records(
    runs: int, episodes: int, rounds: int, eval_episodes: int, snapshot_episodes: np.ndarray, w_shape: tuple
) -> Records:
    return Records(
        returns=np.zeros((runs, episodes)),
        lengths=np.zeros((runs, episodes), dtype=np.int64),
        terminated=np.zeros((runs, episodes), dtype=np.bool_),
        eval_returns=np.zeros((runs, rounds, eval_episodes)),
        eval_lengths=np.zeros((runs, rounds, eval_episodes), dtype=np.int64),
        eval_terminated=np.zeros((runs, rounds, eval_episodes), dtype=np.bool_),
        snapshots=np.zeros((runs, snapshot_episodes.size, *w_shape)),
        snapshot_episodes=np.asarray(snapshot_episodes, dtype=np.int64),
        visits=np.zeros((runs, w_shape[0]), dtype=np.int64),
    )


# --- environment and features -------------------------------------------------------------------------


@njit(inline="always")
def env_reset(env: Env, x: np.ndarray, rng: np.ndarray) -> None:
    """Write a start state into ``x``."""
    if env.kind == MOUNTAIN_CAR:
        x[0], x[1] = mountain_car.reset(rng)
    elif env.kind == TABLE:
        x[0] = table.reset(env.table, rng)
    elif env.kind == CARTPOLE:
        cartpole.reset(x, rng)
    elif env.kind == ACROBOT:
        acrobot.reset(x, rng)
    else:
        _gymnasium_reset(env.handle, env.instance, x)


@njit(inline="always")
def env_step(env: Env, x: np.ndarray, action: int) -> tuple[float, bool]:
    """One transition of ``x`` in place: ``(reward, terminated)``; a table draws its outcome from
    ``env.transitions``."""
    if env.kind == MOUNTAIN_CAR:
        x[0], x[1], terminated = mountain_car.step(x[0], x[1], action, env.max_position)
        return mountain_car.REWARD, terminated
    if env.kind == TABLE:
        next_state, reward, ends = table.step(env.table, int(x[0]), action, env.transitions)
        x[0] = next_state
        return reward, ends
    if env.kind == CARTPOLE:
        return cartpole.REWARD, cartpole.step(x, action)
    if env.kind == ACROBOT:
        return acrobot.step(x, action)
    return _gymnasium_step(env.handle, env.instance, action, x)


@njit
def _gymnasium_reset(handle: int, instance: int, x: np.ndarray) -> None:
    with objmode():
        gymnasium_env.reset(handle, instance, x)


@njit
def _gymnasium_step(handle: int, instance: int, action: int, x: np.ndarray) -> tuple[float, bool]:
    with objmode(reward="float64", terminated="boolean"):
        reward, terminated = gymnasium_env.step(handle, instance, action, x)
    return reward, terminated


@njit(inline="always")
def observe(env: Env, features: Features, x: np.ndarray, obs: np.ndarray, actives: np.ndarray, row: int) -> None:
    """Write Gymnasium's observation of state ``x`` into ``obs``, and the indices of its active features into
    ``actives[row]``.

    Feature lists live as rows of one array and are addressed by row: taking a view of a row on every step
    costs as much as the rest of a tabular step.
    """
    if env.kind == ACROBOT:
        acrobot.observe(x, obs)
    else:
        for k in range(obs.size):
            obs[k] = np.float32(x[k])
    if features.kind == GRID:
        actives[row, 0] = cell_of(features.grid, obs)
    elif features.kind == TILES:
        active_tiles_at(features.tiles, obs, actives, row)
    else:
        actives[row, 0] = int(obs[0])


# --- linear values --------------------------------------------------------------------------------------


@njit(inline="always")
def action_value(w: np.ndarray, actives: np.ndarray, row: int, action: int) -> float:
    """``q(s, action)``: the sum of the weights of the features active in ``s``."""
    total = 0.0
    for k in range(actives.shape[1]):
        total += w[actives[row, k], action]
    return total


@njit(inline="always")
def action_values(w: np.ndarray, actives: np.ndarray, row: int, out: np.ndarray) -> np.ndarray:
    """``q(s, a)`` for every action."""
    for a in range(w.shape[1]):
        out[a] = action_value(w, actives, row, a)
    return out


@njit(inline="always")
def add_to_action(w: np.ndarray, actives: np.ndarray, row: int, action: int, amount: float) -> None:
    """Semi-gradient step on ``q(s, action)``: its gradient is 1 on each active feature (9.5)."""
    for k in range(actives.shape[1]):
        w[actives[row, k], action] += amount


@njit(inline="always")
def count_visit(visits: np.ndarray, actives: np.ndarray, row: int) -> None:
    for k in range(actives.shape[1]):
        visits[actives[row, k]] += 1


@njit(inline="always")
def _behaviour_values(settings: Settings, w: np.ndarray, w2: np.ndarray, actives: np.ndarray, row: int,
                      q: np.ndarray, scratch: np.ndarray) -> np.ndarray:
    """The values the behaviour policy is greedy in: ``Q1 + Q2`` for Double Q-Learning, else ``q``."""
    action_values(w, actives, row, q)
    if settings.algorithm == DOUBLE_Q:
        q += action_values(w2, actives, row, scratch)
    return q


# --- one-step methods -----------------------------------------------------------------------------------



@njit
def one_step_episode(
    settings: Settings, env: Env, features: Features, w: np.ndarray, w2: np.ndarray, epsilon: float,
    env_rng: np.ndarray, agent_rng: np.ndarray, visits: np.ndarray,
) -> tuple[float, int, bool]:
    """One episode of Q-Learning, SARSA, Expected SARSA, Double Q-Learning or the random baseline.

    ``settings.next_action`` says when the next action A' is drawn: before the update of
    ``q(S, A)``, from the values the target bootstraps on (SARSA's box, Algorithm 2), or after it, at the top
    of the loop (Q-Learning's box, Algorithm 1). SARSA drawing after the update still needs an A' for its
    target: it draws one before the update and takes a fresh draw after it (``docs/why.md``).
    """
    algorithm, alpha, gamma = settings.algorithm, settings.alpha, settings.gamma
    before = draws_before_update(settings)
    n_actions = w.shape[1]
    target_epsilon = epsilon if settings.target_epsilon < 0 else settings.target_epsilon
    actives = np.empty((2, features.n_active), np.int64)  # rows ``now`` and ``1 - now``: S and S'
    q, q_next, scratch = np.empty(n_actions), np.empty(n_actions), np.empty(n_actions)
    now = 0
    x, obs = np.empty(env.state_size), np.empty(env.observation_size)
    env_reset(env, x, env_rng)
    observe(env, features, x, obs, actives, now)
    if algorithm == RANDOM:
        action = uniform_action(n_actions, agent_rng)
    else:
        action = epsilon_greedy_action(_behaviour_values(settings, w, w2, actives, now, q, scratch), epsilon,
                                       agent_rng)
    episode_return, steps, terminated = 0.0, 0, False
    while True:
        then = 1 - now
        count_visit(visits, actives, now)
        reward, terminated = env_step(env, x, action)
        episode_return += reward
        steps += 1
        truncated = not terminated and steps >= settings.max_steps
        terminal = terminated or (truncated and settings.truncation_is_terminal)
        observe(env, features, x, obs, actives, then)
        if algorithm == RANDOM:
            if terminated or truncated:
                break
            action = uniform_action(n_actions, agent_rng)
            now = then
            continue
        next_action = 0
        if algorithm != DOUBLE_Q:
            action_values(w, actives, then, q_next)
        if before and not terminal:
            values = _behaviour_values(settings, w, w2, actives, then, q, scratch) if algorithm == DOUBLE_Q else q_next
            next_action = epsilon_greedy_action(values, epsilon, agent_rng)
        if algorithm == DOUBLE_Q:
            if next_double(agent_rng) < 0.5:
                _double_q_update(w, w2, actives, now, action, reward, alpha, gamma, terminal, q_next, scratch)
            else:
                _double_q_update(w2, w, actives, now, action, reward, alpha, gamma, terminal, q_next, scratch)
        else:
            if algorithm == SARSA:
                taken = next_action if before or terminal else epsilon_greedy_action(q_next, epsilon, agent_rng)
                target = sarsa_target(reward, q_next[taken], gamma, terminal)
            elif algorithm == Q_LEARNING:
                target = q_learning_target(reward, q_next, gamma, terminal)
            else:
                target = expected_sarsa_target(reward, q_next, target_epsilon, gamma, terminal)
            add_to_action(w, actives, now, action, alpha * (target - action_value(w, actives, now, action)))
        if terminated or truncated:
            break
        if not before:  # after the update, which may have changed q(S', .)
            next_action = epsilon_greedy_action(_behaviour_values(settings, w, w2, actives, then, q, scratch),
                                                epsilon, agent_rng)
        action = next_action
        now = then
    return episode_return, steps, terminated


@njit(inline="always")
def draws_before_update(settings: Settings) -> bool:
    """Whether a one-step method draws its next action before updating ``q(S, A)``."""
    if settings.next_action == DRAW_AS_BOX:
        return settings.algorithm == SARSA
    return settings.next_action == DRAW_BEFORE_UPDATE


@njit(inline="always")
def _double_q_update(
    learner: np.ndarray, other: np.ndarray, actives: np.ndarray, now: int, action: int, reward: float,
    alpha: float, gamma: float, terminal: bool, q_next: np.ndarray, scratch: np.ndarray,
) -> None:
    """Double Q-Learning (6.7): ``learner`` picks the next action, ``other`` values it."""
    then = 1 - now
    target = double_q_target(reward, action_values(learner, actives, then, q_next),
                             action_values(other, actives, then, scratch), gamma, terminal)
    add_to_action(learner, actives, now, action, alpha * (target - action_value(learner, actives, now, action)))


# --- n-step SARSA ---------------------------------------------------------------------------------------


@njit
def n_step_sarsa_episode(
    settings: Settings, env: Env, features: Features, w: np.ndarray, epsilon: float,
    env_rng: np.ndarray, agent_rng: np.ndarray, visits: np.ndarray,
) -> tuple[float, int, bool]:
    """n-step SARSA (7.2): ``G = R_{τ+1} + γ R_{τ+2} + ... + γ^n q(S_{τ+n}, A_{τ+n})`` updates ``q(S_τ, A_τ)``.

    States, actions and rewards live in ring buffers of ``n + 1`` entries. A time-limit cut bootstraps
    from ``q(S_T, A_T)``, with ``A_T`` drawn from the behaviour policy, unless it is treated as terminal.
    """
    n, alpha, gamma = settings.n, settings.alpha, settings.gamma
    n_actions, n_active = w.shape[1], features.n_active
    size = n + 1
    actives = np.empty((size, n_active), np.int64)
    actions = np.zeros(size, np.int64)
    rewards = np.zeros(size)
    q = np.empty(n_actions)
    x, obs = np.empty(env.state_size), np.empty(env.observation_size)
    env_reset(env, x, env_rng)
    observe(env, features, x, obs, actives, 0)
    actions[0] = epsilon_greedy_action(action_values(w, actives, 0, q), epsilon, agent_rng)
    horizon = np.iinfo(np.int64).max  # T
    bootstrap_end = False  # whether the return at T is completed by q(S_T, A_T) (a time-limit cut)
    episode_return, t, terminated = 0.0, 0, False
    while True:
        if t < horizon:
            now, later = t % size, (t + 1) % size
            count_visit(visits, actives, now)
            reward, terminated = env_step(env, x, actions[now])
            episode_return += reward
            rewards[later] = reward
            observe(env, features, x, obs, actives, later)
            truncated = not terminated and t + 1 >= settings.max_steps
            if terminated or truncated:
                horizon = t + 1
                bootstrap_end = truncated and not settings.truncation_is_terminal
            if not terminated and not (truncated and settings.truncation_is_terminal):
                actions[later] = epsilon_greedy_action(action_values(w, actives, later, q), epsilon, agent_rng)
        tau = t - n + 1
        if tau >= 0:
            ret = 0.0
            for k in range(tau + 1, min(tau + n, horizon) + 1):
                ret += gamma ** (k - tau - 1) * rewards[k % size]
            end = min(tau + n, horizon)
            if tau + n < horizon or bootstrap_end:
                ret += gamma ** (end - tau) * action_value(w, actives, end % size, actions[end % size])
            start = tau % size
            q_tau = action_value(w, actives, start, actions[start])
            add_to_action(w, actives, start, actions[start], alpha * (ret - q_tau))
        if tau == horizon - 1:
            break
        t += 1
    return episode_return, horizon, terminated


# --- eligibility traces ---------------------------------------------------------------------------------


@njit
def lambda_episode(
    settings: Settings, env: Env, features: Features, w: np.ndarray, z: np.ndarray, touched: np.ndarray,
    listed: np.ndarray, epsilon: float, env_rng: np.ndarray, agent_rng: np.ndarray, visits: np.ndarray,
) -> tuple[float, int, bool]:
    """SARSA(λ) (12.7) or Watkins's Q(λ) (12.10) with binary features, accumulating or replacing traces.

    ``z`` holds the traces; only the pairs listed in ``touched`` (flagged in ``listed``) can be non-zero, so
    decaying or cutting the traces costs the number of pairs visited in the episode, not the size of ``w``.
    Q(λ) cuts every trace after an exploratory (non-greedy) action.
    """
    alpha, gamma, lam = settings.alpha, settings.gamma, settings.lam
    watkins = settings.algorithm == Q_LAMBDA
    n_actions, n_active = w.shape[1], features.n_active
    actives = np.empty((2, n_active), np.int64)  # rows ``now`` and ``1 - now``: S and S'
    q_next = np.empty(n_actions)
    n_touched, now = 0, 0
    x, obs = np.empty(env.state_size), np.empty(env.observation_size)
    env_reset(env, x, env_rng)
    observe(env, features, x, obs, actives, now)
    action = epsilon_greedy_action(action_values(w, actives, now, q_next), epsilon, agent_rng)
    episode_return, steps, terminated = 0.0, 0, False
    while True:
        then = 1 - now
        count_visit(visits, actives, now)
        reward, terminated = env_step(env, x, action)
        episode_return += reward
        steps += 1
        truncated = not terminated and steps >= settings.max_steps
        terminal = terminated or (truncated and settings.truncation_is_terminal)
        delta = reward - action_value(w, actives, now, action)
        for k in range(n_active):
            i = actives[now, k]
            if not listed[i * n_actions + action]:
                listed[i * n_actions + action] = True
                touched[n_touched] = i * n_actions + action
                n_touched += 1
            z[i, action] = 1.0 if settings.replacing else z[i, action] + 1.0
        observe(env, features, x, obs, actives, then)
        next_action = 0
        if not terminal:
            action_values(w, actives, then, q_next)
            next_action = epsilon_greedy_action(q_next, epsilon, agent_rng)
            delta += gamma * (q_next.max() if watkins else q_next[next_action])
        step_size = alpha * delta
        for k in range(n_touched):
            i, a = divmod(touched[k], n_actions)
            w[i, a] += step_size * z[i, a]
        if terminated or truncated:
            break
        if watkins and q_next[next_action] < q_next.max():
            n_touched = _clear_traces(z, touched, listed, n_touched)
        else:
            decay = gamma * lam
            for k in range(n_touched):
                i, a = divmod(touched[k], n_actions)
                z[i, a] *= decay
        now, action = then, next_action
    _clear_traces(z, touched, listed, n_touched)  # fresh traces for the next episode
    return episode_return, steps, terminated


@njit(inline="always")
def _clear_traces(z: np.ndarray, touched: np.ndarray, listed: np.ndarray, n_touched: int) -> int:
    for k in range(n_touched):
        i, a = divmod(touched[k], z.shape[1])
        z[i, a] = 0.0
        listed[touched[k]] = False
    return 0


# --- REINFORCE ------------------------------------------------------------------------------------------


@njit
def reinforce_episode(
    settings: Settings, env: Env, features: Features, theta: np.ndarray, baseline: np.ndarray,
    env_rng: np.ndarray, agent_rng: np.ndarray, visits: np.ndarray,
) -> tuple[float, int, bool]:
    """REINFORCE with a softmax policy over action preferences ``h(s, a) = sum of theta[i, a]`` over active
    features, and optionally a learned state-value baseline ``v(s) = sum of baseline[i, 0]`` (13.4).

    ``theta += alpha * gamma^t * G_t * grad ln pi(A_t | S_t)`` as the book's 13.3 box writes it, or without
    the ``gamma^t`` as the paper's Algorithm 3 does (``settings.discount_gradient``). A time-limit cut ends
    the return where it is."""
    alpha, gamma, baseline_alpha = settings.alpha, settings.gamma, settings.baseline_alpha
    n_actions, n_active, limit = theta.shape[1], features.n_active, settings.max_steps
    actives = np.empty((limit, n_active), np.int64)
    actions = np.empty(limit, np.int64)
    rewards = np.empty(limit)
    h, pi = np.empty(n_actions), np.empty(n_actions)
    x, obs = np.empty(env.state_size), np.empty(env.observation_size)
    env_reset(env, x, env_rng)
    episode_return, steps, terminated = 0.0, 0, False
    while not terminated and steps < limit:
        observe(env, features, x, obs, actives, steps)
        count_visit(visits, actives, steps)
        action = sample_softmax(action_values(theta, actives, steps, h), pi, agent_rng)
        actions[steps] = action
        reward, terminated = env_step(env, x, action)
        rewards[steps] = reward
        episode_return += reward
        steps += 1
    ret = 0.0
    returns = np.empty(steps)
    for t in range(steps - 1, -1, -1):
        ret = rewards[t] + gamma * ret
        returns[t] = ret
    discount = 1.0
    for t in range(steps):
        delta = returns[t]
        if baseline_alpha > 0.0:
            delta -= action_value(baseline, actives, t, 0)
            add_to_action(baseline, actives, t, 0, baseline_alpha * delta)
        softmax(action_values(theta, actives, t, h), pi)
        scale = alpha * (discount if settings.discount_gradient else 1.0) * delta
        for a in range(n_actions):
            gradient = (1.0 if a == actions[t] else 0.0) - pi[a]  # d ln pi(A_t | S_t) / d h(S_t, a)
            add_to_action(theta, actives, t, a, scale * gradient)
        discount *= gamma
    return episode_return, steps, terminated


# --- evaluation and the run loop ------------------------------------------------------------------------


@njit
def evaluation_episode(
    settings: Settings, env: Env, features: Features, w: np.ndarray, w2: np.ndarray, env_rng: np.ndarray,
    agent_rng: np.ndarray,
) -> tuple[float, int, bool]:
    """One episode of the target policy: greedy (first maximum) in the learned values, the softmax policy
    for REINFORCE, uniform for the baseline. The environment and the policy draw from the evaluation's own
    two streams."""
    n_actions, n_active = w.shape[1], features.n_active
    actives = np.empty((1, n_active), np.int64)
    q, scratch = np.empty(n_actions), np.empty(n_actions)
    x, obs = np.empty(env.state_size), np.empty(env.observation_size)
    env_reset(env, x, env_rng)
    episode_return, steps, terminated = 0.0, 0, False
    while not terminated and steps < settings.max_steps:
        observe(env, features, x, obs, actives, 0)
        if settings.algorithm == RANDOM:
            action = uniform_action(n_actions, agent_rng)
        elif settings.algorithm == REINFORCE:
            action = sample_softmax(action_values(w, actives, 0, q), scratch, agent_rng)
        else:
            action = greedy_action(_behaviour_values(settings, w, w2, actives, 0, q, scratch))
        reward, terminated = env_step(env, x, action)
        episode_return += reward
        steps += 1
    return episode_return, steps, terminated


@njit
def train_episode(
    settings: Settings, env: Env, features: Features, w: np.ndarray, w2: np.ndarray, z: np.ndarray,
    touched: np.ndarray, listed: np.ndarray, epsilon: float, env_rng: np.ndarray, agent_rng: np.ndarray,
    visits: np.ndarray,
) -> tuple[float, int, bool]:
    """One training episode of the configured algorithm."""
    algorithm = settings.algorithm
    if algorithm == N_STEP_SARSA:
        return n_step_sarsa_episode(settings, env, features, w, epsilon, env_rng, agent_rng, visits)
    if algorithm in (SARSA_LAMBDA, Q_LAMBDA):
        return lambda_episode(settings, env, features, w, z, touched, listed, epsilon, env_rng, agent_rng, visits)
    if algorithm == REINFORCE:
        return reinforce_episode(settings, env, features, w, w2, env_rng, agent_rng, visits)
    return one_step_episode(settings, env, features, w, w2, epsilon, env_rng, agent_rng, visits)


@njit(cache=True, nogil=True)
def train_run(
    run: int, settings: Settings, env: Env, features: Features, state: RunState, epsilons: np.ndarray,
    first_episode: int, stop_episode: int, records: Records,
) -> None:
    """Episodes ``[first_episode, stop_episode)`` of one run, with its evaluations and snapshots."""
    w, w2, rng = state.w[run], state.w2[run], state.rng[run]
    training = env_instance(env, 2 * run, rng[TRANSITION_STREAM])
    evaluation = env_instance(env, 2 * run + 1, rng[EVAL_TRANSITION_STREAM])
    traces = settings.algorithm == SARSA_LAMBDA or settings.algorithm == Q_LAMBDA
    z = np.zeros(w.shape) if traces else np.zeros((1, 1))
    touched, listed = np.empty(z.size, np.int64), np.zeros(z.size, np.bool_)
    eval_episodes = records.eval_returns.shape[2]
    for episode in range(first_episode, stop_episode):
        ret, length, terminated = train_episode(
            settings, training, features, w, w2, z, touched, listed, epsilons[episode], rng[ENV_STREAM],
            rng[AGENT_STREAM], records.visits[run],
        )
        record_episode(records.returns, records.lengths, records.terminated, (run, episode), ret, length, terminated)
        completed = episode + 1
        round_ = evaluation_round(settings, completed)
        if round_ >= 0:
            for k in range(eval_episodes):
                ret, length, terminated = evaluation_episode(settings, evaluation, features, w, w2,
                                                             rng[EVAL_ENV_STREAM], rng[EVAL_AGENT_STREAM])
                record_episode(records.eval_returns, records.eval_lengths, records.eval_terminated, (run, round_, k),
                               ret, length, terminated)
        keep_snapshots(records, run, completed, w, w2, settings.algorithm == DOUBLE_Q)


@njit(inline="always")
def env_instance(env: Env, instance: int, transitions: np.ndarray) -> Env:
    """``env`` naming one of the Gymnasium environments opened for it (ports ignore the instance), a table
    drawing its outcomes from ``transitions``."""
    return Env(env.kind, env.max_position, env.table, env.n_actions, transitions, env.state_size,
               env.observation_size, env.handle, instance)


@njit(inline="always")
def record_episode(returns: np.ndarray, lengths: np.ndarray, terminated: np.ndarray, at: tuple, ret: float,
                   length: int, ended: bool) -> None:
    """Write one episode's return, length and termination at index ``at`` (training or evaluation)."""
    returns[at], lengths[at], terminated[at] = ret, length, ended


@njit(inline="always")
def evaluation_round(settings: Settings, completed: int) -> int:
    """The evaluation round due after ``completed`` episodes, or -1 when none is."""
    if settings.eval_every > 0 and completed % settings.eval_every == 0:
        return completed // settings.eval_every - 1
    return -1


@njit(inline="always")
def keep_snapshots(records: Records, run: int, completed: int, w: np.ndarray, w2: np.ndarray, double: bool) -> None:
    """Copy the weights at every stage whose episode count is ``completed`` (Double Q-Learning: their mean)."""
    for stage in range(records.snapshot_episodes.size):
        if records.snapshot_episodes[stage] == completed:
            records.snapshots[run, stage] = (w + w2) / 2 if double else w


def train_runs(
    settings: Settings, env: Env, features: Features, state: RunState, epsilons: np.ndarray,
    first_episode: int, stop_episode: int, records: Records,
) -> None:
    """Every run over episodes ``[first_episode, stop_episode)``, runs spread over threads."""
    over_runs(lambda run: train_run(run, settings, env, features, state, epsilons, first_episode, stop_episode,
                                    records), state.w.shape[0])


def over_runs(train: Callable[[int], None], runs: int) -> None:
    """Call ``train(run)`` for every run on ``numba.get_num_threads()`` threads; the compiled runs release
    the GIL, and each writes only its own slices, so the order does not matter."""
    threads = min(numba.get_num_threads(), runs)
    if threads <= 1:
        for run in range(runs):
            train(run)
        return
    with ThreadPoolExecutor(threads) as pool:
        for future in [pool.submit(train, run) for run in range(runs)]:
            future.result()
