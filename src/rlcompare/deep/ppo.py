"""Proximal policy optimisation (Schulman et al. 2017, "Proximal Policy Optimization Algorithms"), one seed's whole
training a single jit-able, vmap-able program, as in purejaxrl (Lu et al. 2022, ``purejaxrl/ppo.py``).

The semantics are Stable-Baselines3's (``stable_baselines3/ppo/ppo.py``, ``common/on_policy_algorithm.py``,
``common/buffers.py``, ``common/policies.py``, ``common/vec_env/vec_normalize.py``): separate actor and critic
MLPs with orthogonal initialisation, Adam with ε = 1e-5, GAE with a time-limit cut bootstrapped from
V(last observation), advantages normalised per minibatch, unclipped value loss, global gradient-norm clipping,
and ``VecNormalize``'s running observation and reward normalisation where rl-baselines3-zoo sets ``normalize``.

Departures from SB3:

* ``total_steps`` is rounded down to whole updates of ``n_envs * n_steps`` transitions (SB3 rounds up: the zoo's
  1e5 CartPole steps are 390 updates here, 391 there), so a linear schedule ends just above 0, never below;
  and to whole rounds of updates between evaluations (390 updates in 20 rounds: 380 run).
* Resets are drawn from JAX's generator (:mod:`rlcompare.deep.envs`), and minibatch permutations too.
* Gradient clipping is optax's ``clip_by_global_norm`` (PyTorch's ``clip_grad_norm_`` divides by norm + 1e-6).
* Not implemented: ``clip_range_vf``, ``target_kl`` (both off in SB3's defaults and in the zoo presets here),
  gSDE, continuous actions.

MinAtar's images (``(10, 10, channels)`` booleans) go through MinAtar's convolution, in the actor and in the
critic each, as purejaxql's ``ppo_minatar.py`` (Gallici et al. 2024's PPO baseline, from purejaxrl), and its loss
is available: ``value_loss="purejaxrl"``. Its settings are :data:`MINATAR`; where they still depart from that
source is listed there.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, fields
from typing import Any, NamedTuple

import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np
import optax

from rlcompare.deep.atari import NatureTorso, is_frames
from rlcompare.deep.envs import DeepEnv, EnvState, learning_reward, observe_all, reset_all, step_autoreset_all
from rlcompare.deep.networks import ACTIVATIONS, Conv3x3, is_image
from rlcompare.deep.rollout import Act, Episodes, Finished, TrainOutput, track, train_in_rounds
from rlcompare.envs import atari, minatar
from rlcompare.validation import ConfigError

NORMALIZE_EPSILON = 1e-8
"""``VecNormalize``'s ε under the square root, and the advantage normalisation's (SB3)."""
NORMALIZE_CLIP = 10.0
"""``VecNormalize``'s ``clip_obs`` and ``clip_reward``."""
ADAM_EPSILON = 1e-5
"""SB3's Adam ε for its actor-critic policies (``ActorCriticPolicy.__init__``)."""
CONV_CHANNELS = 16
"""MinAtar's convolution: 16 channels of 3 x 3, stride 1, no padding (Young and Tian 2019)."""
VALUE_LOSSES = ("sb3", "purejaxrl")
"""``sb3``: ``mean((R - V)²)`` (SB3's ``F.mse_loss``, no ½); ``purejaxrl``: ``½ mean(max((R - V)², (R - V_clip)²))``,
``V_clip = V_old + clip(V - V_old, ±clip_range)`` (purejaxrl's ``_loss_fn``, as CleanRL's ``clip_vloss``)."""


