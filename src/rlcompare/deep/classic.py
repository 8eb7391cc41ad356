"""Gymnasium's classic-control environments as pure JAX functions, for the deep engine.

The state is float64, as in Gymnasium, and the network sees it rounded to float32, as Gymnasium returns it. The
dynamics are written in Gymnasium's order of operations (the numba ports in :mod:`rlcompare.envs` are the same
equations), so a transition from the same state equals Gymnasium's (``==``; ``tests/parity/test_deep_envs.py``),
jitted, under ``vmap`` and in a scanned rollout alike. Resets draw from JAX's generator, not NumPy's, so a start
state equals Gymnasium's only in distribution.

Written plainly, XLA would not compute Gymnasium's expressions (CartPole differed in the last bits on two steps
in three): its algebraic simplifier turns a division by a constant into a multiplication by its reciprocal and
regroups constants (``(a + c1) + c2`` as ``a + (c1 + c2)``), XLA:CPU always lets LLVM fuse a product and the sum
that uses it into one multiply-add, and both turn ``pow(x, 2)`` into ``x * x``. No XLA flag turns these off
(``--xla_cpu_max_isa=AVX`` would stop the fusing, for every program), so :func:`_opaque`, :func:`_unfused` and
:func:`_squared` keep each expression as written. The equality holds on XLA:CPU on x86-64 with the C library's
sin, cos and pow (NumPy's too, unless built with its AVX-512 kernels); on a GPU these come from CUDA's libdevice
and the last bits may differ.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import gymnasium as gym
import jax
import jax.numpy as jnp

from rlcompare.deep.envs import DeepEnv
from rlcompare.envs import acrobot, cartpole, mountain_car
from rlcompare.envs.registry import environment


def _opaque(value: float) -> jax.Array:
    """A float64 constant that XLA's algebraic simplifier cannot see, so that it computes NumPy's expression as
    written: it rewrites ``a / c`` as ``a * (1 / c)``, ``(a * c1) / c2`` as ``a * (c1 / c2)`` and ``(a + c1) + c2``
    as ``a + (c1 + c2)``, none of them equal to NumPy's. An optimisation barrier hides the value."""
    hidden: jax.Array = jax.lax.optimization_barrier(jnp.float64(value))
    return hidden


def _unfused(product: jax.Array) -> jax.Array:
    """A product rounded on its own before the sum or difference that uses it. XLA:CPU always compiles with
    LLVM's ``AllowFPOpFusion = Fast``, which makes ``a * b + c`` one fused multiply-add, rounded once where NumPy
    rounds twice; a select in between stops that, and ``where(x == x, x, -x)`` is ``x`` (a NaN stays a NaN)."""
    return jnp.where(product == product, product, -product)


def _squared(x: jax.Array) -> jax.Array:
    """``x ** 2`` on a NumPy float64: the C library's ``pow(x, 2.0)``, which differs from ``x * x`` in the last bit
    about once in a thousand. XLA and LLVM both turn a power of a constant 2 into a product, so the exponent is
    the run-time value ``2 + 0 * x`` (2 for every finite ``x``)."""
    return jax.lax.pow(x, 2.0 + 0.0 * x)


def _as_float32(physics: jax.Array) -> jax.Array:
    return physics.astype(jnp.float32)


# --- MountainCar-v0 (Gymnasium classic_control/mountain_car.py; mirrors rlcompare.envs.mountain_car) ---

def _mountain_car_start(key: jax.Array) -> jax.Array:
    position = jax.random.uniform(key, (), jnp.float64, mountain_car.RESET_LOW, mountain_car.RESET_HIGH)
    return jnp.stack([position, jnp.zeros((), jnp.float64)])


def _mountain_car_dynamics(physics: jax.Array, action: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array]:
    position, velocity = physics[0], physics[1]
    gravity = _unfused(jnp.cos(3 * position) * (-mountain_car.GRAVITY))
    velocity = velocity + ((action - 1) * mountain_car.FORCE + gravity)
    velocity = jnp.clip(velocity, -mountain_car.MAX_SPEED, mountain_car.MAX_SPEED)
    position = jnp.clip(position + velocity, mountain_car.MIN_POSITION, mountain_car.MAX_POSITION)
    velocity = jnp.where((position == mountain_car.MIN_POSITION) & (velocity < 0), 0.0, velocity)
    terminated = (position >= mountain_car.GOAL_POSITION) & (velocity >= mountain_car.GOAL_VELOCITY)
    return jnp.stack([position, velocity]), jnp.asarray(mountain_car.REWARD), terminated


