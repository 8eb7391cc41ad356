"""The networks of the deep methods (flax): multilayer perceptrons, float32 whatever JAX's default."""

from __future__ import annotations

from collections.abc import Sequence

import flax.linen as nn
import jax
import jax.numpy as jnp

ACTIVATIONS = {"relu": nn.relu, "tanh": nn.tanh}


class MLP(nn.Module):
    """``observation -> outputs`` through dense layers, each followed by LayerNorm (PQN, Gallici et al. 2024,
    where ``layer_norm``) and the activation; the last layer is linear."""

    hidden: Sequence[int]
    outputs: int
    activation: str = "relu"
    layer_norm: bool = False
    last_scale: float = 1.0
    """Scale of the last layer's orthogonal initialisation (PPO's 0.01 for the policy); 1.0 keeps flax's default."""
    box: tuple[tuple[float, ...], tuple[float, ...]] | None = None
    """``(low, high)`` of the observation: inputs are mapped linearly onto [-1, 1] first (None: as they are)."""

    @nn.compact
    def __call__(self, x: jax.Array) -> jax.Array:
        x = x.astype(jnp.float32)
        if self.box is not None:
            low, high = (jnp.asarray(bound, jnp.float32) for bound in self.box)
            x = 2.0 * (x - low) / (high - low) - 1.0
        for width in self.hidden:
            x = nn.Dense(width, param_dtype=jnp.float32, dtype=jnp.float32)(x)
            if self.layer_norm:
                x = nn.LayerNorm(param_dtype=jnp.float32, dtype=jnp.float32)(x)
            x = ACTIVATIONS[self.activation](x)
        init = nn.initializers.lecun_normal() if self.last_scale == 1.0 else nn.initializers.orthogonal(self.last_scale)
        return nn.Dense(self.outputs, kernel_init=init, param_dtype=jnp.float32, dtype=jnp.float32)(x)