@dataclass(frozen=True)
class PPOConfig:
    """PPO's settings; the defaults are SB3's ``PPO`` and ``MlpPolicy`` defaults (zoo's ``n_envs: 1`` and
    ``n_timesteps: 1e6``). Frozen and validated on creation."""

    n_envs: int = 1
    """Environments stepped side by side."""
    n_steps: int = 2048
    """Steps per environment collected for each update."""
    batch_size: int = 64
    """Minibatch size (SB3's meaning); must divide ``n_envs * n_steps``."""
    n_epochs: int = 10
    """Passes over each update's transitions, each in a fresh random order."""
    learning_rate: float = 3e-4
    """Adam's step size (at the start, where ``anneal_lr``)."""
    anneal_lr: bool = False
    """Decay the learning rate linearly to 0 over training (the zoo's ``lin_``)."""
    gamma: float = 0.99
    """Discount factor."""
    gae_lambda: float = 0.95
    """GAE's λ (Schulman et al. 2016)."""
    clip_range: float = 0.2
    """The surrogate's ε: the probability ratio is clipped to [1 - ε, 1 + ε] (at the start, where annealed)."""
    anneal_clip_range: bool = False
    """Decay ``clip_range`` linearly to 0 over training (the zoo's ``lin_``)."""
    ent_coef: float = 0.0
    """Weight of the entropy bonus in the loss."""
    vf_coef: float = 0.5
    """Weight of the value loss in the loss."""
    max_grad_norm: float = 0.5
    """The gradient's global norm is clipped to this."""
    normalize_advantage: bool = True
    """Normalise the advantages within each minibatch (to zero mean, unit sample standard deviation)."""
    normalize_observations: bool = False
    """Normalise observations by running mean and variance, clipped to ±10 (``VecNormalize(norm_obs=True)``)."""
    normalize_rewards: bool = False
    """Divide rewards by the running standard deviation of the discounted return, clipped to ±10
    (``VecNormalize(norm_reward=True)``)."""
    hidden: tuple[int, ...] = (64, 64)
    """Widths of the hidden layers of each of the two networks, actor and critic (SB3's ``net_arch``)."""
    activation: str = "tanh"
    """Hidden activation: ``tanh`` (SB3's default) or ``relu``; also after the convolution, for images."""
    total_steps: int = 1_000_000
    """Environment steps of training in all, rounded down to whole updates."""
    value_loss: str = "sb3"
    """The critic's loss: ``sb3`` or ``purejaxrl`` (:data:`VALUE_LOSSES`)."""

    def __post_init__(self) -> None:
        for name, allowed in _CHECKS.items():
            if not allowed.holds(getattr(self, name), self):
                raise ConfigError(name, getattr(self, name), allowed.text)

    @property
    def batch(self) -> int:
        """Transitions collected per update."""
        return self.n_envs * self.n_steps

    @property
    def updates(self) -> int:
        """Updates in the whole training."""
        return self.total_steps // self.batch

    @property
    def minibatches(self) -> int:
        """Minibatches per epoch."""
        return self.batch // self.batch_size


class _Allowed(NamedTuple):
    holds: Callable[[Any, PPOConfig], bool]
    text: str


def _is_int(value: Any) -> bool:
    return isinstance(value, int | np.integer) and not isinstance(value, bool | np.bool_)


def _is_number(value: Any) -> bool:
    return (_is_int(value) or isinstance(value, float | np.floating)) and bool(np.isfinite(value))


def _positive_int(value: Any, _: PPOConfig) -> bool:
    return _is_int(value) and value >= 1


def _is_bool(value: Any, _: PPOConfig) -> bool:
    return isinstance(value, bool)


def _in(low: float, high: float, *, open_low: bool = False) -> Callable[[Any, PPOConfig], bool]:
    def holds(value: Any, _: PPOConfig) -> bool:
        return _is_number(value) and (low < value if open_low else low <= value) and value <= high
    return holds


_CHECKS: dict[str, _Allowed] = {
    "n_envs": _Allowed(_positive_int, "an integer >= 1"),
    "n_steps": _Allowed(_positive_int, "an integer >= 1"),
    "batch_size": _Allowed(lambda v, c: _positive_int(v, c) and (c.n_envs * c.n_steps) % v == 0,
                           "an integer >= 1 dividing n_envs * n_steps"),
    "n_epochs": _Allowed(_positive_int, "an integer >= 1"),
    "learning_rate": _Allowed(_in(0.0, np.inf, open_low=True), "a finite number > 0"),
    "anneal_lr": _Allowed(_is_bool, "true or false"),
    "gamma": _Allowed(_in(0.0, 1.0, open_low=True), "a number in (0, 1]"),
    "gae_lambda": _Allowed(_in(0.0, 1.0), "a number in [0, 1]"),
    "clip_range": _Allowed(_in(0.0, np.inf, open_low=True), "a finite number > 0"),
    "anneal_clip_range": _Allowed(_is_bool, "true or false"),
    "ent_coef": _Allowed(_in(0.0, np.inf), "a finite number >= 0"),
    "vf_coef": _Allowed(_in(0.0, np.inf), "a finite number >= 0"),
    "max_grad_norm": _Allowed(_in(0.0, np.inf, open_low=True), "a finite number > 0"),
    "normalize_advantage": _Allowed(_is_bool, "true or false"),
    "normalize_observations": _Allowed(_is_bool, "true or false"),
    "normalize_rewards": _Allowed(_is_bool, "true or false"),
    "hidden": _Allowed(lambda v, c: isinstance(v, tuple) and all(_positive_int(w, c) for w in v),
                       "a tuple of layer widths, each an integer >= 1"),
    "activation": _Allowed(lambda v, _: v in ACTIVATIONS, " or ".join(ACTIVATIONS)),
    "total_steps": _Allowed(lambda v, c: _is_int(v) and v >= c.n_envs * c.n_steps,
                            "an integer >= n_envs * n_steps (one update)"),
    "value_loss": _Allowed(lambda v, _: v in VALUE_LOSSES, " or ".join(VALUE_LOSSES)),
}
assert set(_CHECKS) == {f.name for f in fields(PPOConfig)}


