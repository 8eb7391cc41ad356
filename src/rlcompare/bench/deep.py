"""``rlcompare bench --deep``: environment steps per second of the deep engine beside Stable-Baselines3, one run.

Each row trains one method with the same settings in both: ours as one compiled program for 1 seed and for
``SEEDS`` seeds side by side (after compiling, which is timed apart), Stable-Baselines3 in this process with
PyTorch's CPU build (the optional ``bench`` extra), timed after a warm-up that fills its replay buffer past
``learning_starts`` and runs its first updates, its torch on the faster of :data:`TORCH_THREADS`. All on Mountain Car,
whose float64 dynamics both step; then MinAtar's Breakout (gymnax's protocol), where DQN with the MinAtar paper's
settings and network is timed beside Stable-Baselines3's on Gymnasium's ``MinAtar/Breakout-v1`` under the same
protocol (:func:`minatar_table`).
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import math
import os
import time
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any, NamedTuple

import jax
import numpy as np

from rlcompare.bench.tabular import BenchTable
from rlcompare.deep import dqn, float64, ppo, pqn
from rlcompare.deep.envs import jax_env
from rlcompare.envs import minatar

SEEDS = 8
ENV = "MountainCar-v0"
TORCH_THREADS = tuple(sorted({1, os.cpu_count() or 1}))
"""Thread counts of torch tried for Stable-Baselines3: the faster over :data:`SB3_PROBE_STEPS` steps times it. JAX
keeps a thread a core; torch on as many was the faster on an idle 2-core machine (362 steps/s against 309 on
MinAtar's Breakout) and about ten times slower than on one thread while other work held a core (its tensors are
small, and each operation waits for the thread on the busy core)."""
SB3_PROBE_STEPS = 500


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


@float64
def ours_steps_per_second(row: DeepRow, seeds: int, steps: int) -> tuple[float, float]:
    """``(steps per second over all seeds, compile seconds)`` of ``steps`` environment steps per seed."""
    config = dataclasses.replace(row.config, total_steps=steps)
    train = jax.jit(jax.vmap(row.module.make_train(config, jax_env(row.env), 1, 1)))
    keys = jax.numpy.stack([jax.random.key(seed) for seed in range(seeds)])
    started = time.perf_counter()
    compiled = train.lower(keys).compile()
    compile_seconds = time.perf_counter() - started
    started = time.perf_counter()
    output = jax.block_until_ready(compiled(keys))
    seconds = time.perf_counter() - started
    return int(np.prod(output.finished.done.shape)) / seconds, compile_seconds


def sb3_model(row: DeepRow, env_id: str = ENV, seed: int = 0):
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


@contextlib.contextmanager
def torch_threads(threads: int) -> Iterator[None]:
    """torch's intra-op threads set to ``threads`` inside, as they were after."""
    import torch

    before = torch.get_num_threads()
    torch.set_num_threads(threads)
    try:
        yield
    finally:
        torch.set_num_threads(before)


class SB3Timing(NamedTuple):
    steps_per_second: float
    torch_threads: int


def sb3_steps_per_second(row: DeepRow, steps: int, model: Any = None) -> SB3Timing:
    """Stable-Baselines3's steps per second over ``steps`` steps, after a warm-up past ``learning_starts`` and a
    probe of :data:`SB3_PROBE_STEPS` steps on each of :data:`TORCH_THREADS`, on the faster; ``model`` (default:
    :func:`sb3_model`) has the row's settings."""
    model = sb3_model(row) if model is None else model
    model.learn(total_timesteps=getattr(row.config, "learning_starts", 0) + 2 * getattr(row.config, "train_freq", 1)
                + getattr(row.config, "n_envs", 1) * getattr(row.config, "n_steps", 0))

    def rate(threads: int, timed_steps: int) -> float:
        with torch_threads(threads):
            started = time.perf_counter()
            before = model.num_timesteps
            model.learn(total_timesteps=timed_steps, reset_num_timesteps=False)
            return (model.num_timesteps - before) / (time.perf_counter() - started)

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
    table, threads = [], []
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
    notes = ("Ours counts the whole training, its learning_starts steps of random actions included (1,000 of "
             "DQN's); Stable-Baselines3 is timed after them.",)
    if threads:
        notes += (f"torch threads, the faster of {' and '.join(map(str, TORCH_THREADS))} over "
                  f"{SB3_PROBE_STEPS} steps: {'; '.join(threads)}.",)
    if not sb3:
        notes += ("Stable-Baselines3 is not installed: pip install -e '.[bench]'",)
    return BenchTable(f"Deep engine on {ENV}, environment steps per second (CPU: {jax.devices()[0]})",
                      ("method", "compile s", "ours, 1 seed", f"ours, {SEEDS} seeds", "SB3, 1 seed",
                       f"ours {SEEDS} seeds / SB3"), table, notes)


