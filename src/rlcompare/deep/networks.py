"""The networks of the deep methods (flax): multilayer perceptrons, float32 whatever JAX's default."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Protocol

import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np

ACTIVATIONS = {"relu": nn.relu, "tanh": nn.tanh}


class Network(Protocol):
    """A flax module as the methods use it: ``init(key, inputs)`` gives its variables, ``apply(variables, inputs)``
    (or ``method=`` another of its methods) its output, an array or a tuple of them. flax types an ``apply`` as
    possibly giving the variables it changed as well, which it does only when asked to (``mutable``), never here."""

    def init(self, rngs: Any, *inputs: Any, **options: Any) -> Any: ...

    def apply(self, variables: Any, *inputs: Any, **options: Any) -> Any: ...


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
    board: bool = False
    """Observations are a board's planes ``(..., rows, columns, planes)``, read as one vector."""

    @nn.compact
    def __call__(self, x: jax.Array) -> jax.Array:
        x = x.astype(jnp.float32)
        if self.board:
            x = x.reshape(*x.shape[:-3], -1)
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


def patches_3x3(x: jax.Array) -> jax.Array:
    """``(..., H, W, C) -> (..., H - 2, W - 2, 9 C)``: every 3 x 3 window of an image, its values ordered by channel,
    then row, then column, in ``x``'s dtype: the values of ``lax.conv_general_dilated_patches`` in its order
    (``tests/unit/test_deep_networks.py``), taken by one gather, several times faster on a CPU than that one-hot
    convolution, and faster than stacking nine shifted slices (which XLA:CPU then interleaves): PQN and PPO on
    MinAtar take about a quarter more steps per second, the same bits."""
    height, width, depth = x.shape[-3:]
    cells = np.arange(height * width * depth).reshape(height, width, depth)
    index = np.stack([cells[row:row + height - 2, column:column + width - 2] for row in range(3)
                      for column in range(3)], axis=-1)  # (H - 2, W - 2, C, 9): flat positions in the image
    return jnp.take(x.reshape(*x.shape[:-3], -1), index.reshape(height - 2, width - 2, 9 * depth), axis=-1,
                    mode="clip")


class Conv3x3(nn.Module):
    """A 3 x 3 convolution, stride 1, no padding, computed as a dense layer over :func:`patches_3x3`: the same
    function as ``nn.Conv(features, (3, 3), padding="VALID")`` (its kernel is this one's, reshaped;
    ``tests/unit/test_deep_networks.py``), about ten times faster on a CPU, where XLA's convolution is slow for small
    images."""

    features: int
    kernel_init: nn.initializers.Initializer = nn.initializers.lecun_normal()

    @nn.compact
    def __call__(self, x: jax.Array) -> jax.Array:
        return nn.Dense(self.features, kernel_init=self.kernel_init, param_dtype=jnp.float32,
                        dtype=jnp.float32)(patches_3x3(x))


class ConvNet(nn.Module):
    """MinAtar's network (Young and Tian 2019): one 3 x 3 convolution of 16 channels, then dense layers of
    ``hidden``, each followed by LayerNorm where ``layer_norm`` (PQN, purejaxql ``pqn_minatar.py``) and ReLU; the
    last layer is linear. Observations are images ``(..., 10, 10, channels)`` of booleans."""

    outputs: int
    channels: int = 16
    hidden: Sequence[int] = (128,)
    layer_norm: bool = False
    last_scale: float = 1.0
    """Scale of the last layer's orthogonal initialisation (PPO's 0.01 for the policy); 1.0 keeps flax's default."""

    @nn.compact
    def __call__(self, x: jax.Array) -> jax.Array:
        x = self.normalised(Conv3x3(self.channels)(x.astype(jnp.float32)))  # over the channels of each cell
        x = x.reshape(*x.shape[:-3], -1)
        for width in self.hidden:
            x = self.normalised(nn.Dense(width, param_dtype=jnp.float32, dtype=jnp.float32)(x))
        init = nn.initializers.lecun_normal() if self.last_scale == 1.0 else nn.initializers.orthogonal(self.last_scale)
        return nn.Dense(self.outputs, kernel_init=init, param_dtype=jnp.float32, dtype=jnp.float32)(x)

    def normalised(self, x: jax.Array) -> jax.Array:
        if self.layer_norm:
            x = nn.LayerNorm(param_dtype=jnp.float32, dtype=jnp.float32)(x)
        return nn.relu(x)


def is_image(observation_shape: tuple[int, ...]) -> bool:
    """Observations that :class:`ConvNet` reads: ``(height, width, channels)``."""
    return len(observation_shape) == 3
