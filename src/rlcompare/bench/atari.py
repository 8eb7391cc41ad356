"""``rlcompare bench atari``: agent steps per second (a step is 4 frames) of the Atari 2600 pipeline on Breakout,
measured in one run: ALE's vector environment alone and through the engine's ``io_callback``
(:mod:`rlcompare.bench.emulator`), then the learner's cost per agent step for each method's Atari preset, beside
Stable-Baselines3's trainings where the ``bench`` extra is installed (:func:`learner_table`). Imported only when
measured: it needs the ``atari`` extra."""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import optax

from rlcompare.bench.deep import SB3_PROBE_STEPS, TORCH_THREADS, DeepRow, have_sb3, ready, sb3_steps_per_second
from rlcompare.bench.emulator import (
    GAME,
    ROLE,
    BenchAtariEnv,
    EmulatorRates,
    bench_env,
    cores,
    emulator_table,
    measure_emulator,
)
from rlcompare.bench.tables import BenchTable, Measured, Say, Stage
from rlcompare.deep import dqn, float64, ppo, pqn
from rlcompare.deep.atari import AtariEnv
from rlcompare.deep.envs import playing
from rlcompare.deep.networks import Network
from rlcompare.deep.ppo_networks import network as ppo_network
from rlcompare.deep.presets import dqn as dqn_config
from rlcompare.deep.presets import ppo as ppo_config
from rlcompare.deep.replay import Transitions
from rlcompare.deep.rollout import TrainOutput
from rlcompare.envs.atari import games as atari

PQN_UPDATES = 2
"""Updates of the PQN preset's timed training (128 games x 32 steps each)."""
SB3_DQN_LEARNING_STARTS, SB3_DQN_STEPS, SB3_PPO_STEPS = 1_000, 2_000, 2_048
"""Stable-Baselines3: DQN's random steps before learning (the zoo's are 100,000), then the steps each training is
timed over."""


@dataclass(frozen=True)
class LearnerCost:
    """What an agent step costs the learner: forward passes of ``forward_batch`` observations (``forwards_per_step``
    of them a step) and gradient steps on minibatches of ``gradient_batch`` (one every ``steps_per_gradient``
    agent steps), each measured inside a compiled ``jax.lax.scan`` as a training runs them."""

    label: str
    forward_batch: int
    forwards_per_step: float
    gradient_batch: int
    steps_per_gradient: float
    forward_seconds: float = math.nan
    gradient_seconds: float = math.nan

    @property
    def seconds_per_step(self) -> float:
        return self.forward_seconds * self.forwards_per_step + self.gradient_seconds / self.steps_per_gradient

    @property
    def steps_per_second(self) -> float:
        return 1.0 / self.seconds_per_step


def uint8_frames(shape: tuple[int, ...], seed: int) -> jax.Array:
    return jnp.asarray(np.random.default_rng(seed).integers(0, 256, size=shape, dtype=np.uint8))


def scan_seconds(step: Callable[[Any, Any], Any], carry: Any, xs: Any) -> float:
    """Seconds per iteration of ``carry = step(carry, x)`` over ``xs`` in a compiled ``jax.lax.scan``: compiled and
    run once first, outside the clock."""
    compiled = jax.jit(lambda carry, xs: jax.lax.scan(lambda c, x: (step(c, x), None), carry, xs)[0]).lower(
        carry, xs).compile()
    ready(compiled(carry, xs))
    started = time.perf_counter()
    ready(compiled(carry, xs))
    return (time.perf_counter() - started) / len(jax.tree.leaves(xs)[0])


def random_like(shapes: Any, key: jax.Array, scale: float = 0.05) -> Any:
    """Arrays of ``shapes`` (``jax.ShapeDtypeStruct``s) drawn normal with standard deviation ``scale``."""
    leaves, tree = jax.tree.flatten(shapes)
    keys = jax.random.split(key, len(leaves))
    return jax.tree.unflatten(tree, [scale * jax.random.normal(k, leaf.shape, leaf.dtype)
                                     for k, leaf in zip(keys, leaves, strict=True)])


def forward_seconds(apply: Callable[[jax.Array], Any], batch: int, passes: int) -> float:
    """Seconds per forward pass ``apply(observations)`` of ``batch`` random frame stacks, a new batch each pass."""
    def step(total: jax.Array, observations: jax.Array) -> jax.Array:
        return total + jnp.stack([jnp.sum(x) for x in jax.tree.leaves(apply(observations))]).sum()

    return scan_seconds(step, jnp.zeros((), jnp.float32), uint8_frames((passes, batch, 84, 84, 4), 0))


