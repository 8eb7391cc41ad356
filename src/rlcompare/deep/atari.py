"""Atari 2600 games for the deep engine: ALE's vector environment (``ale_py.AtariVectorEnv``, the emulator and
the preprocessing in C++ threads) under :mod:`rlcompare.envs.atari.games`'s protocol, stepped from inside the jitted
training through ``jax.experimental.io_callback``, and the network of Mnih et al. (2015).

The emulator's state lives outside JAX, so this environment is batched, not vmapped: the engine resets and steps
all its parallel games at once (:func:`rlcompare.deep.envs.reset_all`, :func:`~rlcompare.deep.envs.step_all`),
and a training holds one emulator per role (training, evaluation). The state JAX carries is the current
observation. One seed trains at a time (``vmap_width`` 1): under ``vmap`` the callbacks of several seeds would
share one emulator; and one program plays the process's emulators at a time (:func:`rlcompare.deep.envs.playing`).
A game's draws (sticky actions) come from the emulator's generator, seeded at each reset from the training's key,
so a seed's training is the same each time it runs.
"""

from __future__ import annotations

import atexit
import functools
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np
from jax.experimental import io_callback

from rlcompare.deep.envs import Step
from rlcompare.envs.atari import games as atari
from rlcompare.envs.atari.games import ACTION_NAMES, PROTOCOL, Protocol

_EMULATORS: dict[tuple[AtariEnv, str, int], Any] = {}
"""One ``AtariVectorEnv`` per (environment, role, number of games), made at its first reset."""


@atexit.register
def close_emulators() -> None:
    """Stop every emulator's threads and free it (one left to the interpreter's end makes nanobind warn)."""
    while _EMULATORS:
        _EMULATORS.popitem()[1].close()