MINATAR_ENV, MINATAR_SEEDS = "Breakout-MinAtar", 4
MINATAR_SB3_ENV = "MinAtar/Breakout-v1"
"""Gymnasium's registration of the reference package's Breakout with the minimal action set: with
``sticky_action_prob=0`` and gymnax's time limit it is :data:`MINATAR_ENV`'s protocol (gymnax's)."""
MINATAR_DQN_STEPS, MINATAR_SB3_STEPS = 10_000, 4_000
"""Steps per seed past ``learning_starts`` that ours and Stable-Baselines3 are timed over."""


def minatar_rows() -> list[DeepRow]:
    config = pqn.PRESETS["default"][MINATAR_ENV]
    return [DeepRow("Q(λ), PQN engine, purejaxql's MinAtar settings", pqn, dataclasses.replace(config, target="max"),
                    "", 128 * 32 * 60, MINATAR_ENV),
            DeepRow("SARSA(λ), same", pqn, dataclasses.replace(config, target="sample"), "", 128 * 32 * 60,
                    MINATAR_ENV),
            DeepRow("DQN, the MinAtar paper's settings and network", dqn, dqn.PRESETS["default"][MINATAR_ENV], "dqn",
                    MINATAR_DQN_STEPS, MINATAR_ENV)]


@float64
def ours_learning_steps_per_second(row: DeepRow, seeds: int, steps: int) -> tuple[float, float]:
    """``(steps per second over all seeds, compile seconds)`` of ``steps`` environment steps per seed past
    ``learning_starts``, as Stable-Baselines3 is timed: the wall time of a training of ``learning_starts + steps``
    steps less that of one of ``learning_starts`` steps, each compiled first (apart from its time)."""
    keys = jax.numpy.stack([jax.random.key(seed) for seed in range(seeds)])

    def seconds(total_steps: int) -> tuple[float, float]:
        config = dataclasses.replace(row.config, total_steps=total_steps)
        train = jax.jit(jax.vmap(row.module.make_train(config, jax_env(row.env), 1, 1)))
        started = time.perf_counter()
        compiled = train.lower(keys).compile()
        compile_seconds = time.perf_counter() - started
        started = time.perf_counter()
        jax.block_until_ready(compiled(keys))
        return time.perf_counter() - started, compile_seconds

    start, _ = seconds(row.config.learning_starts)
    whole, compile_seconds = seconds(row.config.learning_starts + steps)
    return seeds * steps / (whole - start), compile_seconds


@functools.cache
def minatar_features() -> type:
    """Stable-Baselines3's features extractor computing MinAtar's network (Young and Tian 2019; the reference's
    ``examples/dqn.py``) up to its last layer: a 3 x 3 convolution of 16 channels (stride 1, no padding), ReLU,
    flattened channels first as torch orders them, a dense layer of ``features``, ReLU. Observations come
    channels last, as the games give them; the extractor moves the channels first. With ``net_arch=[]`` the
    policy's Q head is one linear layer: the network of :func:`rlcompare.deep.dqn.network` (ours flattens the
    convolution's output channels last, so a dense kernel carried over is permuted)."""
    import torch
    from stable_baselines3.common.torch_layers import BaseFeaturesExtractor

    class MinAtarFeatures(BaseFeaturesExtractor):
        def __init__(self, observation_space: Any, features: int = 128, channels: int = 16) -> None:
            height, width, depth = observation_space.shape
            super().__init__(observation_space, features)
            self.conv = torch.nn.Conv2d(depth, channels, 3)
            self.dense = torch.nn.Linear(channels * (height - 2) * (width - 2), features)

        def forward(self, observations: torch.Tensor) -> torch.Tensor:
            x = torch.relu(self.conv(observations.permute(0, 3, 1, 2)))
            return torch.relu(self.dense(x.flatten(1)))

    return MinAtarFeatures


def sb3_minatar_env() -> Any:
    """Gymnasium's :data:`MINATAR_SB3_ENV` under gymnax's protocol: no sticky actions, gymnax's time limit."""
    import gymnasium as gym
    from minatar.gym import register_envs

    if MINATAR_SB3_ENV not in gym.registry:
        register_envs()
    game, _ = minatar.NAMES[MINATAR_ENV]
    return gym.make(MINATAR_SB3_ENV, sticky_action_prob=0.0, max_episode_steps=game.time_limit)


def sb3_minatar_dqn(config: dqn.DQNConfig, seed: int = 0) -> Any:
    """Stable-Baselines3's ``DQN`` with ``config``'s settings on :func:`sb3_minatar_env`: MinAtar's network
    (:func:`minatar_features`, then ``hidden[1:]`` and the linear head), torch's centered RMSProp with the
    MinAtar paper's constants, gradients unclipped where ``max_grad_norm`` is 0 (SB3 clips to infinity: a no-op),
    ε over ``decay_fraction`` of the learning (SB3's schedule starts at the first step; ours, as the paper's, once
    ``learning_starts`` are taken: both are at ``epsilon_end`` over the timed steps)."""
    import stable_baselines3 as sb3
    import torch

    if config.optimizer != "rmsprop":
        raise ValueError("the MinAtar comparison takes the MinAtar paper's RMSProp")
    policy_kwargs = {"features_extractor_class": minatar_features(),
                     "features_extractor_kwargs": {"features": config.hidden[0]}, "net_arch": list(config.hidden[1:]),
                     "optimizer_class": torch.optim.RMSprop,
                     "optimizer_kwargs": {"alpha": dqn.RMSPROP_DECAY, "eps": dqn.RMSPROP_EPS, "centered": True}}
    return sb3.DQN("MlpPolicy", sb3_minatar_env(), learning_rate=config.learning_rate,
                   buffer_size=config.buffer_size, learning_starts=config.learning_starts,
                   batch_size=config.batch_size, gamma=config.gamma, train_freq=config.train_freq,
                   gradient_steps=config.gradient_steps, target_update_interval=config.target_update_interval,
                   exploration_initial_eps=config.epsilon_start, exploration_final_eps=config.epsilon_end,
                   exploration_fraction=config.decay_fraction, max_grad_norm=config.max_grad_norm or math.inf,
                   policy_kwargs=policy_kwargs, device="cpu", seed=seed)