# --- CartPole-v1 (Gymnasium classic_control/cartpole.py; mirrors rlcompare.envs.cartpole) ---

def _cartpole_start(key: jax.Array) -> jax.Array:
    return jax.random.uniform(key, (4,), jnp.float64, cartpole.RESET_LOW, cartpole.RESET_HIGH)


def _cartpole_dynamics(physics: jax.Array, action: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array]:
    c = cartpole
    x, x_dot, theta, theta_dot = physics[0], physics[1], physics[2], physics[3]
    force = jnp.where(action == 1, c.FORCE_MAG, -c.FORCE_MAG)
    costheta, sintheta = jnp.cos(theta), jnp.sin(theta)
    total_mass = _opaque(c.TOTAL_MASS)
    temp = (force + _unfused(c.POLEMASS_LENGTH * (theta_dot * theta_dot) * sintheta)) / total_mass
    thetaacc = (_unfused(c.GRAVITY * sintheta) - _unfused(costheta * temp)) / (
        c.LENGTH * (4.0 / 3.0 - c.MASS_POLE * (costheta * costheta) / total_mass)
    )
    xacc = temp - c.POLEMASS_LENGTH * thetaacc * costheta / total_mass
    x = x + _unfused(c.TAU * x_dot)
    x_dot = x_dot + _unfused(c.TAU * xacc)
    theta = theta + _unfused(c.TAU * theta_dot)
    theta_dot = theta_dot + _unfused(c.TAU * thetaacc)
    terminated = (x < -c.X_THRESHOLD) | (x > c.X_THRESHOLD) | (theta < -c.THETA_THRESHOLD) | (theta > c.THETA_THRESHOLD)
    return jnp.stack([x, x_dot, theta, theta_dot]), jnp.asarray(c.REWARD), terminated


# --- Acrobot-v1 (Gymnasium classic_control/acrobot.py; mirrors rlcompare.envs.acrobot) ---

def _acrobot_start(key: jax.Array) -> jax.Array:
    """Four draws of ``U(-0.1, 0.1)``, each rounded to float32 as Gymnasium's reset does."""
    state = jax.random.uniform(key, (4,), jnp.float64, acrobot.RESET_LOW, acrobot.RESET_HIGH)
    return state.astype(jnp.float32).astype(jnp.float64)


def _acrobot_dsdt(s: jax.Array, a: jax.Array) -> jax.Array:
    """Gymnasium's ``_dsdt`` (the book's variant), term by term: the state's time derivative under torque ``a``.
    The link parameters are opaque, so XLA multiplies and adds them as Python does instead of regrouping them."""
    m1, m2, l1, lc1, lc2, I1, I2, g = (_opaque(value) for value in (
        acrobot.LINK_MASS_1, acrobot.LINK_MASS_2, acrobot.LINK_LENGTH_1, acrobot.LINK_COM_POS_1,
        acrobot.LINK_COM_POS_2, acrobot.LINK_MOI, acrobot.LINK_MOI, 9.8))
    pi = math.pi
    theta1, theta2, dtheta1, dtheta2 = s[0], s[1], s[2], s[3]
    d1 = m1 * lc1**2 + m2 * (l1**2 + lc2**2 + 2 * l1 * lc2 * jnp.cos(theta2)) + I1 + I2
    d2 = m2 * (lc2**2 + l1 * lc2 * jnp.cos(theta2)) + I2
    phi2 = _unfused(m2 * lc2 * g * jnp.cos(theta1 + theta2 - pi / 2.0))
    phi1 = (
        _unfused(-m2 * l1 * lc2 * _squared(dtheta2) * jnp.sin(theta2))
        - _unfused(2 * m2 * l1 * lc2 * dtheta2 * dtheta1 * jnp.sin(theta2))
        + _unfused((m1 * lc1 + m2 * l1) * g * jnp.cos(theta1 - pi / 2))
        + phi2
    )
    ddtheta2 = (
        a + _unfused(d2 / d1 * phi1) - _unfused(m2 * l1 * lc2 * _squared(dtheta1) * jnp.sin(theta2)) - phi2
    ) / (m2 * lc2**2 + I2 - _squared(d2) / d1)
    ddtheta1 = -(_unfused(d2 * ddtheta2) + phi1) / d1
    return jnp.stack([dtheta1, dtheta2, ddtheta1, ddtheta2])


