"""A circular replay buffer (Lin 1992; Mnih et al. 2015) in JAX: transitions along a leading axis, the newest
overwriting the oldest, batches drawn uniformly with replacement as SB3's ``ReplayBuffer`` draws them."""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp


class Transitions(NamedTuple):
    """Transitions along a leading axis, as the buffer stores them."""

    observations: jax.Array
    """(n, *observation shape) in the environment's dtype: float32 vectors (classic control), booleans (MinAtar)"""
    actions: jax.Array
    """(n,) int32"""
    rewards: jax.Array
    """(n,) float32"""
    next_observations: jax.Array
    """(n, *observation shape), as ``observations``: the observation the action led to, before any reset (a
    time-limit cut bootstraps from it)."""
    terminated: jax.Array
    """(n,) bool: a terminal state, whose value is zero; a time-limit cut is not one."""


class Buffer(NamedTuple):
    """A circular replay buffer (Mnih et al. 2015; Lin 1992): the newest transitions overwrite the oldest."""

    data: Transitions
    """``capacity`` rows; those past ``size`` are zeros."""
    position: jax.Array
    """int32, the slot the next transition goes to."""
    size: jax.Array
    """int32, filled slots."""


def buffer_init(capacity: int, observation_shape: int | tuple[int, ...], dtype: jnp.dtype = jnp.float32) -> Buffer:
    """An empty buffer of ``capacity`` transitions whose observations have ``observation_shape`` (a size: a vector)
    and ``dtype`` (MinAtar's booleans take a byte a cell: 100,000 x 10 x 10 x 10 is 10 MB a copy, not 40)."""
    shape = (capacity, observation_shape) if isinstance(observation_shape, int) else (capacity, *observation_shape)
    data = Transitions(jnp.zeros(shape, dtype), jnp.zeros(capacity, jnp.int32), jnp.zeros(capacity, jnp.float32),
                       jnp.zeros(shape, dtype), jnp.zeros(capacity, bool))
    return Buffer(data, jnp.zeros((), jnp.int32), jnp.zeros((), jnp.int32))


def buffer_bytes(capacity: int, observation: jax.ShapeDtypeStruct) -> int:
    """Bytes a buffer of ``capacity`` transitions holds (:func:`buffer_init`): two observations of the shape and
    dtype of ``observation``, an int32 action, a float32 reward and a bool ending each."""
    return capacity * (2 * int(observation.size) * int(observation.dtype.itemsize) + 4 + 4 + 1)


def buffer_add(buffer: Buffer, batch: Transitions) -> Buffer:
    """``batch`` (at most ``capacity`` rows, cast to the buffer's dtypes) written after the newest, wrapping."""
    capacity, n = buffer.data.actions.shape[0], batch.actions.shape[0]
    slots = (buffer.position + jnp.arange(n, dtype=jnp.int32)) % capacity
    data = jax.tree.map(lambda store, new: store.at[slots].set(new.astype(store.dtype)), buffer.data, batch)
    return Buffer(data, (buffer.position + n) % capacity, jnp.minimum(buffer.size + n, capacity))


def buffer_sample(buffer: Buffer, key: jax.Array, batch_size: int) -> Transitions:
    """``batch_size`` filled transitions drawn uniformly with replacement (SB3's ``ReplayBuffer.sample``)."""
    index = jax.random.randint(key, (batch_size,), 0, buffer.size)
    sampled: Transitions = jax.tree.map(lambda store: store[index], buffer.data)
    return sampled