def minatar_table(sb3_steps: int = MINATAR_SB3_STEPS) -> BenchTable:
    """The PQN pair on MinAtar's Breakout (gymnax's protocol, purejaxql's settings and network), 1 seed and
    several side by side; then DQN (the MinAtar paper's settings and network), timed past ``learning_starts``,
    beside Stable-Baselines3's with the same network and settings on Gymnasium's Breakout under the same
    protocol."""
    sb3 = have_sb3()
    c, (game, _) = dqn.PRESETS["default"][MINATAR_ENV], minatar.NAMES[MINATAR_ENV]
    table, threads = [], 0
    for row in minatar_rows():
        if row.sb3:
            one, compile_seconds = ours_learning_steps_per_second(row, 1, row.steps)
            many, _ = ours_learning_steps_per_second(row, MINATAR_SEEDS, row.steps)
        else:
            one, compile_seconds = ours_steps_per_second(row, 1, row.steps)
            many, _ = ours_steps_per_second(row, MINATAR_SEEDS, row.steps)
        timing = sb3_steps_per_second(row, sb3_steps, sb3_minatar_dqn(row.config)) if row.sb3 and sb3 else None
        theirs = float("nan") if timing is None else timing.steps_per_second
        if timing is not None:
            threads = timing.torch_threads
        table.append((row.label, f"{compile_seconds:.1f}", f"{one:,.0f}", f"{many:,.0f}",
                      *(("", "", "") if math.isnan(theirs) else
                        (f"{theirs:,.0f}", f"{one / theirs:.1f}x", f"{many / theirs:.1f}x"))))
    notes = ("PQN: 128 environments x 32 steps per update, 2 epochs x 32 minibatches, MinAtar's network with "
             "LayerNorm; one greedy evaluation included.",
             f"DQN: replay {c.buffer_size:,}, batch {c.batch_size}, a gradient step every {c.train_freq} step, "
             f"target every {c.target_update_interval:,}, centered RMSProp, MinAtar's network; both timed past "
             f"their {c.learning_starts:,} random steps (ours: a training of {c.learning_starts:,} + "
             f"{MINATAR_DQN_STEPS:,} steps less one of {c.learning_starts:,}; SB3: {sb3_steps:,} steps after them) "
             f"on {MINATAR_SB3_ENV} with sticky_action_prob=0 and gymnax's {game.time_limit:,}-step limit. JAX on "
             f"{os.cpu_count()} cores"
             + (f", torch on {threads} (the faster of {' and '.join(map(str, TORCH_THREADS))} over "
                f"{SB3_PROBE_STEPS} steps)." if threads else "."))
    if not sb3:
        notes += ("Stable-Baselines3 is not installed: pip install -e '.[bench]'",)
    return BenchTable(f"Deep engine on {MINATAR_ENV}, environment steps per second (CPU: {jax.devices()[0]})",
                      ("method", "compile s", "1 seed", f"{MINATAR_SEEDS} seeds", "SB3, 1 seed", "1 seed / SB3",
                       f"{MINATAR_SEEDS} seeds / SB3"), table, notes)


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
    returns = np.asarray(jax.block_until_ready(compiled(keys)).eval_returns).mean(axis=-1)  # (seeds, rounds)
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

    model = sb3_model(row, SCORE_ENV, seed)
    every = row.config.total_steps // SCORE_ROUNDS
    evaluation_env = Monitor(gym.make(SCORE_ENV))

    class StopAtScore(BaseCallback):
        reached: bool = False

        def _on_step(self) -> bool:
            if self.num_timesteps % every >= getattr(self.training_env, "num_envs", 1):
                return True
            mean, _ = evaluate_policy(model, evaluation_env, n_eval_episodes=10, deterministic=True)
            self.reached = mean >= SCORE
            return not self.reached

    callback = StopAtScore()
    started = time.perf_counter()
    model.learn(total_timesteps=row.config.total_steps, callback=callback)
    return time.perf_counter() - started if callback.reached else float("nan")


def score_table(seeds: int = 3) -> BenchTable:
    """Median wall seconds to the score on CartPole, ours (seeds side by side) beside Stable-Baselines3's (one
    seed after another, as it trains)."""
    table = []
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