def _wrap(x: jax.Array, low: float, high: float) -> jax.Array:
    """Gymnasium's ``wrap``, elementwise: subtract ``high - low`` while above ``high``, then add it while below
    ``low``."""
    diff = high - low
    x = jax.lax.while_loop(lambda x: jnp.any(x > high), lambda x: jnp.where(x > high, x - diff, x), x)
    return jax.lax.while_loop(lambda x: jnp.any(x < low), lambda x: jnp.where(x < low, x + diff, x), x)


def _acrobot_terminal(physics: jax.Array) -> jax.Array:
    """The free end above the bar: ``-cos(theta1) - cos(theta2 + theta1) > 1``."""
    return -jnp.cos(physics[0]) - jnp.cos(physics[1] + physics[0]) > 1.0


def _acrobot_dynamics(physics: jax.Array, action: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array]:
    """One RK4 step of ``dt = 0.2`` s (Gymnasium's ``rk4`` over ``[0, dt]``), angles wrapped, velocities clipped."""
    torque = action - 1.0
    dt = acrobot.DT
    dt2 = dt / 2.0
    k1 = _acrobot_dsdt(physics, torque)
    k2 = _acrobot_dsdt(physics + _unfused(dt2 * k1), torque)
    k3 = _acrobot_dsdt(physics + _unfused(dt2 * k2), torque)
    k4 = _acrobot_dsdt(physics + _unfused(dt * k3), torque)
    state = physics + _unfused(dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4))
    angles = _wrap(state[:2], -math.pi, math.pi)
    dtheta1 = jnp.clip(state[2], -acrobot.MAX_VEL_1, acrobot.MAX_VEL_1)
    dtheta2 = jnp.clip(state[3], -acrobot.MAX_VEL_2, acrobot.MAX_VEL_2)
    physics = jnp.stack([angles[0], angles[1], dtheta1, dtheta2])
    terminated = _acrobot_terminal(physics)
    return physics, jnp.where(terminated, 0.0, -1.0), terminated


def _acrobot_observe(physics: jax.Array) -> jax.Array:
    """``(cos theta1, sin theta1, cos theta2, sin theta2, dtheta1, dtheta2)``, computed in float64, then float32."""
    theta1, theta2 = physics[0], physics[1]
    return jnp.stack([jnp.cos(theta1), jnp.sin(theta1), jnp.cos(theta2), jnp.sin(theta2), physics[2], physics[3]]
                     ).astype(jnp.float32)


def _port(name: str, start: Callable[[jax.Array], jax.Array],
          dynamics: Callable[[jax.Array, jax.Array], tuple[jax.Array, jax.Array, jax.Array]],
          observe: Callable[[jax.Array], jax.Array]) -> DeepEnv:
    """The JAX port of a registered environment: its actions and observation size from its registry entry, its
    limit Gymnasium's registered one (200 steps for Mountain Car, where the paper's tables use 1000)."""
    entry, limit = environment(name), gym.spec(name).max_episode_steps
    if limit is None:
        raise ValueError(f"{name}: Gymnasium registers no step limit, which the JAX port needs")
    return DeepEnv(name, entry.n_actions, entry.observation_size, limit, start, dynamics, observe)


MOUNTAIN_CAR = _port("MountainCar-v0", _mountain_car_start, _mountain_car_dynamics, _as_float32)
CARTPOLE = _port("CartPole-v1", _cartpole_start, _cartpole_dynamics, _as_float32)
ACROBOT = _port("Acrobot-v1", _acrobot_start, _acrobot_dynamics, _acrobot_observe)
