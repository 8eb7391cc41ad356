"""Gymnasium's ``MountainCar-v0`` as pure compiled functions, equal to it bit for bit.

Spec sheet (Gymnasium ``classic_control/mountain_car.py``; Moore 1990):

| item        | value                                                                      |
|-------------|----------------------------------------------------------------------------|
| observation | ``(position, velocity)``; position in [-1.2, 0.6], velocity in [-0.07, 0.07] |
| actions     | 0 push left, 1 no push, 2 push right                                       |
| dynamics    | ``v <- clip(v + ((a - 1) * 0.001 + cos(3 p) * (-0.0025)), -0.07, 0.07)``      |
|             | ``p <- clip(p + v, -1.2, 0.6)``; at the left wall with ``v < 0``, ``v <- 0``   |
| reward      | -1 on every step, the last one included                                    |
| termination | ``p >= 0.5 and v >= 0`` (goal velocity 0)                                 |
| truncation  | the episode limit, a parameter of the caller (Gymnasium registers 200; the paper uses 1000) |
| reset       | ``p ~ U(-0.6, -0.4)`` drawn as ``Generator.uniform``, ``v = 0``              |

The state is float64, as in Gymnasium; the agent observes it rounded to float32, as Gymnasium returns it.
The order of operations is Gymnasium's and the kernels compile without fastmath, so every transition is
equal (``==``) to Gymnasium's, and a reset from a stream seeded with ``seed`` equals ``env.reset(seed=seed)``.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from rlcompare.compiled import njit
from rlcompare.rng import next_double

ENV_ID = "MountainCar-v0"
N_ACTIONS = 3
MIN_POSITION = -1.2
MAX_POSITION = 0.6
MAX_SPEED = 0.07
GOAL_POSITION = 0.5
GOAL_VELOCITY = 0.0
FORCE = 0.001
GRAVITY = 0.0025
RESET_LOW = -0.6
RESET_HIGH = -0.4
REWARD = -1.0
OBSERVATION_LOW = np.array([MIN_POSITION, -MAX_SPEED], dtype=np.float32)
OBSERVATION_HIGH = np.array([MAX_POSITION, MAX_SPEED], dtype=np.float32)
BOOK_MAX_POSITION = 0.5


class MountainCar(NamedTuple):
    """The dynamics' one parameter, the right bound of the position: Gymnasium's 0.6, or the book's 0.5
    (Sutton and Barto, Example 10.1), which changes no trajectory but the bounds a tile coder spans."""

    max_position: float = MAX_POSITION


@njit(inline="always")
def reset(env: MountainCar, rng: np.ndarray) -> tuple[float, float]:
    """Start state ``(position, velocity)``: position uniform in [-0.6, -0.4), velocity 0."""
    return RESET_LOW + (RESET_HIGH - RESET_LOW) * next_double(rng), 0.0


@njit(inline="always")
def step(env: MountainCar, state: tuple[float, float], action: int,
         rng: np.ndarray) -> tuple[tuple[float, float], float, bool]:
    """One transition: ``((position, velocity), reward, terminated)``; ``rng`` is not drawn from."""
    position, velocity = state
    velocity = velocity + ((action - 1) * FORCE + math.cos(3 * position) * (-GRAVITY))
    velocity = min(max(velocity, -MAX_SPEED), MAX_SPEED)
    position = position + velocity
    position = min(max(position, MIN_POSITION), env.max_position)
    if position == MIN_POSITION and velocity < 0:
        velocity = 0.0
    terminated = position >= GOAL_POSITION and velocity >= GOAL_VELOCITY
    return (position, velocity), REWARD, terminated


@njit(inline="always")
def observe(env: MountainCar, state: tuple[float, float]) -> tuple[np.float32, np.float32]:
    """What Gymnasium returns: the state rounded to float32."""
    return np.float32(state[0]), np.float32(state[1])