def gradient_seconds(loss: Callable[[Any, Any], jax.Array], tx: optax.GradientTransformation, params: Any,
                     batches: Any) -> float:
    """Seconds per gradient step (``loss``'s gradient, then ``tx``) over ``batches``, one a step."""
    def step(carry: tuple[Any, Any], batch: Any) -> tuple[Any, Any]:
        params, opt_state = carry
        updates, opt_state = tx.update(jax.grad(loss)(params, batch), opt_state, params)
        return optax.apply_updates(params, updates), opt_state

    return scan_seconds(step, (params, tx.init(params)), batches)


@float64
def dqn_cost(env: AtariEnv, gradients: int = 8, passes: int = 64) -> LearnerCost:
    """DQN's Atari preset (the costs of CleanRL's ``dqn_atari_jax.py``: Mnih et al.'s network, one environment, a
    forward pass a step, a gradient on 32 transitions every 4 steps, the target network's pass inside it)."""
    config = dqn_config.ATARI
    net: Network = dqn.network(config, env)
    params = net.init(jax.random.key(0), jnp.zeros((1, *env.observation_shape), jnp.float32))
    cost = LearnerCost("DQN preset (CleanRL dqn_atari_jax's costs)", config.n_envs, 1.0 / config.n_envs,
                       config.batch_size, steps_per_gradient(config))
    b = config.batch_size
    batches = Transitions(uint8_frames((gradients, b, 84, 84, 4), 1), jnp.zeros((gradients, b), jnp.int32),
                          jnp.ones((gradients, b), jnp.float32), uint8_frames((gradients, b, 84, 84, 4), 2),
                          jnp.zeros((gradients, b), bool))

    def loss(params: Any, batch: Transitions) -> jax.Array:
        return dqn.q_loss(params, params, batch, net.apply, config)

    return dataclasses.replace(cost, forward_seconds=forward_seconds(lambda x: net.apply(params, x),
                                                                     cost.forward_batch, passes),
                               gradient_seconds=gradient_seconds(loss, dqn.optimizer(config), params, batches))


@float64
def ppo_cost(env: AtariEnv, gradients: int = 4, passes: int = 32) -> LearnerCost:
    """PPO's Atari preset (the costs of CleanRL's ``ppo_atari_envpool_xla_jax.py``: 8 environments x 128 steps, a
    forward pass of 8 every 8 steps, 4 epochs x 4 minibatches of 256: 16 gradients per 1,024 steps), on the
    engine's network (one Nature CNN shared by the policy and the value) and loss. Its variables are drawn
    normal, not orthogonal: the same cost, without the orthogonal initialisation's QR decompositions (about 16 s
    on 2 cores)."""
    config = ppo_config.ATARI
    module: Network = ppo_network(config, env)
    variables = random_like(jax.eval_shape(lambda key: ppo.init_params(config, env, key).network,
                                           jax.random.key(0)), jax.random.key(0))
    cost = LearnerCost("PPO preset (CleanRL ppo_atari_envpool_xla_jax's)", config.n_envs,
                       1.0 / config.n_envs, config.batch_size, steps_per_gradient(config))
    b = config.batch_size
    noise = jax.random.normal(jax.random.key(1), (5, gradients, b), jnp.float32)
    batches = ppo.Batch(uint8_frames((gradients, b, 84, 84, 4), 1), jnp.zeros((gradients, b), jnp.int32),
                        -jnp.abs(noise[0]) - 2.9, noise[1], noise[2], noise[3])
    clip_range = jnp.asarray(config.clip_range, jnp.float32)

    def loss(variables: Any, batch: ppo.Batch) -> jax.Array:
        return ppo.ppo_loss(module, variables, batch, clip_range, config)

    return dataclasses.replace(cost, forward_seconds=forward_seconds(lambda x: module.apply(variables, x),
                                                                     cost.forward_batch, passes),
                               gradient_seconds=gradient_seconds(loss, ppo.optimizer(config), variables, batches))


def pqn_preset() -> pqn.PQNConfig:
    config: pqn.PQNConfig = pqn.PRESETS["default"][GAME]
    return config


