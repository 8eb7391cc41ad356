"""PPO's networks: SB3's ``MlpPolicy`` (separate actor and critic, orthogonal initialisation, zero biases), MinAtar's
convolution in each, or Mnih et al.'s network shared by both on the Atari 2600 (:mod:`rlcompare.deep.ppo`)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np

from rlcompare.deep.atari import NatureTorso, is_frames
from rlcompare.deep.envs import Environment
from rlcompare.deep.networks import ACTIVATIONS, Conv3x3, is_image
from rlcompare.deep.presets.ppo import PPOConfig

CONV_CHANNELS = 16
"""MinAtar's convolution: 16 channels of 3 x 3, stride 1, no padding (Young and Tian 2019)."""


def gram_schmidt(a: jax.Array) -> jax.Array:
    """The ``Q`` of ``a``'s QR decomposition with ``R``'s diagonal positive, ``a`` ``(n, m)`` with ``n >= m``: classical
    Gram-Schmidt, each column orthogonalised twice (CGS2, orthogonal to rounding), in plain JAX operations."""

    def column(j: jax.Array, q: jax.Array) -> jax.Array:
        v = jax.lax.dynamic_index_in_dim(a, j, axis=1, keepdims=False)
        for _ in range(2):
            v = v - q @ (q.T @ v)  # q's columns from j on are still 0
        updated: jax.Array = jax.lax.dynamic_update_index_in_dim(q, v / jnp.linalg.norm(v), j, axis=1)
        return updated

    orthonormal: jax.Array = jax.lax.fori_loop(0, a.shape[1], column, jnp.zeros_like(a))
    return orthonormal


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


def network(config: PPOConfig, env: Environment) -> ActorCritic | SharedActorCritic:
    """The flax module whose variables are :attr:`PolicyParams.network`: MLPs, for MinAtar's images MinAtar's
    convolution before each, for Atari's one network of Mnih et al. shared by both heads."""
    if is_frames(env.observation_shape):
        return SharedActorCritic(config.hidden, env.n_actions)
    channels = CONV_CHANNELS if is_image(env.observation_shape) else 0
    return ActorCritic(config.hidden, env.n_actions, config.activation, channels)


# --- running normalisation (SB3's RunningMeanStd and VecNormalize; statistics in float64, as there) ---