MINATAR = PPOConfig(n_envs=64, n_steps=128, batch_size=64 * 128 // 8, n_epochs=4, learning_rate=5e-3, anneal_lr=True,
                    gamma=0.99, gae_lambda=0.95, clip_range=0.2, ent_coef=1e-4, vf_coef=0.5, max_grad_norm=0.5,
                    hidden=(128,), activation="relu", total_steps=10_000_000, value_loss="purejaxrl")
"""MinAtar: purejaxql's ``config/alg/ppo_minatar.yaml`` with its ``ppo_minatar.py`` (mttga/purejaxql at 0436c80):
64 environments x 128 steps, 4 epochs x 8 minibatches (of 1,024), Adam at 5e-3 decayed linearly, γ 0.99,
GAE λ 0.95, clip 0.2 (not annealed), entropy 1e-4, value coefficient 0.5 on its clipped, halved value loss,
gradients clipped at 0.5, ReLU, 10 M steps; separate actor and critic, each MinAtar's convolution (16 channels,
flax's default initialisation) and a dense layer of 128 (orthogonal √2), heads orthogonal 0.01 and 1. The same
numbers as purejaxrl's MinAtar notebook (``examples/brax_minatar.ipynb``) but for its entropy 0.01 on a flattened
64 x 64 MLP. Departures: the schedule is SB3's, one update ahead of purejaxrl's (its ``frac`` counts the updates
done, SB3's progress the steps after this rollout); advantages are normalised with ``ddof=1`` (purejaxrl 0: a
factor √(1024/1023)); a time-limit cut (gymnax's protocol) bootstraps from V(last observation), where purejaxrl's
auto-reset treats it as termination; no observation normalisation (booleans)."""

ATARI = PPOConfig(n_envs=8, n_steps=128, batch_size=256, n_epochs=4, learning_rate=2.5e-4, anneal_lr=True,
                  clip_range=0.1, anneal_clip_range=True, ent_coef=0.01, vf_coef=0.5, hidden=(512,), activation="relu",
                  total_steps=10_000_000)
"""Atari: rl-baselines3-zoo's ``atari`` entry of ``hyperparams/ppo.yml`` (8 environments x 128 steps, 4 epochs of
minibatches of 256, Adam at 2.5e-4 and clip 0.1 both decayed linearly, entropy 0.01, value 0.5, 10 M steps), on
SB3's ``CnnPolicy``: one network of Mnih et al. (2015) shared by the policy and the value (orthogonal √2), heads
orthogonal 0.01 and 1; it learns from the score's sign, as SB3's Atari wrapper does."""

ZOO: dict[str, PPOConfig] = {
    "CartPole-v1": PPOConfig(n_envs=8, n_steps=32, batch_size=256, gae_lambda=0.8, gamma=0.98, n_epochs=20,
                             ent_coef=0.0, learning_rate=1e-3, anneal_lr=True, clip_range=0.2,
                             anneal_clip_range=True, total_steps=100_000),
    "Acrobot-v1": PPOConfig(n_envs=16, n_steps=256, gae_lambda=0.94, gamma=0.99, n_epochs=4, ent_coef=0.0,
                            normalize_observations=True, normalize_rewards=True, total_steps=1_000_000),
    "MountainCar-v0": PPOConfig(n_envs=16, n_steps=16, gae_lambda=0.98, gamma=0.99, n_epochs=4, ent_coef=0.0,
                                normalize_observations=True, normalize_rewards=True, total_steps=1_000_000),
    **dict.fromkeys(minatar.NAMES, MINATAR),
    **dict.fromkeys(atari.NAMES, ATARI),
}
"""Environment -> rl-baselines3-zoo's tuned PPO settings, ``hyperparams/ppo.yml`` (DLR-RM/rl-baselines3-zoo at
22e3ff2, 2026-04): ``lin_x`` is ``x`` with the matching ``anneal_*``; ``normalize: true`` is ``VecNormalize`` of
observations and rewards (with the algorithm's γ); fields the file leaves out keep SB3's defaults. The zoo has no
MinAtar: every MinAtar name, both protocols, has purejaxql's settings (:data:`MINATAR`)."""