@dataclass(frozen=True)
class AtariEnv:
    """One game under :data:`~rlcompare.envs.atari.games.PROTOCOL`, with the batched interface of the deep engine:
    ``reset_batch(keys, role)``, ``step_batch(state, actions, keys, role)``, ``step_autoreset_batch`` and
    ``observe_batch``; ``role`` (training, evaluation) names the emulator that plays."""

    name: str
    rom: str
    protocol: Protocol = PROTOCOL
    batched = True
    """Stepped all at once by the host, not vmapped (:mod:`rlcompare.deep.envs`)."""

    @property
    def n_actions(self) -> int:
        return len(ACTION_NAMES)

    @property
    def action_names(self) -> tuple[str, ...]:
        return ACTION_NAMES

    @property
    def observation_shape(self) -> tuple[int, int, int]:
        return self.protocol.observation_shape

    @property
    def max_steps(self) -> int:
        return self.protocol.max_steps

    @property
    def eval_epsilon(self) -> float:
        return self.protocol.eval_epsilon

    @staticmethod
    def learning_reward(reward: jax.Array) -> jax.Array:
        """The reward the methods learn from: the score's sign (Mnih et al. 2015); the records keep the score."""
        return jnp.sign(reward)

    def emulator(self, role: str, n: int) -> Any:
        """The vector environment of ``n`` games that plays ``role``: the same object for each call."""
        import ale_py  # the Atari extra

        key = (self, role, n)
        if key not in _EMULATORS:
            p = self.protocol
            _EMULATORS[key] = ale_py.AtariVectorEnv(
                self.rom, n, repeat_action_probability=p.sticky_action_prob, full_action_space=True,
                max_num_frames_per_episode=p.max_frames, frameskip=p.frameskip, img_height=p.size, img_width=p.size,
                stack_num=p.stack, grayscale=True, maxpool=True, noop_max=0, use_fire_reset=False,
                episodic_life=False, reward_clipping=False, autoreset_mode="SameStep")
        return _EMULATORS[key]

    def reset_batch(self, keys: jax.Array, role: str = "training") -> jax.Array:
        """Every game of ``role`` started again, seeded from ``keys[0]`` (game ``i`` from the seed + ``i``): the
        first observations ``(n, 84, 84, 4)``."""
        n = keys.shape[0]

        def reset(seed: np.ndarray) -> np.ndarray:
            observations, _ = self.emulator(role, n).reset(seed=int(seed))
            return channels_last(observations)

        observations: jax.Array = io_callback(reset, self._observations(n), reset_seed(keys))
        return observations

    def step_autoreset_batch(self, state: jax.Array, actions: jax.Array, keys: jax.Array, role: str = "training"
                             ) -> Step:
        """One step of every game; a game that ended starts again at once (ALE's ``SameStep``), its last
        observation kept for bootstrapping. The draws are the emulator's: ``keys`` is not used."""
        n = state.shape[0]

        def step(actions: np.ndarray, _: np.ndarray) -> tuple[np.ndarray, ...]:
            observations, rewards, terminated, truncated, info = self.emulator(role, n).step(np.asarray(actions))
            last = info.get("final_obs", observations)
            ended = (terminated | truncated)[:, None, None, None]
            return (channels_last(observations), channels_last(np.where(ended, last, observations)),
                    rewards.astype(np.float32), terminated, truncated)

        shapes = (self._observations(n), self._observations(n), jax.ShapeDtypeStruct((n,), jnp.float32),
                  jax.ShapeDtypeStruct((n,), jnp.bool_), jax.ShapeDtypeStruct((n,), jnp.bool_))
        # the state's first pixels make this step wait for the one before (or the reset), whatever the actions
        observation, last, reward, terminated, truncated = io_callback(step, shapes, actions.astype(jnp.int32),
                                                                        state[:, 0, 0, 0])
        return Step(observation, observation, last, reward, terminated, truncated)

    def step_batch(self, state: jax.Array, actions: jax.Array, keys: jax.Array, role: str = "training"
                   ) -> tuple[jax.Array, jax.Array, jax.Array, jax.Array]:
        """``(state, reward, terminated, truncated)``; where a game ended the state is its next episode's start.
        The draws are the emulator's: ``keys`` is not used."""
        step = self.step_autoreset_batch(state, actions, keys, role)
        return step.state, step.reward, step.terminated, step.truncated

    @staticmethod
    def observe_batch(state: jax.Array) -> jax.Array:
        return state

    def _observations(self, n: int) -> jax.ShapeDtypeStruct:
        return jax.ShapeDtypeStruct((n, *self.observation_shape), jnp.uint8)


def reset_seed(keys: jax.Array) -> jax.Array:
    """The emulator's seed for a reset of ``len(keys)`` games (each game ``i`` is seeded with it + ``i``)."""
    return jax.random.randint(keys[0], (), 0, 2**31 - keys.shape[0], jnp.int32)


def channels_last(observations: np.ndarray) -> np.ndarray:
    """ALE's ``(n, stack, 84, 84)`` as ``(n, 84, 84, stack)``, the layout of every image the networks read."""
    return np.ascontiguousarray(observations.transpose(0, 2, 3, 1))


def is_frames(observation_shape: tuple[int, ...]) -> bool:
    """Atari's stacks of frames, which :class:`NatureCNN` reads (MinAtar's 10 x 10 images go to its own network)."""
    return len(observation_shape) == 3 and observation_shape[:2] == (PROTOCOL.size, PROTOCOL.size)


def atari_env(name: str) -> AtariEnv:
    """``<Game>-Atari`` (:data:`rlcompare.envs.atari.games.NAMES`)."""
    return AtariEnv(name, atari.NAMES[name])


NHWC = ("NHWC", "HWIO", "NHWC")


def _convolved(x: jax.Array, kernel: jax.Array, stride: int) -> jax.Array:
    return jax.lax.conv_general_dilated(x, kernel, (stride, stride), "VALID", dimension_numbers=NHWC)


@functools.partial(jax.custom_vjp, nondiff_argnums=(2,))
def convolved(x: jax.Array, kernel: jax.Array, stride: int) -> jax.Array:
    """A valid convolution whose kernel's gradient is a product of the input's patches and the output's gradient.
    XLA:CPU's own kernel gradient (a convolution over the batch) runs 15 to 40 times slower inside a loop than
    outside one, and a training's gradients are all inside loops (``docs/atari.md``, "Cost, measured"); the
    product is as fast in a loop as out of it. The value and the input's gradient are XLA's own."""
    return _convolved(x, kernel, stride)


