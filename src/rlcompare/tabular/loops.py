"""Each method's training episode and its target policy's evaluation episode, chosen by the type of its rule when the
run loop compiles (:func:`train_episode`, :func:`evaluation_episode`).

The evaluation loop is built with the action of its target policy compiled in (:func:`evaluation_loop`): greedy in
the learnt values, the softmax policy for REINFORCE, uniform for the baseline. It draws from the evaluation's own
streams, in the order the training loops do (:mod:`rlcompare.tabular.episodes`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rlcompare.algorithms.linear import action_values
from rlcompare.algorithms.policies import greedy_action, uniform_legal_action
from rlcompare.algorithms.registry import METHODS, Method
from rlcompare.algorithms.softmax import sample_softmax
from rlcompare.compiled import njit
from rlcompare.tabular.borrowed import borrowed, kept
from rlcompare.tabular.episodes import (
    Episode,
    TargetAction,
    Traces,
    Values,
    lambda_episode,
    n_step_episode,
    one_step_loop,
    random_episode,
    reinforce_episode,
    values_of_w,
)
from rlcompare.tabular.state import Settings
from rlcompare.tabular.steps import COMPILED_ONLY, by_type, features_of, observe, reset, states_buffer, step


def greedy(values: Values = values_of_w) -> TargetAction:
    """The first action of highest value (``np.argmax``) in these values, as a loaded agent acts."""

    @njit(inline="always")
    def greedy_in(rule: Any, w: np.ndarray, w2: np.ndarray, s: int | np.ndarray, q: np.ndarray, scratch: np.ndarray,
                  rng: np.ndarray) -> int:
        return greedy_action(values(rule, w, w2, s, q, scratch))

    return greedy_in


@njit(inline="always")
def softmax_policy(rule: Any, w: np.ndarray, w2: np.ndarray, s: int | np.ndarray, q: np.ndarray,
                   scratch: np.ndarray, rng: np.ndarray) -> int:
    """REINFORCE's target policy is its behaviour: the softmax over its preferences."""
    return sample_softmax(action_values(w, s, q), scratch, rng)


@njit(inline="always")
def uniform(rule: Any, w: np.ndarray, w2: np.ndarray, s: int | np.ndarray, q: np.ndarray, scratch: np.ndarray,
            rng: np.ndarray) -> int:
    return uniform_legal_action(action_values(w, s, q), rng)


def evaluation_loop(target_action: TargetAction) -> Episode:
    """Episodes of the target policy whose action in a state is ``target_action(...)``."""

    @njit
    def evaluation_episode(rule: Any, settings: Settings, env: Any, features: Any, w: np.ndarray, w2: np.ndarray,
                           env_rng: np.ndarray, agent_rng: np.ndarray,
                           transitions: np.ndarray) -> tuple[float, int, bool]:
        """One episode of the target policy, drawing from the evaluation's own streams."""
        w, w2, agent_rng, transitions = borrowed((w, w2, agent_rng, transitions))
        n_actions = w.shape[1]
        owners = (states_buffer(features, 1), np.empty(n_actions), np.empty(n_actions))
        buffer, q, scratch = borrowed(owners)
        state = reset(env, env_rng)
        episode_return, steps, terminated = 0.0, 0, False
        while not terminated and steps < settings.max_steps:
            s = features_of(features, observe(env, state), buffer, 0)
            action = target_action(rule, w, w2, s, q, scratch, agent_rng)
            state, reward, terminated = step(env, state, action, transitions)
            episode_return += reward
            steps += 1
        kept(owners)
        return episode_return, steps, terminated

    return evaluation_episode


def _loops(method: Method) -> tuple[Episode, Episode]:
    """A method's training episode and its target policy's episode: greedy in the learned values, the softmax
    policy for REINFORCE, uniform for the baseline."""
    values = method.values or values_of_w
    if method.family == "one-step":
        update = method.update
        if update is None:
            raise ValueError(f"the one-step method {method.name!r} names no update (update_at)")
        return (one_step_loop(update, values, method.target_takes_next_action), evaluation_loop(greedy(values)))
    train, act = {"baseline": (random_episode, uniform), "n-step": (n_step_episode, greedy()),
                  "traces": (lambda_episode, greedy()), "policy gradient": (reinforce_episode, softmax_policy),
                  }[method.family]
    return train, evaluation_loop(act)


LOOPS = {m.rule: _loops(m) for m in METHODS.values()}
"""Each rule's training episode and evaluation episode."""


@by_type({rule: loops[0] for rule, loops in LOOPS.items()})
def train_episode(rule: Any, settings: Settings, env: Any, features: Any, w: np.ndarray, w2: np.ndarray, work: Traces,
                  epsilon: float, env_rng: np.ndarray, agent_rng: np.ndarray, transitions: np.ndarray,
                  visits: np.ndarray) -> tuple[float, int, bool]:
    """One training episode of the rule's method: ``(return, steps, terminated)``."""
    raise NotImplementedError(COMPILED_ONLY)


@by_type({rule: loops[1] for rule, loops in LOOPS.items()})
def evaluation_episode(rule: Any, settings: Settings, env: Any, features: Any, w: np.ndarray, w2: np.ndarray,
                       env_rng: np.ndarray, agent_rng: np.ndarray, transitions: np.ndarray) -> tuple[float, int, bool]:
    """One episode of the rule's target policy: ``(return, steps, terminated)``."""
    raise NotImplementedError(COMPILED_ONLY)