PRESETS: dict[str, dict[str, PPOConfig]] = {"default": ZOO}
"""Preset name -> environment -> config. ``default``: the zoo's for classic control, purejaxql's for MinAtar
(:data:`ZOO`)."""


# --- networks (SB3's MlpPolicy: separate actor and critic, orthogonal initialisation, zero biases) ---

def gram_schmidt(a: jax.Array) -> jax.Array:
    """The ``Q`` of ``a``'s QR decomposition with ``R``'s diagonal positive, ``a`` ``(n, m)`` with ``n >= m``: classical
    Gram-Schmidt, each column orthogonalised twice (CGS2, orthogonal to rounding), in plain JAX operations."""

    def column(j: jax.Array, q: jax.Array) -> jax.Array:
        v = jax.lax.dynamic_index_in_dim(a, j, axis=1, keepdims=False)
        for _ in range(2):
            v = v - q @ (q.T @ v)  # q's columns from j on are still 0
        return jax.lax.dynamic_update_index_in_dim(q, v / jnp.linalg.norm(v), j, axis=1)

    return jax.lax.fori_loop(0, a.shape[1], column, jnp.zeros_like(a))


def orthogonal(scale: float) -> nn.initializers.Initializer:
    """flax's ``orthogonal(scale)`` for a dense kernel (the same Gaussian matrix, its QR's ``Q`` with the signs that
    make ``R``'s diagonal positive, scaled), with the QR by :func:`gram_schmidt` in place of LAPACK's: jaxlib 0.10's
    batched CPU QR (``lapack_sorgqr_ffi``) splits its batch over the thread pool it runs on and waits, so as many
    such QRs at once as the pool has threads wait forever (measured: two 1024 x 128 kernels under ``vmap`` of two
    seeds, on 2 cores, as MinAtar's actor and critic are). Equal to flax's within float32 rounding."""

    def init(key: jax.Array, shape: Sequence[int], dtype: Any = jnp.float32) -> jax.Array:
        rows, columns = shape
        gaussian = jax.random.normal(key, (columns, rows) if rows < columns else (rows, columns), dtype)
        q = gram_schmidt(gaussian)
        return scale * (q.T if rows < columns else q)

    return init


class OrthogonalMLP(nn.Module):
    """``observation -> outputs``: dense layers initialised orthogonally with gain √2, each followed by the
    activation, then a linear layer with gain ``last_scale`` (SB3's ``ActorCriticPolicy`` with ``ortho_init``);
    :class:`~rlcompare.deep.networks.MLP` keeps flax's LeCun-normal hidden layers. With ``conv_channels``, an image
    ``(..., H, W, C)`` first goes through a 3 x 3 convolution of that many channels (flax's default LeCun-normal
    initialisation, as ``nn.Conv``), the activation, and is flattened (purejaxql ``ppo_minatar.py``); the dense
    layers are then initialised by :func:`orthogonal`, without LAPACK."""

    hidden: Sequence[int]
    outputs: int
    activation: str
    last_scale: float
    conv_channels: int = 0
    """0: no convolution (a vector observation)."""

    @nn.compact
    def __call__(self, x: jax.Array) -> jax.Array:
        x = x.astype(jnp.float32)
        if self.conv_channels:
            x = ACTIVATIONS[self.activation](Conv3x3(self.conv_channels)(x))
            x = x.reshape(*x.shape[:-3], -1)
        init = orthogonal if self.conv_channels else nn.initializers.orthogonal  # classic control: as it was
        for width in self.hidden:
            x = nn.Dense(width, kernel_init=init(np.sqrt(2.0)), param_dtype=jnp.float32, dtype=jnp.float32)(x)
            x = ACTIVATIONS[self.activation](x)
        return nn.Dense(self.outputs, kernel_init=init(self.last_scale), param_dtype=jnp.float32,
                        dtype=jnp.float32)(x)


