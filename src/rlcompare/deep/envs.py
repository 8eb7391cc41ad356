"""Gymnasium's classic-control environments as pure JAX functions, for the deep engine.

The state is float64, as in Gymnasium, and the network sees it rounded to float32, as Gymnasium returns it.
The dynamics are written in Gymnasium's order of operations (the numba ports in :mod:`rlcompare.envs` are
the same equations), so a transition from the same state equals Gymnasium's (``==``; ``tests/test_deep_envs.py``).
Resets draw from JAX's generator, not NumPy's, so a start state equals Gymnasium's only in distribution.

An environment is a hashable description (static under ``jax.jit``): ``reset(key) -> EnvState`` and
``step(state, action) -> (state, reward, terminated, truncated)``; :func:`step_autoreset` starts a new episode
where one ended and keeps the true last observation for bootstrapping at a time-limit cut.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import jax
import jax.numpy as jnp

from rlcompare.envs import cartpole, mountain_car


class EnvState(NamedTuple):
    """One environment's state: Gymnasium's float64 physics and the steps taken in this episode."""

    physics: jax.Array
    t: jax.Array


class Step(NamedTuple):
    """One step of :func:`step_autoreset`."""

    state: EnvState
    """After a reset where the episode ended."""
    observation: jax.Array
    """float32, what the agent sees next (the first observation of a new episode where one ended)."""
    last_observation: jax.Array
    """float32, the observation the action led to, before any reset: what a time-limit cut bootstraps from."""
    reward: jax.Array
    terminated: jax.Array
    truncated: jax.Array


@dataclass(frozen=True)
class DeepEnv:
    """An environment the deep engine steps: Gymnasium's dynamics written in JAX, and its episode limit."""

    name: str
    n_actions: int
    observation_size: int
    max_steps: int
    start: Callable[[jax.Array], jax.Array]
    """``key -> physics``: a start state."""
    dynamics: Callable[[jax.Array, jax.Array], tuple[jax.Array, jax.Array, jax.Array]]
    """``(physics, action) -> (physics, reward, terminated)``."""
    observe: Callable[[jax.Array], jax.Array]
    """``physics -> float32 observation``."""

    def reset(self, key: jax.Array) -> EnvState:
        return EnvState(self.start(key), jnp.zeros((), jnp.int32))

    def step(self, state: EnvState, action: jax.Array) -> tuple[EnvState, jax.Array, jax.Array, jax.Array]:
        """One transition: ``(state, reward, terminated, truncated)``; truncated at the limit, unless terminated."""
        physics, reward, terminated = self.dynamics(state.physics, action)
        t = state.t + 1
        return EnvState(physics, t), reward, terminated, (t >= self.max_steps) & ~terminated


def step_autoreset(env: DeepEnv, state: EnvState, action: jax.Array, key: jax.Array) -> Step:
    """One step, and a reset (drawn from ``key``) where the episode ended, as Gymnasium's vector environments
    do with ``autoreset_mode=SAME_STEP``."""
    state, reward, terminated, truncated = env.step(state, action)
    last_observation = env.observe(state.physics)
    fresh = env.reset(key)
    done = terminated | truncated
    state = jax.tree.map(lambda new, old: jnp.where(done, new, old), fresh, state)
    return Step(state, env.observe(state.physics), last_observation, reward, terminated, truncated)


# --- MountainCar-v0 (mirrors rlcompare.envs.mountain_car) ---

def _mountain_car_start(key: jax.Array) -> jax.Array:
    position = jax.random.uniform(key, (), jnp.float64, mountain_car.RESET_LOW, mountain_car.RESET_HIGH)
    return jnp.stack([position, jnp.zeros((), jnp.float64)])


def _mountain_car_dynamics(physics: jax.Array, action: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array]:
    position, velocity = physics[0], physics[1]
    velocity = velocity + ((action - 1) * mountain_car.FORCE + jnp.cos(3 * position) * (-mountain_car.GRAVITY))
    velocity = jnp.clip(velocity, -mountain_car.MAX_SPEED, mountain_car.MAX_SPEED)
    position = jnp.clip(position + velocity, mountain_car.MIN_POSITION, mountain_car.MAX_POSITION)
    velocity = jnp.where((position == mountain_car.MIN_POSITION) & (velocity < 0), 0.0, velocity)
    terminated = (position >= mountain_car.GOAL_POSITION) & (velocity >= mountain_car.GOAL_VELOCITY)
    return jnp.stack([position, velocity]), jnp.asarray(mountain_car.REWARD), terminated


def _as_float32(physics: jax.Array) -> jax.Array:
    return physics.astype(jnp.float32)


# --- CartPole-v1 (mirrors rlcompare.envs.cartpole) ---

def _cartpole_start(key: jax.Array) -> jax.Array:
    return jax.random.uniform(key, (4,), jnp.float64, cartpole.RESET_LOW, cartpole.RESET_HIGH)


def _cartpole_dynamics(physics: jax.Array, action: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array]:
    c = cartpole
    x, x_dot, theta, theta_dot = physics[0], physics[1], physics[2], physics[3]
    force = jnp.where(action == 1, c.FORCE_MAG, -c.FORCE_MAG)
    costheta, sintheta = jnp.cos(theta), jnp.sin(theta)
    temp = (force + c.POLEMASS_LENGTH * (theta_dot * theta_dot) * sintheta) / c.TOTAL_MASS
    thetaacc = (c.GRAVITY * sintheta - costheta * temp) / (
        c.LENGTH * (4.0 / 3.0 - c.MASS_POLE * (costheta * costheta) / c.TOTAL_MASS)
    )
    xacc = temp - c.POLEMASS_LENGTH * thetaacc * costheta / c.TOTAL_MASS
    x = x + c.TAU * x_dot
    x_dot = x_dot + c.TAU * xacc
    theta = theta + c.TAU * theta_dot
    theta_dot = theta_dot + c.TAU * thetaacc
    terminated = (x < -c.X_THRESHOLD) | (x > c.X_THRESHOLD) | (theta < -c.THETA_THRESHOLD) | (theta > c.THETA_THRESHOLD)
    return jnp.stack([x, x_dot, theta, theta_dot]), jnp.asarray(c.REWARD), terminated


MOUNTAIN_CAR = DeepEnv("MountainCar-v0", mountain_car.N_ACTIONS, 2, 200, _mountain_car_start,
                       _mountain_car_dynamics, _as_float32)
CARTPOLE = DeepEnv("CartPole-v1", cartpole.N_ACTIONS, 4, 500, _cartpole_start, _cartpole_dynamics, _as_float32)
DEEP_ENVS = {env.name: env for env in (MOUNTAIN_CAR, CARTPOLE)}
"""Every environment the deep engine steps, with Gymnasium's registered limit."""
