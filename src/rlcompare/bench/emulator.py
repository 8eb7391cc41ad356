"""The Atari 2600's emulator on Breakout, measured in one run: ALE's vector environment alone and through the deep
engine's ``io_callback``, beside envpool's published rate per core (:func:`emulator_table`). Imported only when
measured: it needs the ``atari`` extra."""

from __future__ import annotations

import os
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from rlcompare.bench.deep import ready
from rlcompare.bench.tables import BenchTable, Say
from rlcompare.deep import float64
from rlcompare.deep.atari import AtariEnv
from rlcompare.deep.envs import playing
from rlcompare.envs.atari import games as atari

GAME = "Breakout-Atari"
GAMES = (1, 8, 128)
"""Games side by side in the emulator's rows: DQN's one, PPO's 8, PQN's 128."""
ROLE = "training"
"""The emulator the rows step: the one the PQN training then plays (making 128 games takes seconds)."""
ENVPOOL_PER_CORE = 1_100
"""The anchor: envpool publishes about 4,000 to 5,000 frames per second per core for its emulator alone, about 1,100
agent steps per second per core at 4 frames a step."""
EMULATOR_STEPS, TURNS = 4_096, 3
"""Agent steps per measurement of the emulator, and the turns of every row whose median is kept."""

@dataclass(frozen=True)
class BenchAtariEnv(AtariEnv):
    """:class:`~rlcompare.deep.atari.AtariEnv` whose greedy evaluations stop after one step: a timed training is
    then its updates (an evaluation episode of an untrained policy may run thousands of steps)."""

    @property
    def max_steps(self) -> int:
        return 1


def bench_env() -> BenchAtariEnv:
    return BenchAtariEnv(GAME, atari.NAMES[GAME])


def cores() -> int:
    return os.cpu_count() or 1


def emulator_threads(games: int) -> int:
    """The worker threads ALE's vector environment starts at its default ``num_threads=0``: one a game, at most
    one a core (``std::thread::hardware_concurrency``)."""
    return min(games, cores())


def random_actions(env: AtariEnv, games: int, steps: int, seed: int = 0) -> np.ndarray:
    """``(steps // games, games)`` uniformly random actions (at least one row)."""
    rows = max(1, steps // games)
    return np.random.default_rng(seed).integers(0, env.n_actions, size=(rows, games), dtype=np.int32)


def emulator_alone(env: AtariEnv, games: int, steps: int = EMULATOR_STEPS) -> Callable[[], float]:
    """A measurement of ``env``'s emulator of ``games`` games (``AtariEnv.emulator``: the protocol's settings,
    its default thread pool) stepped from Python with random actions: each call, agent steps per second over about
    ``steps`` steps, after one step outside the clock."""
    emulator = env.emulator(ROLE, games)
    actions = random_actions(env, games, steps)
    emulator.reset(seed=0)

    def measure() -> float:
        emulator.step(actions[0])
        started = time.perf_counter()
        for action in actions:
            emulator.step(action)
        return actions.size / (time.perf_counter() - started)

    return measure


@float64
def emulator_through_callback(env: AtariEnv, games: int, steps: int = EMULATOR_STEPS) -> Callable[[], float]:
    """A measurement of the same emulator stepped by ``AtariEnv.step_autoreset_batch`` (``io_callback``) inside a
    jitted ``jax.lax.scan``, with random actions, compiled here: each call, agent steps per second over about
    ``steps`` steps."""
    keys = jax.random.split(jax.random.key(0), games)  # not used by the emulator

    def play(state: jax.Array, actions: jax.Array) -> tuple[jax.Array, jax.Array]:
        def one_step(state: jax.Array, action: jax.Array) -> tuple[jax.Array, jax.Array]:
            step = env.step_autoreset_batch(state, action, keys, ROLE)
            return step.state, step.reward.sum()

        return jax.lax.scan(one_step, state, actions)

    actions = jnp.asarray(random_actions(env, games, steps))
    with playing(env):
        state = jax.jit(lambda key: env.reset_batch(jax.random.split(key, games), ROLE))(jax.random.key(1))
    compiled = jax.jit(play).lower(state, actions).compile()

    def measure() -> float:
        nonlocal state
        with playing(env):
            started = time.perf_counter()
            state, _ = ready(compiled(state, actions))
            return int(actions.size) / (time.perf_counter() - started)

    return measure


@dataclass(frozen=True)
class EmulatorRates:
    """Agent steps per second of the emulator of ``games`` games: alone, and through the callback (medians)."""

    games: int
    alone: float
    callback: float


def measure_emulator(env: AtariEnv, say: Say, games: tuple[int, ...] = GAMES, steps: int = EMULATOR_STEPS,
                     turns: int = TURNS) -> list[EmulatorRates]:
    """Each number of ``games``, alone and through the callback, in turn ``turns`` times; medians."""
    measures = {n: (emulator_alone(env, n, steps), emulator_through_callback(env, n, steps)) for n in games}
    runs: dict[int, tuple[list[float], list[float]]] = {n: ([], []) for n in games}
    for _ in range(turns):
        for n, (alone, callback) in measures.items():
            runs[n][0].append(alone())
            runs[n][1].append(callback())
    rates = [EmulatorRates(n, statistics.median(runs[n][0]), statistics.median(runs[n][1])) for n in games]
    for rate in rates:
        say(f"{rate.games} games: {rate.alone:,.0f} steps/s alone, {rate.callback:,.0f} through the callback")
    return rates


def emulator_table(rates: list[EmulatorRates], steps: int = EMULATOR_STEPS, turns: int = TURNS) -> BenchTable:
    """The emulator's rows: alone and through the callback, each number of games; per core beside envpool's."""
    n = cores()
    rows: list[tuple[str, ...]] = []
    for rate in rates:
        for what, value, ratio in (("alone, stepped from Python", rate.alone, ""),
                                   ("through the engine's callback", rate.callback,
                                    f"{rate.callback / rate.alone:.2f}")):
            rows.append((what, str(rate.games), str(emulator_threads(rate.games)), f"{value:,.0f}",
                         f"{value / n:,.0f}", f"{value / n / ENVPOOL_PER_CORE:.2f}", ratio))
    notes = (
        "alone: ale_py.AtariVectorEnv as AtariEnv.emulator makes it (Machado et al.'s protocol: sticky actions 0.25, "
        "18 actions, 4 frames a step max-pooled, 84 x 84 grey, 4 stacked), uniformly random actions from NumPy; its "
        f"thread pool at ALE's default num_threads=0, one worker a game up to one a core; {n} cores "
        f"(os.cpu_count()). Per core: steps/s / {n}.",
        "callback: the same emulator and actions through AtariEnv.step_autoreset_batch (jax.experimental."
        "io_callback) inside a jitted jax.lax.scan, compiled apart: what the engine's trainings pay for each step.",
        f"Anchor: envpool publishes about 4,000-5,000 frames/s per core for the emulator alone, about "
        f"{ENVPOOL_PER_CORE:,} agent steps/s per core at 4 frames a step. Medians of {turns} turns of about "
        f"{steps:,} steps; JAX on {jax.devices()[0]}.")
    return BenchTable(f"Atari 2600 emulator on {GAME}, agent steps per second (4 frames a step)",
                      ("what", "games", "ALE threads", "steps/s", "steps/s per core",
                       f"per core / envpool's {ENVPOOL_PER_CORE:,}", "callback / alone"), rows, notes)


# --- the learner ---
