"""What the compiled loops read and write: a configuration's common scalars, each run's weights and random
streams, and the records of training and evaluation.

A run is one seed of one configuration. Each owns its weights and six random streams (environment resets, the
agent's choices, stochastic transitions, and the same three for evaluation), so its result is the same whatever
thread runs it, however many threads there are, and however the episodes are split into chunks between calls.
The reset stream only draws start states, so every method sees the same start state at the same episode of the
same seed, on every environment: common random numbers for paired comparisons.
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import numpy as np

from rlcompare.rng import stream_state

ENV_STREAM, AGENT_STREAM, EVAL_ENV_STREAM, EVAL_AGENT_STREAM, TRANSITION_STREAM, EVAL_TRANSITION_STREAM = range(6)
STREAMS = 6


class Settings(NamedTuple):
    """The scalars every method reads (what a method reads beyond them is in its rule). Keep the types as
    annotated: another type compiles the loops anew."""

    alpha: float
    gamma: float
    max_steps: int
    truncation_as_terminal: bool
    eval_every: int
    legal_moves: bool = False
    """The environment's legal moves change with the state (masked by −∞ in the tables:
    :mod:`rlcompare.algorithms.policies`)."""


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

    w: np.ndarray  # (runs, features, actions) float64, initialised to 0 as in the paper (−∞ at illegal moves)
    w2: np.ndarray  # (runs, features, actions): Double Q-Learning's second estimate; REINFORCE's baseline in [:, :, 0]
    rng: np.ndarray  # (runs, 6, 4) uint64: the streams of each run, indexed by ENV_STREAM ... EVAL_TRANSITION_STREAM


def initial_state(seeds: list[int], n_features: int, n_actions: int, legal: np.ndarray | None = None) -> RunState:
    """Zero weights and per-run streams. The reset stream of seed ``s`` is ``PCG64(s)``, so its start states are
    those of Gymnasium's ``env.reset(seed=s)`` followed by plain resets; the others are the children of
    ``SeedSequence(s)``. ``legal``: ``(features, actions)`` bool, the legal moves of a game's states; an illegal
    move's weight is −∞ (:mod:`rlcompare.algorithms.policies`)."""
    rng = np.empty((len(seeds), STREAMS, 4), dtype=np.uint64)
    for run, seed in enumerate(seeds):
        rng[run] = seed_streams(int(seed))
    shape = (len(seeds), n_features, n_actions)
    w, w2 = np.zeros(shape), np.zeros(shape)
    if legal is not None:
        w[:, ~legal] = w2[:, ~legal] = -np.inf
    return RunState(w=w, w2=w2, rng=rng)


@functools.lru_cache(maxsize=2**17)
def seed_streams(seed: int) -> np.ndarray:
    """The starting states of the six streams of seed ``seed``, ``(6, 4)``, read-only. Cached: deriving them
    takes about 0.2 ms a seed, and a study of 50,000 runs asks for the same seeds in every configuration."""
    rng = np.empty((STREAMS, 4), dtype=np.uint64)
    agent, eval_env, eval_agent, transition, eval_transition = np.random.SeedSequence(seed).spawn(5)
    rng[ENV_STREAM] = stream_state(seed)
    rng[AGENT_STREAM] = stream_state(agent)
    rng[EVAL_ENV_STREAM] = stream_state(eval_env)
    rng[EVAL_AGENT_STREAM] = stream_state(eval_agent)
    rng[TRANSITION_STREAM] = stream_state(transition)
    rng[EVAL_TRANSITION_STREAM] = stream_state(eval_transition)
    rng.flags.writeable = False
    return rng


def allocate_records(
    runs: int, episodes: int, rounds: int, eval_episodes: int, snapshot_episodes: np.ndarray,
    w_shape: tuple[int, ...],
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