class ActorCritic(nn.Module):
    """``observation -> (logits, value)`` from two separate networks; the policy head's gain is 0.01, the value
    head's 1.0 (SB3, purejaxrl). For images each has its own convolution (purejaxql ``ppo_minatar.py``)."""

    hidden: Sequence[int]
    n_actions: int
    activation: str
    conv_channels: int = 0

    def setup(self) -> None:
        self.actor = OrthogonalMLP(self.hidden, self.n_actions, self.activation, 0.01, self.conv_channels)
        self.critic = OrthogonalMLP(self.hidden, 1, self.activation, 1.0, self.conv_channels)

    def __call__(self, observation: jax.Array) -> tuple[jax.Array, jax.Array]:
        return self.logits(observation), self.value(observation)

    def logits(self, observation: jax.Array) -> jax.Array:
        return self.actor(observation)

    def value(self, observation: jax.Array) -> jax.Array:
        return self.critic(observation)[..., 0]


class SharedActorCritic(nn.Module):
    """SB3's ``CnnPolicy`` on Atari: one network of Mnih et al. (2015) (orthogonal √2, zero biases) feeds a policy
    head (orthogonal 0.01) and a value head (orthogonal 1), as :class:`ActorCritic` is called."""

    hidden: Sequence[int]
    n_actions: int

    def setup(self) -> None:
        self.torso = NatureTorso(self.hidden, kernel_init=kernel_orthogonal(np.sqrt(2.0)))
        self.policy_head = nn.Dense(self.n_actions, kernel_init=orthogonal(0.01), param_dtype=jnp.float32)
        self.value_head = nn.Dense(1, kernel_init=orthogonal(1.0), param_dtype=jnp.float32)

    def __call__(self, observation: jax.Array) -> tuple[jax.Array, jax.Array]:
        features = self.torso(observation)
        return self.policy_head(features), self.value_head(features)[..., 0]

    def logits(self, observation: jax.Array) -> jax.Array:
        return self.policy_head(self.torso(observation))

    def value(self, observation: jax.Array) -> jax.Array:
        return self.value_head(self.torso(observation))[..., 0]


def kernel_orthogonal(scale: float) -> nn.initializers.Initializer:
    """:func:`orthogonal` for a kernel of any rank, as flax's and torch's take it: a matrix of its inputs (all axes
    but the last) by its outputs."""

    def init(key: jax.Array, shape: Sequence[int], dtype: Any = jnp.float32) -> jax.Array:
        return orthogonal(scale)(key, (int(np.prod(shape[:-1])), shape[-1]), dtype).reshape(shape)

    return init


def network(config: PPOConfig, env: DeepEnv) -> ActorCritic | SharedActorCritic:
    """The flax module whose variables are :attr:`PolicyParams.network`: MLPs, for MinAtar's images MinAtar's
    convolution before each, for Atari's one network of Mnih et al. shared by both heads."""
    if is_frames(env.observation_shape):
        return SharedActorCritic(config.hidden, env.n_actions)
    channels = CONV_CHANNELS if is_image(env.observation_shape) else 0
    return ActorCritic(config.hidden, env.n_actions, config.activation, channels)


# --- running normalisation (SB3's RunningMeanStd and VecNormalize; statistics in float64, as there) ---

class RunningMeanStd(NamedTuple):
    """Running mean and (population) variance of a stream of batches (Chan et al.'s parallel update)."""

    mean: jax.Array
    var: jax.Array
    count: jax.Array

    @classmethod
    def start(cls, shape: tuple[int, ...]) -> RunningMeanStd:
        """SB3's start: mean 0, variance 1, count 1e-4."""
        return cls(jnp.zeros(shape, jnp.float64), jnp.ones(shape, jnp.float64), jnp.asarray(1e-4, jnp.float64))


def update_running(stats: RunningMeanStd, batch: jax.Array) -> RunningMeanStd:
    """Add a batch (leading axis) to the statistics (SB3's ``RunningMeanStd.update``)."""
    batch = batch.astype(jnp.float64)
    batch_mean, batch_var, batch_count = batch.mean(axis=0), batch.var(axis=0), batch.shape[0]
    delta = batch_mean - stats.mean
    count = stats.count + batch_count
    m2 = stats.var * stats.count + batch_var * batch_count + delta**2 * stats.count * batch_count / count
    return RunningMeanStd(stats.mean + delta * batch_count / count, m2 / count, count)


def normalize_observation(observation: jax.Array, stats: RunningMeanStd) -> jax.Array:
    """``VecNormalize.normalize_obs``: standardised, clipped to ±10, float32."""
    scaled = (observation - stats.mean) / jnp.sqrt(stats.var + NORMALIZE_EPSILON)
    return jnp.clip(scaled, -NORMALIZE_CLIP, NORMALIZE_CLIP).astype(jnp.float32)


