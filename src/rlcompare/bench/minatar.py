"""``rlcompare bench deep`` on MinAtar's Breakout (gymnax's protocol): the PQN pair with purejaxql's settings and
network, 1 seed and several side by side; then DQN with the MinAtar paper's settings and network, timed past
``learning_starts`` beside Stable-Baselines3's with the same network and settings on Gymnasium's
``MinAtar/Breakout-v1`` under the same protocol (:func:`minatar_table`)."""

from __future__ import annotations

import dataclasses
import functools
import math
import os
from typing import Any

import jax

from rlcompare.bench.deep import (
    SB3_PROBE_STEPS,
    TORCH_THREADS,
    DeepRow,
    have_sb3,
    ours_steps_per_second,
    sb3_steps_per_second,
    timed_training,
)
from rlcompare.bench.tables import BenchTable
from rlcompare.deep import dqn, float64, pqn
from rlcompare.deep.presets.dqn import RMSPROP_DECAY, RMSPROP_EPS, DQNConfig
from rlcompare.envs import minatar

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
    start, _, _ = timed_training(row, seeds, row.config.learning_starts)
    whole, compile_seconds, _ = timed_training(row, seeds, row.config.learning_starts + steps)
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

    class MinAtarFeatures(BaseFeaturesExtractor):  # type: ignore[misc, unused-ignore]  # untyped unless installed
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


def sb3_minatar_dqn(config: DQNConfig, seed: int = 0) -> Any:
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
                     "optimizer_kwargs": {"alpha": RMSPROP_DECAY, "eps": RMSPROP_EPS, "centered": True}}
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
    table: list[tuple[str, ...]] = []
    threads = 0
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
    notes: tuple[str, ...] = (
        "PQN: 128 environments x 32 steps per update, 2 epochs x 32 minibatches, MinAtar's network with LayerNorm; "
        "one greedy evaluation included.",
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
