"""``rlcompare bench chess``: learner moves per second of Q-Learning on the chess endgames, rlcompare's kernel on 1
and all threads beside a plain kernel written for the endgames alone, measured in turn in one run.

The plain kernel draws from the same streams in the same order as the engine, so it learns the same table: the
benchmark checks that its returns are the engine's before it reports a ratio.
"""

from __future__ import annotations

import statistics
import time

import numpy as np

from rlcompare.algorithms.policies import greedy_action_random_ties
from rlcompare.bench.harness import Measurement, bench_config, kernel_seconds, numba_threads, thread_counts
from rlcompare.bench.tables import BenchTable, Measured, Say, Stage
from rlcompare.compiled import njit
from rlcompare.envs.chess.endgame import Endgame, make_endgame, reset, step
from rlcompare.envs.chess.endgames import parse
from rlcompare.rng import next_below, next_double
from rlcompare.tabular.config import ExperimentConfig
from rlcompare.tabular.runs import over_runs
from rlcompare.tabular.state import AGENT_STREAM, ENV_STREAM, TRANSITION_STREAM, initial_state
from rlcompare.tabular.train import epsilon_schedule, train

ENDGAMES = {"KRK": 15_000, "KQK": 15_000}
"""Episodes per seed against the optimal defender: about a million moves over 8 seeds."""


@njit(inline="always")
def _act(row: np.ndarray, epsilon: float, rng: np.ndarray) -> int:
    """ε-greedy over the legal moves (the finite values), written out."""
    if next_double(rng) < epsilon:
        legal = 0
        for action in range(row.size):
            legal += row[action] != -np.inf
        pick = next_below(rng, legal)
        for action in range(row.size):
            if row[action] != -np.inf:
                if pick == 0:
                    return action
                pick -= 1
    return greedy_action_random_ties(row, rng)


@njit(cache=True, nogil=True)
def plain_q_learning(rng: np.ndarray, epsilons: np.ndarray, env: Endgame, w: np.ndarray, alpha: float, gamma: float,
                     max_steps: int, returns: np.ndarray, lengths: np.ndarray) -> None:
    """Q-Learning (Algorithm 1) on an endgame, every run's episodes in one loop, nothing else recorded."""
    for run in range(w.shape[0]):
        q, streams = w[run], rng[run]
        for episode in range(epsilons.size):
            epsilon = epsilons[episode]
            state = reset(env, streams[ENV_STREAM])
            action = _act(q[state], epsilon, streams[AGENT_STREAM])
            total, steps = 0.0, 0
            while True:
                after, reward, ended = step(env, state, action, streams[TRANSITION_STREAM])
                total += reward
                steps += 1
                best = q[after, 0]
                for other in range(1, q.shape[1]):
                    best = max(best, q[after, other])
                target = reward if ended else reward + gamma * best
                q[state, action] += alpha * (target - q[state, action])
                if ended or steps >= max_steps:
                    break
                state, action = after, _act(q[after], epsilon, streams[AGENT_STREAM])
            returns[run, episode], lengths[run, episode] = total, steps


def plain_seconds(config: ExperimentConfig) -> tuple[int, float, np.ndarray]:
    """Moves, seconds and returns of the plain kernel training every seed of ``config``, runs spread over threads
    as rlcompare's are."""
    env, endgame = config.environment, make_endgame(parse(config.env))
    state = initial_state(list(config.seeds), env.n_states, env.n_actions, env.legal_moves)
    runs, epsilons = len(config.seeds), epsilon_schedule(config)
    returns, lengths = np.zeros((runs, config.episodes)), np.zeros((runs, config.episodes), np.int64)

    def train(first: int, stop: int, episodes: np.ndarray = epsilons) -> None:
        plain_q_learning(state.rng[first:stop], episodes, endgame, state.w[first:stop], config.alpha,
                         config.gamma, config.step_limit, returns[first:stop], lengths[first:stop])

    train(0, 0, epsilons[:0])  # compile or load it outside the clock
    started = time.perf_counter()
    over_runs(train, runs)
    return int(lengths.sum()), time.perf_counter() - started, returns


def measure_endgame(env: str, episodes: int, threads: int, repeats: int = 3) -> tuple[Measurement, Measurement]:
    """rlcompare's kernel and the plain one on 8 seeds, measured in turn ``repeats`` times, each first in every other
    turn; a :class:`RuntimeError` where the two learn differently."""
    config = bench_config("q_learning", 8, episodes, env=env)
    learnt = train(config).records.returns
    ours: list[tuple[int, float]] = []
    plain: list[tuple[int, float]] = []
    with numba_threads(threads):
        for turn in range(repeats):
            for kind in ("ours", "plain")[:: 1 - 2 * (turn % 2)]:
                if kind == "ours":
                    ours.append(kernel_seconds(config))
                else:
                    moves, seconds, returns = plain_seconds(config)
                    if not np.array_equal(returns, learnt):
                        raise RuntimeError(f"{env}: the plain kernel's returns differ from the engine's")
                    plain.append((moves, seconds))
    return (Measurement(f"{env}, Q-Learning", threads, ours[0][0], statistics.median(t[1] for t in ours)),
            Measurement(f"{env}, plain kernel", threads, plain[0][0], statistics.median(t[1] for t in plain)))


def measure_chess(say: Say) -> Measured:
    """Each endgame on 1 and all threads, said as measured: its table and its measurements."""
    rows: list[tuple[str, ...]] = []
    found = []
    for env, episodes in ENDGAMES.items():
        single = None
        for threads in thread_counts():
            ours, plain = measure_endgame(env, episodes, threads)
            single = single or ours.steps_per_second
            say(f"{ours.label}, {threads} thread(s): {ours.steps_per_second:,.0f} moves/s, plain kernel "
                f"{plain.steps_per_second:,.0f}")
            rows.append((env, str(threads), f"{ours.steps_per_second:,.0f}", f"{plain.steps_per_second:,.0f}",
                         f"{ours.steps_per_second / plain.steps_per_second:.2f}x",
                         f"{ours.steps_per_second / single:.2f}x"))
            found.append({"env": env, "threads": threads, "ours": ours.as_dict(), "plain": plain.as_dict()})
    table = BenchTable("Q-Learning on the chess endgames against the optimal defender, ε = 0.5: learner moves/s",
                       ("endgame", "threads", "rlcompare", "plain kernel", "vs plain kernel", "vs 1 thread"), rows,
                       ("plain kernel: Q-Learning written out for the endgames alone (rlcompare.bench.chess), the "
                        "same seeds and threads in turn; it learns the same table, checked each time",))
    return Measured(table, {"chess": found})


CHESS_STAGE = Stage("Q-Learning on the chess endgames beside a plain kernel", measure_chess)