def normalize_reward(reward: jax.Array, stats: RunningMeanStd) -> jax.Array:
    """``VecNormalize.normalize_reward``: divided by the discounted return's standard deviation, clipped to ±10."""
    return jnp.clip(reward / jnp.sqrt(stats.var + NORMALIZE_EPSILON), -NORMALIZE_CLIP, NORMALIZE_CLIP
                    ).astype(jnp.float32)


class PolicyParams(NamedTuple):
    """What the greedy policy needs: the network's variables and the observation statistics (left at their
    start, and unused, without ``normalize_observations``; always so for images)."""

    network: Any
    observations: RunningMeanStd


def init_params(config: PPOConfig, env: DeepEnv, key: jax.Array) -> PolicyParams:
    """Fresh parameters; also the template to restore saved ones into."""
    variables = network(config, env).init(key, jnp.zeros((1, *env.observation_shape), jnp.float32))
    return PolicyParams(variables, RunningMeanStd.start(env.observation_shape))


def _observe(config: PPOConfig, params: PolicyParams, observation: jax.Array) -> jax.Array:
    """What the network and the rollout buffer see: normalised where ``normalize_observations``; images stay
    booleans (the network casts them); vectors float32."""
    if config.normalize_observations:
        return normalize_observation(observation, params.observations)
    return observation if observation.dtype == jnp.bool_ else observation.astype(jnp.float32)


def act(config: PPOConfig, env: DeepEnv) -> Act:
    """``(params, raw observations) -> greedy actions``: the argmax of the logits (SB3's ``deterministic=True``),
    observations normalised with the frozen statistics where trained so (the zoo's evaluation)."""
    module = network(config, env)

    def greedy(params: PolicyParams, observation: jax.Array) -> jax.Array:
        logits = module.apply(params.network, _observe(config, params, observation), method="logits")
        return jnp.argmax(logits, axis=-1)

    return greedy


# --- the pieces of the objective ---

def gae(rewards: jax.Array, values: jax.Array, next_values: jax.Array, terminated: jax.Array, dones: jax.Array,
        gamma: float, lam: float) -> jax.Array:
    """Generalised advantage estimates (Schulman et al. 2016), time-major ``(steps, envs)``.

    ``next_values[t]`` is V of the observation step ``t`` led to (before any reset); it counts unless the episode
    terminated, so a time-limit cut bootstraps from it, as SB3's ``rewards += gamma * V(terminal_observation)``;
    the trace stops where an episode ended either way (``dones``).
    """
    continues = 1.0 - terminated.astype(values.dtype)
    deltas = rewards + gamma * next_values * continues - values
    carries = gamma * lam * (1.0 - dones.astype(values.dtype))

    def backward(later: jax.Array, step: tuple[jax.Array, jax.Array]) -> tuple[jax.Array, jax.Array]:
        delta, carry = step
        advantage = delta + carry * later
        return advantage, advantage

    _, advantages = jax.lax.scan(backward, jnp.zeros_like(values[0]), (deltas, carries), reverse=True)
    return advantages


def normalize_advantages(advantages: jax.Array) -> jax.Array:
    """Zero mean, unit sample standard deviation (``ddof=1``, PyTorch's ``std``), as SB3 per minibatch."""
    return (advantages - advantages.mean()) / (advantages.std(ddof=1) + NORMALIZE_EPSILON)


def clipped_surrogate_loss(log_prob: jax.Array, old_log_prob: jax.Array, advantages: jax.Array,
                           clip_range: float | jax.Array) -> jax.Array:
    """``-mean(min(r A, clip(r, 1 - ε, 1 + ε) A))`` with ``r = π(a|s) / π_old(a|s)`` (Schulman et al. 2017, eq. 7)."""
    ratio = jnp.exp(log_prob - old_log_prob)
    clipped = jnp.clip(ratio, 1.0 - clip_range, 1.0 + clip_range)
    return -jnp.minimum(ratio * advantages, clipped * advantages).mean()


def value_loss(values: jax.Array, returns: jax.Array) -> jax.Array:
    """Mean squared error to the TD(λ) returns, unclipped and without a ½ (SB3's ``F.mse_loss``)."""
    return jnp.mean((returns - values) ** 2)


def clipped_value_loss(values: jax.Array, old_values: jax.Array, returns: jax.Array,
                       clip_range: float | jax.Array) -> jax.Array:
    """purejaxrl's: ``½ mean(max((V - R)², (V_old + clip(V - V_old, ±ε) - R)²))``, the pessimistic of the value and
    the value kept within ``ε`` of the one the rollout recorded (``purejaxrl/ppo.py``, ``_loss_fn``)."""
    clipped = old_values + jnp.clip(values - old_values, -clip_range, clip_range)
    return 0.5 * jnp.maximum((values - returns) ** 2, (clipped - returns) ** 2).mean()


