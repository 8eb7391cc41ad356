"""``rlcompare bench --deep``: environment steps per second of the deep engine beside Stable-Baselines3, one run.

Each row trains one method with the same settings in both: ours as one compiled program for 1 seed and for
``SEEDS`` seeds side by side (after compiling, which is timed apart), Stable-Baselines3 in this process with
PyTorch's CPU build (the optional ``bench`` extra), timed after a warm-up that fills its replay buffer past
``learning_starts`` and runs its first updates. All on Mountain Car, whose float64 dynamics both step.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass
from typing import Any

import jax
import numpy as np

from rlcompare.deep import dqn, ppo, pqn
from rlcompare.deep.envs import DEEP_ENVS
from rlcompare.experiment.benchmark import BenchTable

SEEDS = 8
ENV = "MountainCar-v0"


@dataclass(frozen=True)
class DeepRow:
    """One method's settings, as ours and as Stable-Baselines3's."""

    label: str
    module: Any
    config: Any
    sb3: str
    """``dqn``, ``ppo`` or ``""`` (no Stable-Baselines3 counterpart)."""


def rows() -> list[DeepRow]:
    pqn_config = pqn.PRESETS["default"][ENV]
    return [
        DeepRow("Q(λ), PQN engine, 16 x 128, 2 x 64 LayerNorm", pqn, dataclasses.replace(pqn_config, target="max"), ""),
        DeepRow("SARSA(λ), PQN engine, same", pqn, dataclasses.replace(pqn_config, target="sample"), ""),
        DeepRow("PPO, zoo settings", ppo, ppo.PRESETS["default"][ENV], "ppo"),
        DeepRow("DQN, zoo settings on 2 x 64", dqn, dqn.PRESETS["default"][ENV], "dqn"),
        DeepRow("DQN, zoo settings (256 x 256)", dqn, dqn.PRESETS["zoo"][ENV], "dqn"),
    ]


def ours_steps_per_second(row: DeepRow, seeds: int, steps: int) -> tuple[float, float]:
    """``(steps per second over all seeds, compile seconds)`` of ``steps`` environment steps per seed."""
    config = dataclasses.replace(row.config, total_steps=steps)
    train = jax.jit(jax.vmap(row.module.make_train(config, DEEP_ENVS[ENV], 1, 1)))
    keys = jax.numpy.stack([jax.random.key(seed) for seed in range(seeds)])
    started = time.perf_counter()
    compiled = train.lower(keys).compile()
    compile_seconds = time.perf_counter() - started
    started = time.perf_counter()
    output = jax.block_until_ready(compiled(keys))
    seconds = time.perf_counter() - started
    return int(np.prod(output.finished.done.shape)) / seconds, compile_seconds


def sb3_model(row: DeepRow):
    """Stable-Baselines3's model with the row's settings (the zoo's, as our presets hold them)."""
    import gymnasium as gym
    import stable_baselines3 as sb3
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import VecNormalize

    c = row.config
    if row.sb3 == "dqn":
        return sb3.DQN("MlpPolicy", gym.make(ENV), learning_rate=c.learning_rate, buffer_size=c.buffer_size,
                       learning_starts=c.learning_starts, batch_size=c.batch_size, gamma=c.gamma,
                       train_freq=c.train_freq, gradient_steps=c.gradient_steps,
                       target_update_interval=c.target_update_interval, exploration_fraction=c.decay_fraction,
                       exploration_final_eps=c.epsilon_end, policy_kwargs={"net_arch": list(c.hidden)},
                       device="cpu", seed=0)
    env = make_vec_env(ENV, n_envs=c.n_envs, seed=0)
    if c.normalize_observations:
        env = VecNormalize(env, gamma=c.gamma)
    return sb3.PPO("MlpPolicy", env, n_steps=c.n_steps, batch_size=c.batch_size, n_epochs=c.n_epochs,
                   learning_rate=c.learning_rate, gamma=c.gamma, gae_lambda=c.gae_lambda, clip_range=c.clip_range,
                   ent_coef=c.ent_coef, vf_coef=c.vf_coef, max_grad_norm=c.max_grad_norm, device="cpu", seed=0)


def sb3_steps_per_second(row: DeepRow, steps: int) -> float:
    """Stable-Baselines3's steps per second over ``steps`` steps, after a warm-up past ``learning_starts``."""
    model = sb3_model(row)
    model.learn(total_timesteps=getattr(row.config, "learning_starts", 0) + 2 * getattr(row.config, "train_freq", 1)
                + getattr(row.config, "n_envs", 1) * getattr(row.config, "n_steps", 0))
    started = time.perf_counter()
    before = model.num_timesteps
    model.learn(total_timesteps=steps, reset_num_timesteps=False)
    return (model.num_timesteps - before) / (time.perf_counter() - started)


def deep_table(sb3_steps: int = 4_000, our_steps: int = 200_000) -> BenchTable:
    """Every row, ours beside Stable-Baselines3's where it has the method."""
    try:
        import stable_baselines3  # noqa: F401
    except ImportError:
        have_sb3 = False
    else:
        have_sb3 = True
    table = []
    for row in rows():
        one, _ = ours_steps_per_second(row, 1, our_steps // 4)
        many, compile_seconds = ours_steps_per_second(row, SEEDS, our_steps // 4)
        theirs = sb3_steps_per_second(row, sb3_steps) if row.sb3 and have_sb3 else float("nan")
        ratio = "" if np.isnan(theirs) else f"{many / theirs:,.0f}x"
        table.append((row.label, f"{compile_seconds:.1f}", f"{one:,.0f}", f"{many:,.0f}",
                      "" if np.isnan(theirs) else f"{theirs:,.0f}", ratio))
    notes = () if have_sb3 else ("Stable-Baselines3 is not installed: pip install -e '.[bench]'",)
    return BenchTable(f"Deep engine on {ENV}, environment steps per second (CPU: {jax.devices()[0]})",
                      ("method", "compile s", "ours, 1 seed", f"ours, {SEEDS} seeds", "SB3, 1 seed",
                       f"ours {SEEDS} seeds / SB3"), table, notes)
