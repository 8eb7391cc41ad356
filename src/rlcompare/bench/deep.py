"""``rlcompare bench deep``: environment steps per second of the deep engine beside Stable-Baselines3, one run.

Each row trains one method with the same settings in both: ours as one compiled program for 1 seed and for
``SEEDS`` seeds side by side (after compiling, which is timed apart), Stable-Baselines3 in this process with
PyTorch's CPU build (the optional ``bench`` extra), timed after a warm-up that fills its replay buffer past
``learning_starts`` and runs its first updates, its torch on the faster of :data:`TORCH_THREADS`. All on Mountain Car,
whose float64 dynamics both step (:func:`deep_table`); then, with ``--to-score``, the wall time to a greedy return
of 475 on CartPole (:func:`score_table`). MinAtar's Breakout is :mod:`rlcompare.bench.minatar`'s.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, NamedTuple, TypeVar

import jax
import numpy as np

from rlcompare.bench.harness import temporarily
from rlcompare.bench.tables import BenchTable
from rlcompare.deep import dqn, float64, ppo, pqn
from rlcompare.deep.envs import jax_env

SEEDS = 8
ENV = "MountainCar-v0"
TORCH_THREADS = tuple(sorted({1, os.cpu_count() or 1}))
"""Thread counts of torch tried for Stable-Baselines3: the faster over :data:`SB3_PROBE_STEPS` steps times it. JAX
keeps a thread a core; torch on as many was the faster on an idle 2-core machine (362 steps/s against 309 on
MinAtar's Breakout) and about ten times slower than on one thread while other work held a core (its tensors are
small, and each operation waits for the thread on the busy core)."""
SB3_PROBE_STEPS = 500
Output = TypeVar("Output")


@dataclass(frozen=True)
class DeepRow:
    """One method's settings, as ours and as Stable-Baselines3's."""

    label: str
    module: Any
    config: Any
    sb3: str
    """``dqn``, ``ppo`` or ``""`` (no Stable-Baselines3 counterpart)."""
    steps: int = 100_000
    """Environment steps per seed that ours is timed over."""
    env: str = ENV


def rows() -> list[DeepRow]:
    pqn_config = pqn.PRESETS["default"][ENV]
    return [
        DeepRow("Q(λ), PQN engine, 16 x 128, 2 x 64 LayerNorm", pqn, dataclasses.replace(pqn_config, target="max"), "",
                200_000),
        DeepRow("SARSA(λ), PQN engine, same", pqn, dataclasses.replace(pqn_config, target="sample"), "", 200_000),
        DeepRow("PPO, zoo settings", ppo, ppo.PRESETS["default"][ENV], "ppo", 100_000),
        DeepRow("DQN, zoo settings on 2 x 64", dqn, dqn.PRESETS["default"][ENV], "dqn", 20_000),
        DeepRow("DQN, zoo settings (256 x 256)", dqn, dqn.PRESETS["zoo"][ENV], "dqn", 8_000),
    ]


def ready(output: Output) -> Output:
    """``output`` once JAX has computed every array of it (``jax.block_until_ready``)."""
    wait: Callable[[Output], Output] = jax.block_until_ready
    return wait(output)


def timed_training(row: DeepRow, seeds: int, total_steps: int) -> tuple[float, float, Any]:
    """``(wall seconds, compile seconds, output)`` of the row's training of ``total_steps`` environment steps per
    seed, ``seeds`` seeds side by side; compiled first, apart from its time."""
    config = dataclasses.replace(row.config, total_steps=total_steps)
    train = jax.jit(jax.vmap(row.module.make_train(config, jax_env(row.env), 1, 1)))
    keys = jax.numpy.stack([jax.random.key(seed) for seed in range(seeds)])
    started = time.perf_counter()
    compiled = train.lower(keys).compile()
    compile_seconds = time.perf_counter() - started
    started = time.perf_counter()
    output = ready(compiled(keys))
    return time.perf_counter() - started, compile_seconds, output


@float64
def ours_steps_per_second(row: DeepRow, seeds: int, steps: int) -> tuple[float, float]:
    """``(steps per second over all seeds, compile seconds)`` of ``steps`` environment steps per seed."""
    seconds, compile_seconds, output = timed_training(row, seeds, steps)
    return int(np.prod(output.finished.done.shape)) / seconds, compile_seconds


def sb3_model(row: DeepRow, env_id: str = ENV, seed: int = 0) -> Any:
    """Stable-Baselines3's model with the row's settings (the zoo's, as our presets hold them)."""
    import gymnasium as gym
    import stable_baselines3 as sb3
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import VecNormalize

    c = row.config
    if row.sb3 == "dqn":
        return sb3.DQN("MlpPolicy", gym.make(env_id), learning_rate=c.learning_rate, buffer_size=c.buffer_size,
                       learning_starts=c.learning_starts, batch_size=c.batch_size, gamma=c.gamma,
                       train_freq=c.train_freq, gradient_steps=c.gradient_steps,
                       target_update_interval=c.target_update_interval, exploration_fraction=c.decay_fraction,
                       exploration_final_eps=c.epsilon_end, policy_kwargs={"net_arch": list(c.hidden)},
                       device="cpu", seed=seed)
    env = make_vec_env(env_id, n_envs=c.n_envs, seed=seed)
    if c.normalize_observations:
        env = VecNormalize(env, gamma=c.gamma)
    return sb3.PPO("MlpPolicy", env, n_steps=c.n_steps, batch_size=c.batch_size, n_epochs=c.n_epochs,
                   learning_rate=c.learning_rate, gamma=c.gamma, gae_lambda=c.gae_lambda, clip_range=c.clip_range,
                   ent_coef=c.ent_coef, vf_coef=c.vf_coef, max_grad_norm=c.max_grad_norm, device="cpu", seed=seed,
                   policy_kwargs={"net_arch": list(c.hidden)})


def unlogged(model: Any) -> Any:
    """``model`` with a logger that writes nothing: left to itself, Stable-Baselines3 makes a directory
    ``SB3-<time>`` in the system's temporary directory at every ``learn``, and leaves it there."""
    from stable_baselines3.common.logger import Logger

    model.set_logger(Logger(folder=None, output_formats=[]))
    return model


def torch_threads(threads: int) -> contextlib.AbstractContextManager[None]:
    """torch's intra-op threads set to ``threads`` inside, as they were after."""
    import torch

    return temporarily(torch.get_num_threads, torch.set_num_threads, threads)


class SB3Timing(NamedTuple):
    steps_per_second: float
    torch_threads: int


def sb3_steps_per_second(row: DeepRow, steps: int, model: Any = None) -> SB3Timing:
    """Stable-Baselines3's steps per second over ``steps`` steps, after a warm-up past ``learning_starts`` and a
    probe of :data:`SB3_PROBE_STEPS` steps on each of :data:`TORCH_THREADS`, on the faster; ``model`` (default:
    :func:`sb3_model`) has the row's settings."""
    model = unlogged(sb3_model(row) if model is None else model)
    model.learn(total_timesteps=getattr(row.config, "learning_starts", 0) + 2 * getattr(row.config, "train_freq", 1)
                + getattr(row.config, "n_envs", 1) * getattr(row.config, "n_steps", 0))

    def rate(threads: int, timed_steps: int) -> float:
        with torch_threads(threads):
            started = time.perf_counter()
            before: int = model.num_timesteps
            model.learn(total_timesteps=timed_steps, reset_num_timesteps=False)
            done: int = model.num_timesteps
            return (done - before) / (time.perf_counter() - started)

    probes = {threads: rate(threads, SB3_PROBE_STEPS) for threads in TORCH_THREADS}
    threads = max(probes, key=probes.__getitem__)
    return SB3Timing(rate(threads, steps), threads)


def have_sb3() -> bool:
    """Whether Stable-Baselines3 (the optional ``bench`` extra) is installed."""
    try:
        import stable_baselines3  # noqa: F401
    except ImportError:
        return False
    return True


def deep_table(sb3_steps: int = 4_000) -> BenchTable:
    """Every row, ours beside Stable-Baselines3's where it has the method."""
    sb3 = have_sb3()
    table: list[tuple[str, ...]] = []
    threads: list[str] = []
    for row in rows():
        one, _ = ours_steps_per_second(row, 1, row.steps)
        many, compile_seconds = ours_steps_per_second(row, SEEDS, row.steps)
        timing = sb3_steps_per_second(row, sb3_steps) if row.sb3 and sb3 else None
        theirs = float("nan") if timing is None else timing.steps_per_second
        if timing is not None:
            threads.append(f"{row.label} {timing.torch_threads}")
        ratio = "" if np.isnan(theirs) else f"{many / theirs:,.0f}x"
        table.append((row.label, f"{compile_seconds:.1f}", f"{one:,.0f}", f"{many:,.0f}",
                      "" if np.isnan(theirs) else f"{theirs:,.0f}", ratio))
    notes: tuple[str, ...] = ("Ours counts the whole training, its learning_starts steps of random actions "
                              "included (1,000 of DQN's); Stable-Baselines3 is timed after them.",)
    if threads:
        notes += (f"torch threads, the faster of {' and '.join(map(str, TORCH_THREADS))} over "
                  f"{SB3_PROBE_STEPS} steps: {'; '.join(threads)}.",)
    if not sb3:
        notes += ("Stable-Baselines3 is not installed: pip install -e '.[bench]'",)
    return BenchTable(f"Deep engine on {ENV}, environment steps per second (CPU: {jax.devices()[0]})",
                      ("method", "compile s", "ours, 1 seed", f"ours, {SEEDS} seeds", "SB3, 1 seed",
                       f"ours {SEEDS} seeds / SB3"), table, notes)


SCORE_ENV, SCORE = "CartPole-v1", 475.0
SCORE_ROUNDS = 20
"""Greedy evaluations over the training, in both: the resolution of the time to the score."""


def score_rows() -> list[DeepRow]:
    return [DeepRow("PPO, zoo settings", ppo, ppo.PRESETS["default"][SCORE_ENV], "ppo"),
            DeepRow("DQN, zoo settings on 2 x 64", dqn, dqn.PRESETS["default"][SCORE_ENV], "dqn")]


@float64
def ours_seconds_to_score(row: DeepRow, seeds: int) -> np.ndarray:
    """Wall seconds (compiling apart) until each seed's greedy evaluation first reached the score (NaN: never),
    the seeds trained side by side; a seed reached round ``k`` at ``k / rounds`` of the wall time."""
    train = jax.jit(jax.vmap(row.module.make_train(row.config, jax_env(SCORE_ENV), SCORE_ROUNDS, 10)))
    keys = jax.numpy.stack([jax.random.key(seed) for seed in range(seeds)])
    compiled = train.lower(keys).compile()
    started = time.perf_counter()
    returns = np.asarray(ready(compiled(keys)).eval_returns).mean(axis=-1)  # (seeds, rounds)
    wall = time.perf_counter() - started
    reached = returns >= SCORE
    return np.where(reached.any(axis=1), (reached.argmax(axis=1) + 1) * wall / SCORE_ROUNDS, np.nan)


def sb3_seconds_to_score(row: DeepRow, seed: int) -> float:
    """Wall seconds until Stable-Baselines3's greedy evaluation (10 episodes, every 1/20 of the training, its
    time counted) first reached the score; NaN if it never did within the preset's steps."""
    import gymnasium as gym
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.evaluation import evaluate_policy
    from stable_baselines3.common.monitor import Monitor

    model = unlogged(sb3_model(row, SCORE_ENV, seed))
    every = row.config.total_steps // SCORE_ROUNDS
    evaluation_env: Any = Monitor(gym.make(SCORE_ENV))

    class StopAtScore(BaseCallback):  # type: ignore[misc, unused-ignore]  # SB3 is untyped unless installed
        reached: bool = False

        def _on_step(self) -> bool:
            if self.num_timesteps % every >= getattr(self.training_env, "num_envs", 1):
                return True
            mean, _ = evaluate_policy(model, evaluation_env, n_eval_episodes=10, deterministic=True)
            self.reached = float(mean) >= SCORE  # type: ignore[arg-type, unused-ignore]
            return not self.reached

    callback = StopAtScore()
    started = time.perf_counter()
    model.learn(total_timesteps=row.config.total_steps, callback=callback)
    return time.perf_counter() - started if callback.reached else float("nan")


def score_table(seeds: int = 3) -> BenchTable:
    """Median wall seconds to the score on CartPole, ours (seeds side by side) beside Stable-Baselines3's (one
    seed after another, as it trains)."""
    table: list[tuple[str, ...]] = []
    for row in score_rows():
        ours = ours_seconds_to_score(row, seeds)
        theirs = np.array([sb3_seconds_to_score(row, seed) for seed in range(seeds)])
        table.append((row.label, f"{np.nanmedian(ours):.1f}" if np.isfinite(ours).any() else "never",
                      f"{int(np.isfinite(ours).sum())}/{seeds}",
                      f"{np.nanmedian(theirs):.1f}" if np.isfinite(theirs).any() else "never",
                      f"{int(np.isfinite(theirs).sum())}/{seeds}"))
    return BenchTable(f"Wall seconds to a greedy return of {SCORE:g} on {SCORE_ENV}, median over seeds",
                      ("method", "ours", "ours reached", "SB3", "SB3 reached"), table,
                      ("Ours: every seed in one program, the time to the first evaluation at the score; SB3: one "
                       "seed at a time, its evaluations' time included.",))