def entropy(logits: jax.Array) -> jax.Array:
    """Entropy of each categorical distribution given by ``logits`` (last axis)."""
    log_p = jax.nn.log_softmax(logits)
    return -jnp.sum(jnp.exp(log_p) * log_p, axis=-1)


def log_probability(logits: jax.Array, actions: jax.Array) -> jax.Array:
    """``log π(a|s)`` of each action under the categorical ``logits``."""
    return jnp.take_along_axis(jax.nn.log_softmax(logits), actions[..., None], axis=-1)[..., 0]


class Batch(NamedTuple):
    """Transitions to learn from, with what the policy said when it acted."""

    observations: jax.Array
    actions: jax.Array
    log_probs: jax.Array
    advantages: jax.Array
    returns: jax.Array
    values: jax.Array
    """V(s) when the action was taken (for ``value_loss="purejaxrl"``)."""


def ppo_loss(module: ActorCritic, variables: Any, batch: Batch, clip_range: jax.Array, config: PPOConfig
             ) -> jax.Array:
    """SB3's loss: ``policy_loss - ent_coef * entropy + vf_coef * value_loss`` on one minibatch, the value loss
    SB3's or purejaxrl's (``config.value_loss``)."""
    logits, values = module.apply(variables, batch.observations)
    advantages = batch.advantages
    if config.normalize_advantage and config.batch_size > 1:
        advantages = normalize_advantages(advantages)
    policy = clipped_surrogate_loss(log_probability(logits, batch.actions), batch.log_probs, advantages, clip_range)
    critic = (clipped_value_loss(values, batch.values, batch.returns, clip_range) if config.value_loss == "purejaxrl"
              else value_loss(values, batch.returns))
    return policy - config.ent_coef * entropy(logits).mean() + config.vf_coef * critic


def progress_remaining(config: PPOConfig, update: jax.Array) -> jax.Array:
    """SB3's ``1 - num_timesteps / total_timesteps`` during update ``update`` (from 0), its rollout counted."""
    return 1.0 - (update + 1) * config.batch / config.total_steps


