"""Gymnasium's ``CartPole-v1`` as pure compiled functions, equal to it bit for bit.

Spec sheet (Gymnasium ``classic_control/cartpole.py``; Barto, Sutton and Anderson 1983):

| item        | value                                                                                |
|-------------|--------------------------------------------------------------------------------------|
| state       | ``(x, x_dot, theta, theta_dot)`` float64; observed rounded to float32                 |
| observation | box ``x`` in [-4.8, 4.8], ``theta`` in [-0.418, 0.418] rad, both velocities unbounded |
| actions     | 0 push left, 1 push right, with a force of 10 N                                      |
| dynamics    | Florian (2007) equations, explicit Euler with ``tau = 0.02`` s                         |
| reward      | +1 on every step, the last one included                                              |
| termination | ``|x| > 2.4`` or ``|theta| > 12 degrees``                                             |
| truncation  | the episode limit, a parameter of the caller (Gymnasium registers 500 for v1)         |
| reset       | each state variable ``~ U(-0.05, 0.05)``, drawn as ``Generator.uniform(size=4)``        |

The order of operations is Gymnasium's and the kernels compile without fastmath, so every transition is
equal (``==``) to Gymnasium's, and a reset from a stream seeded with ``seed`` equals ``env.reset(seed=seed)``.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from rlcompare.compiled import njit
from rlcompare.rng import next_double

ENV_ID = "CartPole-v1"
N_ACTIONS = 2
STATE_SIZE = 4
GRAVITY = 9.8
MASS_CART = 1.0
MASS_POLE = 0.1
TOTAL_MASS = MASS_POLE + MASS_CART
LENGTH = 0.5  # half the pole's length
POLEMASS_LENGTH = MASS_POLE * LENGTH
FORCE_MAG = 10.0
TAU = 0.02
THETA_THRESHOLD = 12 * 2 * math.pi / 360
X_THRESHOLD = 2.4
RESET_LOW = -0.05
RESET_HIGH = 0.05
REWARD = 1.0
OBSERVATION_HIGH = np.array([X_THRESHOLD * 2, np.inf, THETA_THRESHOLD * 2, np.inf], dtype=np.float32)
OBSERVATION_LOW = -OBSERVATION_HIGH


class CartPole(NamedTuple):
    """CartPole has no parameter to choose; the field only gives the type a value."""

    state_size: int = STATE_SIZE


@njit(inline="always")
def reset(env: CartPole, rng: np.ndarray) -> tuple[float, float, float, float]:
    """A start state: four draws of ``U(-0.05, 0.05)``."""
    low, width = RESET_LOW, RESET_HIGH - RESET_LOW
    x = low + width * next_double(rng)
    x_dot = low + width * next_double(rng)
    theta = low + width * next_double(rng)
    return x, x_dot, theta, low + width * next_double(rng)


@njit
def step(env: CartPole, state: tuple[float, float, float, float], action: int,
         rng: np.ndarray) -> tuple[tuple[float, float, float, float], float, bool]:
    """One transition: ``(state, reward, terminated)``, terminated when the pole fell or the cart left the
    track; ``rng`` is not drawn from."""
    x, x_dot, theta, theta_dot = state
    force = FORCE_MAG if action == 1 else -FORCE_MAG
    costheta = math.cos(theta)
    sintheta = math.sin(theta)
    temp = (force + POLEMASS_LENGTH * (theta_dot * theta_dot) * sintheta) / TOTAL_MASS
    thetaacc = (GRAVITY * sintheta - costheta * temp) / (
        LENGTH * (4.0 / 3.0 - MASS_POLE * (costheta * costheta) / TOTAL_MASS)
    )
    xacc = temp - POLEMASS_LENGTH * thetaacc * costheta / TOTAL_MASS
    x = x + TAU * x_dot
    x_dot = x_dot + TAU * xacc
    theta = theta + TAU * theta_dot
    theta_dot = theta_dot + TAU * thetaacc
    terminated = x < -X_THRESHOLD or x > X_THRESHOLD or theta < -THETA_THRESHOLD or theta > THETA_THRESHOLD
    return (x, x_dot, theta, theta_dot), REWARD, terminated


@njit(inline="always")
def observe(env: CartPole, state: tuple[float, float, float, float]) -> tuple[np.float32, ...]:
    """What Gymnasium returns: the state rounded to float32."""
    return np.float32(state[0]), np.float32(state[1]), np.float32(state[2]), np.float32(state[3])
