"""The greedy policy of a learnt table played from given start states, against the environment's own dynamics: the
games a study scores on a fixed evaluation set (the chess endgames' starts), where the engine's evaluation rounds
draw their starts from the reset stream."""

from __future__ import annotations

from typing import Any

import numpy as np

from rlcompare.algorithms.policies import greedy_action
from rlcompare.compiled import njit
from rlcompare.tabular.steps import step


@njit(cache=True)
def greedy_games(env: Any, q: np.ndarray, starts: np.ndarray, limit: int, rng: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One game from each start state, the greedy action (first maximum, as a loaded agent) at every step, outcomes
    drawn from ``rng``, cut after ``limit`` steps: ``(returns, lengths, terminated, last)``, ``last`` the final
    state and action as ``state * actions + action``."""
    returns = np.zeros(starts.size)
    lengths = np.full(starts.size, limit, np.int64)
    terminated = np.zeros(starts.size, np.bool_)
    last = np.empty(starts.size, np.int64)
    for game in range(starts.size):
        state = starts[game]
        for move in range(1, limit + 1):
            action = greedy_action(q[state])
            last[game] = state * q.shape[1] + action
            state, reward, ended = step(env, state, action, rng)
            returns[game] += reward
            if ended:
                terminated[game], lengths[game] = True, move
                break
    return returns, lengths, terminated, last