def optimizer(config: PPOConfig) -> optax.GradientTransformation:
    """Global-norm clipping, then Adam (ε 1e-5), its step size annealed per update where ``anneal_lr``."""
    steps_per_update = config.n_epochs * config.minibatches

    def learning_rate(count: jax.Array) -> jax.Array:
        scale = progress_remaining(config, count // steps_per_update) if config.anneal_lr else 1.0
        return jnp.asarray(config.learning_rate * scale, jnp.float32)

    return optax.chain(optax.clip_by_global_norm(config.max_grad_norm),
                       optax.adam(learning_rate, eps=ADAM_EPSILON))


# --- the training program ---

class Runner(NamedTuple):
    """Everything one seed's training carries from update to update."""

    params: PolicyParams
    opt_state: Any
    rewards: RunningMeanStd
    """Statistics of the discounted return, for ``normalize_rewards``."""
    discounted: jax.Array
    """(envs,) each environment's running discounted return, for ``normalize_rewards``."""
    env_state: EnvState
    observation: jax.Array
    """(envs, *observation shape): float32, normalised where ``normalize_observations``; images booleans."""
    episodes: Episodes
    update: jax.Array


class Transition(NamedTuple):
    observation: jax.Array
    action: jax.Array
    log_prob: jax.Array
    value: jax.Array
    reward: jax.Array
    """Normalised where ``normalize_rewards``."""
    last_observation: jax.Array
    terminated: jax.Array
    done: jax.Array


def make_train(config: PPOConfig, env: DeepEnv, rounds: int, eval_episodes: int
               ) -> Callable[[jax.Array], TrainOutput]:
    """``key -> TrainOutput``: one seed's training, ``config.updates // rounds`` updates in each of ``rounds``
    rounds (the remainder, fewer than ``rounds`` updates, is not run; the schedules still span ``total_steps``),
    with a greedy evaluation of ``eval_episodes`` episodes after each; ``finished`` is ``(rounds, updates per
    round, n_steps, n_envs)``. Jit-able and vmap-able over keys."""
    if not _is_int(rounds) or not 1 <= rounds <= config.updates:
        raise ConfigError("total_steps", config.total_steps, f"at least {rounds} updates of n_envs x n_steps = "
                                                             f"{config.batch} steps (one per evaluation round)")
    if config.normalize_observations and is_image(env.observation_shape):
        raise ConfigError("normalize_observations", True, "false for images (MinAtar's are booleans)")
    module = network(config, env)
    tx = optimizer(config)
    greedy = act(config, env)

    def step(runner: Runner, key: jax.Array) -> tuple[Runner, tuple[Transition, Finished]]:
        action_key, reset_key = jax.random.split(key)
        logits, value = module.apply(runner.params.network, runner.observation)
        action = jax.random.categorical(action_key, logits)
        out = step_autoreset_all(env, runner.env_state, action, jax.random.split(reset_key, config.n_envs))
        episodes, finished = track(runner.episodes, out.reward, out.terminated, out.truncated)
        done = out.terminated | out.truncated
        params, reward_stats, discounted = runner.params, runner.rewards, runner.discounted
        reward = learning_reward(env, out.reward)
        if config.normalize_observations:
            params = params._replace(observations=update_running(params.observations, out.observation))
        if config.normalize_rewards:
            discounted = discounted * config.gamma + reward
            reward_stats = update_running(reward_stats, discounted)
            reward = normalize_reward(reward, reward_stats)
            discounted = jnp.where(done, 0.0, discounted)
        transition = Transition(runner.observation, action, log_probability(logits, action), value,
                                reward.astype(jnp.float32), _observe(config, params, out.last_observation),
                                out.terminated, done)
        runner = runner._replace(params=params, rewards=reward_stats, discounted=discounted, env_state=out.state,
                                 observation=_observe(config, params, out.observation), episodes=episodes)
        return runner, (transition, finished)

    def minibatch_step(carry: tuple[Any, Any, jax.Array], batch: Batch) -> tuple[tuple[Any, Any, jax.Array], None]:
        variables, opt_state, clip_range = carry
        grads = jax.grad(lambda v: ppo_loss(module, v, batch, clip_range, config))(variables)
        updates, opt_state = tx.update(grads, opt_state, variables)
        return (optax.apply_updates(variables, updates), opt_state, clip_range), None

    def epoch(carry: tuple[Any, Any, jax.Array], key: jax.Array, batch: Batch
              ) -> tuple[tuple[Any, Any, jax.Array], None]:
        order = jax.random.permutation(key, config.batch)
        shuffled = jax.tree.map(lambda x: x[order].reshape(config.minibatches, config.batch_size, *x.shape[1:]),
                                batch)
        carry, _ = jax.lax.scan(minibatch_step, carry, shuffled)
        return carry, None

    def update(runner: Runner, key: jax.Array) -> tuple[Runner, Finished]:
        rollout_key, epochs_key = jax.random.split(key)
        runner, (transitions, finished) = jax.lax.scan(step, runner, jax.random.split(rollout_key, config.n_steps))
        next_values = module.apply(runner.params.network, transitions.last_observation, method="value")
        advantages = gae(transitions.reward, transitions.value, next_values, transitions.terminated,
                         transitions.done, config.gamma, config.gae_lambda)
        flat = jax.tree.map(lambda x: x.reshape(config.batch, *x.shape[2:]),
                            Batch(transitions.observation, transitions.action, transitions.log_prob, advantages,
                                  advantages + transitions.value, transitions.value))
        clip_range = config.clip_range * (progress_remaining(config, runner.update)
                                          if config.anneal_clip_range else 1.0)
        carry = (runner.params.network, runner.opt_state, jnp.asarray(clip_range, jnp.float32))
        (variables, opt_state, _), _ = jax.lax.scan(lambda c, k: epoch(c, k, flat), carry,
                                                    jax.random.split(epochs_key, config.n_epochs))
        runner = runner._replace(params=runner.params._replace(network=variables), opt_state=opt_state,
                                 update=runner.update + 1)
        return runner, finished

    run = train_in_rounds(update, lambda runner: runner.params, env, greedy, rounds, config.updates // rounds,
                          eval_episodes)

    def train(key: jax.Array) -> TrainOutput:
        init_key, reset_key, train_key = jax.random.split(key, 3)
        params = init_params(config, env, init_key)
        env_state = reset_all(env, jax.random.split(reset_key, config.n_envs))
        observation = observe_all(env, env_state)
        if config.normalize_observations:
            params = params._replace(observations=update_running(params.observations, observation))
        runner = Runner(params, tx.init(params.network), RunningMeanStd.start(()),
                        jnp.zeros(config.n_envs, jnp.float64), env_state, _observe(config, params, observation),
                        Episodes.start(config.n_envs), jnp.zeros((), jnp.int32))
        return run(runner, train_key)

    return train