@float64
def pqn_cost(env: AtariEnv, gradients: int = 4, passes: int = 4) -> LearnerCost:
    """The PQN preset by its parts: a forward pass of its 128 games each step and one over the rollout's next
    observations for the λ-returns (2 per 128 steps), a gradient of its loss on 128 transitions every 64 steps
    (2 epochs x 32 minibatches per 128 x 32 steps), on its network (Nature CNN with LayerNorm) and optimiser."""
    config = pqn_preset()
    net: Network = pqn.network(config, env)
    params = net.init(jax.random.key(0), jnp.zeros((1, *env.observation_shape), jnp.float32))
    cost = LearnerCost("Q(λ) PQN preset, by its parts", config.n_envs, 2.0 / config.n_envs,
                       config.n_envs * config.n_steps // config.n_minibatches, steps_per_gradient(config))
    b = cost.gradient_batch
    batches = (uint8_frames((gradients, b, 84, 84, 4), 1), jnp.zeros((gradients, b), jnp.int32),
               jax.random.normal(jax.random.key(1), (gradients, b), jnp.float32))

    def loss(params: Any, batch: tuple[jax.Array, jax.Array, jax.Array]) -> jax.Array:
        observations, actions, returns = batch
        taken = jnp.take_along_axis(net.apply(params, observations), actions[:, None], axis=-1)[:, 0]
        return 0.5 * jnp.mean(jnp.square(taken - returns))

    tx = optax.chain(optax.clip_by_global_norm(config.max_grad_norm), optax.radam(config.learning_rate))
    return dataclasses.replace(cost, forward_seconds=forward_seconds(lambda x: net.apply(params, x),
                                                                     cost.forward_batch, passes),
                               gradient_seconds=gradient_seconds(loss, tx, params, batches))


@dataclass(frozen=True)
class TrainingRate:
    steps_per_second: float
    compile_seconds: float
    output: TrainOutput


@float64
def pqn_training(env: BenchAtariEnv, updates: int = PQN_UPDATES, config: pqn.PQNConfig | None = None
                 ) -> TrainingRate:
    """The PQN preset's training of ``updates`` updates as the engine runs it (``make_train`` jitted without
    ``vmap``, one greedy evaluation of one step), compiled apart and its emulators made before the clock."""
    config = pqn_preset() if config is None else config
    config = dataclasses.replace(config, total_steps=updates * config.n_envs * config.n_steps)
    env.emulator(ROLE, config.n_envs)
    env.emulator("evaluation", 1)
    key = jax.random.key(0)
    started = time.perf_counter()
    compiled = jax.jit(pqn.make_train(config, env, 1, 1)).lower(key).compile()
    compile_seconds = time.perf_counter() - started
    with playing(env):
        started = time.perf_counter()
        output: TrainOutput = ready(compiled(key))
        seconds = time.perf_counter() - started
    return TrainingRate(config.total_steps / seconds, compile_seconds, output)


def learner_alone(whole: float, emulator: float) -> float:
    """Steps per second of the learner alone, from a training's rate and its emulator's through the callback:
    ``1 / (1 / whole - 1 / emulator)``; NaN where the emulator measured no faster than the whole."""
    left = 1.0 / whole - 1.0 / emulator
    return 1.0 / left if left > 0 else math.nan


def together(learner: float, emulator: float) -> float:
    """Steps per second of a learner and an emulator taking turns: ``1 / (1 / learner + 1 / emulator)``."""
    return 1.0 / (1.0 / learner + 1.0 / emulator)


# --- Stable-Baselines3 (the ``bench`` extra) ---

def sb3_dqn(config: dqn_config.DQNConfig, seed: int = 0) -> Any:
    """Stable-Baselines3's ``DQN`` with ``CnnPolicy`` and ``config``'s settings (the zoo's Atari entry) on
    :func:`rlcompare.envs.atari.games.gymnasium_env` (Gymnasium's ``ALE/Breakout-v5`` under the same protocol)."""
    import stable_baselines3 as sb3

    c = config
    return sb3.DQN("CnnPolicy", atari.gymnasium_env(GAME), learning_rate=c.learning_rate, buffer_size=c.buffer_size,
                   learning_starts=c.learning_starts, batch_size=c.batch_size, gamma=c.gamma, train_freq=c.train_freq,
                   gradient_steps=c.gradient_steps, target_update_interval=c.target_update_interval,
                   exploration_fraction=c.decay_fraction, exploration_final_eps=c.epsilon_end,
                   max_grad_norm=c.max_grad_norm, device="cpu", seed=seed)


def sb3_ppo(config: ppo_config.PPOConfig, seed: int = 0) -> Any:
    """Stable-Baselines3's ``PPO`` with ``CnnPolicy`` and ``config``'s settings (the zoo's Atari entry, its
    schedules held at their start: they do not change the cost) on ``n_envs`` of :func:`gymnasium_env` side by
    side (``DummyVecEnv``)."""
    import stable_baselines3 as sb3
    from stable_baselines3.common.env_util import make_vec_env

    c = config
    env = make_vec_env(lambda: atari.gymnasium_env(GAME), n_envs=c.n_envs, seed=seed)
    return sb3.PPO("CnnPolicy", env, n_steps=c.n_steps, batch_size=c.batch_size, n_epochs=c.n_epochs,
                   learning_rate=c.learning_rate, gamma=c.gamma, gae_lambda=c.gae_lambda, clip_range=c.clip_range,
                   ent_coef=c.ent_coef, vf_coef=c.vf_coef, max_grad_norm=c.max_grad_norm, device="cpu", seed=seed)


@dataclass(frozen=True)
class SB3Rate:
    label: str
    steps_per_gradient: float
    steps_per_second: float
    torch_threads: int


def steps_per_gradient(config: Any) -> float:
    """Agent steps per gradient step: DQN's ``train_freq`` x ``n_envs`` / ``gradient_steps``; PQN's and PPO's
    rollout over its epochs x minibatches."""
    if isinstance(config, dqn_config.DQNConfig):
        return config.train_freq * config.n_envs / config.gradient_steps
    if isinstance(config, ppo_config.PPOConfig):
        return config.batch / (config.n_epochs * config.minibatches)
    return float(config.n_envs * config.n_steps / (config.n_epochs * config.n_minibatches))


def measure_sb3(dqn_steps: int = SB3_DQN_STEPS, ppo_steps: int = SB3_PPO_STEPS,
                learning_starts: int = SB3_DQN_LEARNING_STARTS) -> list[SB3Rate]:
    """Stable-Baselines3's DQN past ``learning_starts`` and PPO, each timed over its steps (whole trainings: the
    emulator, the network and the updates)."""
    dqn_settings = dataclasses.replace(dqn_config.ATARI, learning_starts=learning_starts)
    rates = []
    for label, config, model, steps in (
            ("SB3 DQN, CnnPolicy, the zoo's settings", dqn_settings, sb3_dqn(dqn_settings), dqn_steps),
            ("SB3 PPO, CnnPolicy, the zoo's settings", ppo_config.ATARI, sb3_ppo(ppo_config.ATARI), ppo_steps)):
        timing = sb3_steps_per_second(DeepRow(label, None, config, "", env=GAME), steps, model)
        rates.append(SB3Rate(label, steps_per_gradient(config), timing.steps_per_second, timing.torch_threads))
    return rates


# --- the learner's table ---

def whole(value: float) -> str:
    """``value`` rounded, thousands separated; an empty cell where it was not measured (NaN)."""
    return "" if math.isnan(value) else f"{value:,.0f}"


def learner_table(costs: list[LearnerCost], training: TrainingRate, emulator: dict[int, EmulatorRates],
                  sb3: list[SB3Rate] | None) -> BenchTable:
    """The learner's agent steps per second (the emulator excluded) for each preset, beside the emulator's alone
    at the method's number of games (``emulator``, by games); the PQN preset's training as the engine runs it;
    Stable-Baselines3's trainings (None: not installed)."""
    config = pqn_preset()
    at_pqn = emulator.get(config.n_envs)
    rows: list[tuple[str, ...]] = [
        (f"Q(λ) PQN preset, its training ({PQN_UPDATES} updates)", "", "",
         f"{steps_per_gradient(config):g}",
         whole(learner_alone(training.steps_per_second, at_pqn.callback)) if at_pqn else "",
         whole(at_pqn.alone) if at_pqn else "", whole(training.steps_per_second))]
    for cost in costs:
        rates = emulator.get(cost.forward_batch)  # a forward pass acts in every game
        rows.append((cost.label, f"{cost.forward_seconds * 1e3:.1f} ({cost.forward_batch})",
                     f"{cost.gradient_seconds * 1e3:.0f} ({cost.gradient_batch})", f"{cost.steps_per_gradient:g}",
                     whole(cost.steps_per_second), whole(rates.alone) if rates else "",
                     f"~{together(cost.steps_per_second, rates.callback):,.0f}" if rates else ""))
    rows += [(rate.label, "", "", f"{rate.steps_per_gradient:g}", "", "", whole(rate.steps_per_second))
             for rate in sb3 or []]
    notes: tuple[str, ...] = (
        "learner steps/s: 1 / (forward ms x forward passes a step + gradient ms / steps per gradient), each part "
        "timed inside a compiled jax.lax.scan as a training runs it (XLA:CPU's convolution gradients are slower in "
        "loops; the engine's Conv avoids it), under float64 as the engine runs. Forward passes: DQN one of 1 "
        "observation a step, PPO one of 8 every 8 steps, PQN two of 128 every 128 steps (acting, and the λ-returns' "
        "next observations); PQN's parts leave out the rest of its update (shuffling the minibatches, the "
        "λ-returns). For the PQN training: 1 / (1 / its whole rate - 1 / the callback's at 128 games).",
        f"whole steps/s: the PQN preset's training measured (make_train jitted without vmap, compiled apart in "
        f"{training.compile_seconds:.0f} s, {PQN_UPDATES} x 128 x 32 steps, its greedy evaluation cut to one step), "
        "Stable-Baselines3's measured; ~: estimated, the learner and the emulator through the callback at the "
        "method's number of games taking turns. emulator alone: the first table's, at 128 games (PQN), 1 (DQN), 8 "
        "(PPO).",
        "CleanRL's settings: dqn_atari_jax.py (Nature CNN, 1 environment, batch 32, a gradient every 4 steps, one "
        "forward pass a step) and ppo_atari_envpool_xla_jax.py (8 environments x 128 steps, 4 epochs x 4 "
        "minibatches of 256: 16 gradients per 1,024 steps), the same as the presets in what they cost. DQN's "
        "timed gradient includes the target network's pass on the next observations.")
    if sb3 is None:
        notes += ("Stable-Baselines3 is not installed: pip install -e '.[bench]'",)
    else:
        threads = "; ".join(f"{rate.label.split(',')[0]} {rate.torch_threads}" for rate in sb3)
        notes += (f"SB3: Gymnasium's ALE/Breakout-v5 with frameskip=1, AtariPreprocessing and FrameStackObservation "
                  f"(rlcompare.envs.atari.games.gymnasium_env, the same protocol), whole trainings; DQN timed over "
                  f"{SB3_DQN_STEPS:,} steps past learning_starts={SB3_DQN_LEARNING_STARTS:,} (the zoo's 100,000), "
                  f"replay 100,000, batch 32, a gradient every 4; PPO 8 environments (DummyVecEnv) x 128 steps, 4 "
                  f"epochs of 256, over {SB3_PPO_STEPS:,} steps. torch threads, the faster of "
                  f"{' and '.join(map(str, TORCH_THREADS))} over {SB3_PROBE_STEPS} steps: {threads}.",)
    return BenchTable(f"Learner on {GAME}, agent steps per second (JAX on {jax.devices()[0]}, {cores()} cores)",
                      ("what", "forward ms (batch)", "gradient ms (batch)", "steps per gradient", "learner steps/s",
                       "emulator alone steps/s", "whole steps/s"), rows, notes)


def atari_stages(env: BenchAtariEnv | None = None) -> tuple[Stage, Stage]:
    """The emulator's stage, then the learner's, which reads the emulator's rates."""
    env = bench_env() if env is None else env
    measured: dict[int, EmulatorRates] = {}

    def emulator_stage(say: Say) -> Measured:
        rates = measure_emulator(env, say)
        measured.update({rate.games: rate for rate in rates})
        return Measured(emulator_table(rates), {"atari_emulator": [dataclasses.asdict(rate) for rate in rates]})

    def learner_stage(say: Say) -> Measured:
        costs = []
        for measure in (pqn_cost, dqn_cost, ppo_cost):
            cost = measure(env)
            say(f"{cost.label}: forward {cost.forward_seconds * 1e3:.1f} ms, gradient "
                f"{cost.gradient_seconds * 1e3:.0f} ms, {cost.steps_per_second:,.0f} learner steps/s")
            costs.append(cost)
        training = pqn_training(env)
        say(f"PQN preset's training: {training.steps_per_second:,.0f} steps/s (compiled in "
            f"{training.compile_seconds:.0f} s)")
        sb3 = measure_sb3() if have_sb3() else None
        for rate in sb3 or []:
            say(f"{rate.label}: {rate.steps_per_second:,.0f} steps/s")
        table = learner_table(costs, training, measured, sb3)
        return Measured(table, {"atari_learner": {
            "costs": [{**dataclasses.asdict(cost), "steps_per_second": cost.steps_per_second} for cost in costs],
            "pqn_training": {"steps_per_second": training.steps_per_second,
                             "compile_seconds": training.compile_seconds},
            "sb3": [dataclasses.asdict(rate) for rate in sb3 or []]}})

    return (Stage(f"the Atari 2600 emulator on {GAME}, alone and through the engine's callback", emulator_stage),
            Stage(f"the learner's cost per agent step on {GAME}, beside Stable-Baselines3 (a few minutes)",
                  learner_stage))
