"""Finite MDPs as precomputed tables, stepped by compiled code.

Each state-action pair has a few outcomes, each with a probability, a next state, a reward and whether
it ends the episode. Every reset and every step draws one uniform from the stream it is given and takes
the first outcome whose cumulative probability exceeds it, deterministic ones included, as Gymnasium's
``categorical_sample`` does; so a stream stays in step with the generator of Gymnasium's toy-text
environments, and a table reproduces them episode after episode, not only until the first reset. The
kernels give resets and steps separate streams (and the adapter gives Gymnasium's environments the same
two), so the start states of a seed are the same whatever the agent did before.
Small problems with known answers (a chain, a two-armed bandit) are written this way for tests, and so
is any gridworld whose dynamics fit in a table.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from rlcompare.compiled import njit
from rlcompare.rng import next_double


class TableEnv(NamedTuple):
    """``(states, actions, outcomes)`` tables; unused outcomes have probability 0."""

    next_state: np.ndarray  # int64
    reward: np.ndarray  # float64
    ends: np.ndarray  # bool: the outcome ends the episode (the next state is terminal)
    cumulative: np.ndarray  # float64, cumulative probability over outcomes; the last used one is 1
    start: np.ndarray  # (states,) float64 cumulative start distribution

    @property
    def n_states(self) -> int:
        return int(self.next_state.shape[0])

    @property
    def n_actions(self) -> int:
        return int(self.next_state.shape[1])


def make_table_env(
    outcomes: dict[tuple[int, int], list[tuple[float, int, float, bool]]], n_states: int, n_actions: int,
    start: dict[int, float],
) -> TableEnv:
    """Build from ``{(state, action): [(probability, next_state, reward, ends), ...]}``; missing pairs
    stay in place with reward 0."""
    width = max(len(v) for v in outcomes.values())
    shape = (n_states, n_actions, width)
    next_state = np.repeat(np.arange(n_states)[:, None, None], n_actions, axis=1).repeat(width, axis=2)
    reward, ends = np.zeros(shape), np.zeros(shape, dtype=np.bool_)
    cumulative = np.ones(shape)
    for (state, action), options in outcomes.items():
        probabilities = np.array([p for p, *_ in options])
        if not np.isclose(probabilities.sum(), 1.0):
            raise ValueError(f"outcomes of ({state}, {action}) sum to {probabilities.sum()}, not 1")
        for k, (_, target, r, done) in enumerate(options):
            next_state[state, action, k], reward[state, action, k], ends[state, action, k] = target, r, done
        cumulative[state, action, : len(options)] = np.cumsum(probabilities)
        cumulative[state, action, len(options) - 1 :] = 1.0
    start_cumulative = np.cumsum([start.get(s, 0.0) for s in range(n_states)])
    start_cumulative[-1] = 1.0
    return TableEnv(next_state, reward, ends, cumulative, start_cumulative)


def from_gymnasium(env_id: str, **kwargs: Any) -> TableEnv:
    """The table of a Gymnasium toy-text environment (CliffWalking-v1, FrozenLake-v1, Taxi-v4, ...), read
    from its own transition model ``P`` and start distribution, so stepping it equals stepping Gymnasium."""
    import gymnasium as gym

    env: Any = gym.make(env_id, **kwargs).unwrapped  # a toy-text environment: P and initial_state_distrib
    outcomes = {(s, a): [(p, int(target), float(r), bool(done)) for p, target, r, done in env.P[s][a]]
                for s in env.P for a in env.P[s]}
    start = {s: float(p) for s, p in enumerate(env.initial_state_distrib) if p > 0}
    return make_table_env(outcomes, env.observation_space.n, env.action_space.n, start)


def chain(length: int = 5, reward: float = 1.0) -> TableEnv:
    """States ``0 .. length - 1`` in a row, start at 0; action 1 moves right, action 0 stays. Leaving the
    last state to the right ends the episode with ``reward``; every other step gives 0. With discount γ,
    ``q*(s, right) = γ^(length - 1 - s) * reward`` and ``q*(s, stay) = γ q*(s, right)``."""
    outcomes = {}
    for s in range(length):
        outcomes[(s, 0)] = [(1.0, s, 0.0, False)]
        outcomes[(s, 1)] = [(1.0, s + 1, 0.0, False)] if s < length - 1 else [(1.0, s, reward, True)]
    return make_table_env(outcomes, length, 2, {0: 1.0})


def two_armed_bandit(p_left: float = 0.2, p_right: float = 0.8) -> TableEnv:
    """One state, two arms; arm ``a`` pays 1 with probability ``p_a``, else 0, and the episode ends."""
    outcomes = {(0, a): [(p, 0, 1.0, True), (1 - p, 0, 0.0, True)] for a, p in enumerate((p_left, p_right))}
    return make_table_env(outcomes, 1, 2, {0: 1.0})


@njit(inline="always")
def _draw(cumulative: np.ndarray, rng_state: np.ndarray) -> int:
    """``np.argmax(cumulative > u)`` for one uniform ``u``: Gymnasium's ``categorical_sample``."""
    u = next_double(rng_state)
    k = 0
    while k < cumulative.size - 1 and u >= cumulative[k]:
        k += 1
    return k


@njit(inline="always")
def reset(env: TableEnv, rng: np.ndarray) -> int:
    """A start state drawn from the start distribution."""
    return _draw(env.start, rng)


@njit(inline="always")
def step(env: TableEnv, state: int, action: int, rng: np.ndarray) -> tuple[int, float, bool]:
    """``(next_state, reward, ends)`` of one transition, its outcome drawn from ``rng``."""
    k = _draw(env.cumulative[state, action], rng)
    return env.next_state[state, action, k], env.reward[state, action, k], env.ends[state, action, k]


@njit(inline="always")
def observe(env: TableEnv, state: int) -> tuple[int]:
    """What Gymnasium returns: the state's index."""
    return (state,)