def _forward(x: jax.Array, kernel: jax.Array, stride: int) -> tuple[jax.Array, tuple[jax.Array, jax.Array]]:
    return _convolved(x, kernel, stride), (x, kernel)


def _backward(stride: int, saved: tuple[jax.Array, jax.Array], gradient: jax.Array) -> tuple[jax.Array, jax.Array]:
    x, kernel = saved
    _, input_gradient = jax.vjp(lambda x: _convolved(x, kernel, stride), x)
    rows, columns = gradient.shape[1:3]
    patches = jnp.stack([jnp.stack([x[:, i:i + stride * (rows - 1) + 1:stride, j:j + stride * (columns - 1) + 1:stride]
                                    for j in range(kernel.shape[1])], axis=3) for i in range(kernel.shape[0])], axis=3)
    return input_gradient(gradient)[0], jnp.einsum("nhwijc,nhwf->ijcf", patches, gradient)


convolved.defvjp(_forward, _backward)


class Conv(nn.Module):
    """``flax.linen.Conv`` with ``VALID`` padding (the same parameters, initialised alike, the same values), its
    kernel's gradient taken by :func:`convolved`."""

    features: int
    size: int
    stride: int
    kernel_init: nn.initializers.Initializer = nn.initializers.lecun_normal()

    @nn.compact
    def __call__(self, x: jax.Array) -> jax.Array:
        kernel = self.param("kernel", self.kernel_init, (self.size, self.size, x.shape[-1], self.features),
                            jnp.float32)
        bias = self.param("bias", nn.initializers.zeros_init(), (self.features,), jnp.float32)
        # computed in float32 whatever the initialiser returned, as flax's ``dtype=float32`` promotes
        return convolved(x.astype(jnp.float32), kernel.astype(jnp.float32), self.stride) + bias.astype(jnp.float32)


class NatureTorso(nn.Module):
    """The body of Mnih et al. (2015)'s network: 32 8 x 8 filters at stride 4, 64 4 x 4 at stride 2, 64 3 x 3 at
    stride 1, dense layers of ``hidden`` (512), each followed by ReLU (after LayerNorm where ``layer_norm``: PQN).
    Observations are stacks of grey frames ``(..., 84, 84, 4)``, scaled from [0, 255] to [0, 1]."""

    hidden: Sequence[int] = (512,)
    layer_norm: bool = False
    kernel_init: nn.initializers.Initializer = nn.initializers.lecun_normal()

    @nn.compact
    def __call__(self, x: jax.Array) -> jax.Array:
        leading = x.shape[:-3]
        x = x.reshape(-1, *x.shape[-3:]).astype(jnp.float32) / 255.0
        for features, size, stride in ((32, 8, 4), (64, 4, 2), (64, 3, 1)):
            x = self.normalised(Conv(features, size, stride, self.kernel_init)(x))
        x = x.reshape(*leading, -1)
        for width in self.hidden:
            x = self.normalised(nn.Dense(width, kernel_init=self.kernel_init, param_dtype=jnp.float32,
                                         dtype=jnp.float32)(x))
        return x

    def normalised(self, x: jax.Array) -> jax.Array:
        if self.layer_norm:
            x = nn.LayerNorm(param_dtype=jnp.float32, dtype=jnp.float32)(x)
        return nn.relu(x)


class NatureCNN(nn.Module):
    """Mnih et al. (2015)'s network, :class:`NatureTorso` then a linear layer of ``outputs``."""

    outputs: int
    hidden: Sequence[int] = (512,)
    layer_norm: bool = False

    @nn.compact
    def __call__(self, x: jax.Array) -> jax.Array:
        features = NatureTorso(self.hidden, self.layer_norm)(x)
        return nn.Dense(self.outputs, param_dtype=jnp.float32, dtype=jnp.float32)(features)
