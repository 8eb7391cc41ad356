"""Gymnasium's ``Acrobot-v1`` as pure compiled functions, equal to it bit for bit.

Spec sheet (Gymnasium ``classic_control/acrobot.py``; Sutton 1996, Sutton and Barto 1998 section 11.3):

| item        | value                                                                                  |
|-------------|----------------------------------------------------------------------------------------|
| state       | ``(theta1, theta2, dtheta1, dtheta2)`` float64                                          |
| observation | ``(cos theta1, sin theta1, cos theta2, sin theta2, dtheta1, dtheta2)`` rounded to float32, |
|             | in [-1, 1]^4 x [-4 pi, 4 pi] x [-9 pi, 9 pi]                                             |
| actions     | torque -1, 0, +1 on the joint between the links                                       |
| dynamics    | the book's equations (``book_or_nips = "book"``), one RK4 step of ``dt = 0.2`` s, angles |
|             | wrapped to [-pi, pi], velocities clipped to 4 pi and 9 pi                              |
| reward      | -1 on every step, 0 on the step that reaches the goal                                  |
| termination | ``-cos(theta1) - cos(theta2 + theta1) > 1``: the free end above the bar                 |
| truncation  | the episode limit, a parameter of the caller (Gymnasium registers 500)                  |
| reset       | each state variable ``~ U(-0.1, 0.1)`` drawn as ``Generator.uniform(size=4)``, then    |
|             | rounded to float32 as Gymnasium does                                                    |

The order of operations is Gymnasium's, term by term, and the kernels compile without fastmath. Gymnasium
computes ``sin`` and ``cos`` with NumPy, this port with the C library; where the two agree (they do on
x86-64 builds without AVX-512 kernels for them, checked by the parity test) every transition is equal
(``==``) to Gymnasium's. Torque noise (``torque_noise_max``) is 0 in Gymnasium and not ported.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, NamedTuple, cast

import numpy as np
from llvmlite import ir
from numba import types
from numba.core.typing.templates import Signature
from numba.extending import intrinsic

from rlcompare.compiled import Codegen, njit
from rlcompare.rng import next_double

ENV_ID = "Acrobot-v1"
N_ACTIONS = 3
STATE_SIZE = 4
OBSERVATION_SIZE = 6
DT = 0.2
LINK_LENGTH_1 = 1.0
LINK_MASS_1 = 1.0
LINK_MASS_2 = 1.0
LINK_COM_POS_1 = 0.5
LINK_COM_POS_2 = 0.5
LINK_MOI = 1.0
MAX_VEL_1 = 4 * math.pi
MAX_VEL_2 = 9 * math.pi
RESET_LOW = -0.1
RESET_HIGH = 0.1
OBSERVATION_HIGH = np.array([1.0, 1.0, 1.0, 1.0, MAX_VEL_1, MAX_VEL_2], dtype=np.float32)
OBSERVATION_LOW = -OBSERVATION_HIGH


class Acrobot(NamedTuple):
    """Acrobot has no parameter to choose; the field only gives the type a value."""

    state_size: int = STATE_SIZE


@njit(inline="always")
def reset(env: Acrobot, rng: np.ndarray) -> tuple[float, float, float, float]:
    """A start state: four draws of ``U(-0.1, 0.1)``, each rounded to float32."""
    low, width = RESET_LOW, RESET_HIGH - RESET_LOW
    theta1 = float(np.float32(low + width * next_double(rng)))
    theta2 = float(np.float32(low + width * next_double(rng)))
    dtheta1 = float(np.float32(low + width * next_double(rng)))
    return theta1, theta2, dtheta1, float(np.float32(low + width * next_double(rng)))


@intrinsic
def _pow_intrinsic(typingctx: Any, x: types.Type, y: types.Type) -> tuple[Signature, Codegen]:
    def codegen(context: Any, builder: Any, signature: Signature, args: tuple[Any, ...]) -> Any:
        double, module = ir.DoubleType(), builder.module
        pow_ = module.globals.get("pow")
        if pow_ is None:  # declared once a module
            pow_ = ir.Function(module, ir.FunctionType(double, [double, double]), "pow")
        pow_.attributes.add("nobuiltin")
        return builder.call(pow_, args)

    return types.float64(types.float64, types.float64), codegen


_libm_pow = cast(Callable[[float, float], float], _pow_intrinsic)
"""The C library's ``pow``, as Python's ``x ** y`` on floats calls it. LLVM would turn ``x ** 2`` into
``x * x``, which differs from ``pow(x, 2)`` in the last bit about once in a thousand; the declaration
is marked ``nobuiltin`` so that it stays a call. An intrinsic (compiled code only), whose typing function
takes numba's typing context first: to the type checker, the function compiled code calls."""


@njit
def _dsdt(theta1: float, theta2: float, dtheta1: float, dtheta2: float, a: float) -> tuple[float, float, float, float]:
    """Time derivative of the state under torque ``a`` (Gymnasium's ``_dsdt``, the book's variant).

    Gymnasium squares with ``**``, which calls ``pow``; so does this port (constants square exactly)."""
    m1, m2, l1 = LINK_MASS_1, LINK_MASS_2, LINK_LENGTH_1
    lc1, lc2, I1, I2 = LINK_COM_POS_1, LINK_COM_POS_2, LINK_MOI, LINK_MOI
    g = 9.8
    pi = math.pi
    d1 = m1 * lc1**2 + m2 * (l1**2 + lc2**2 + 2 * l1 * lc2 * math.cos(theta2)) + I1 + I2
    d2 = m2 * (lc2**2 + l1 * lc2 * math.cos(theta2)) + I2
    phi2 = m2 * lc2 * g * math.cos(theta1 + theta2 - pi / 2.0)
    phi1 = (
        -m2 * l1 * lc2 * _libm_pow(dtheta2, 2.0) * math.sin(theta2)
        - 2 * m2 * l1 * lc2 * dtheta2 * dtheta1 * math.sin(theta2)
        + (m1 * lc1 + m2 * l1) * g * math.cos(theta1 - pi / 2)
        + phi2
    )
    ddtheta2 = (a + d2 / d1 * phi1 - m2 * l1 * lc2 * _libm_pow(dtheta1, 2.0) * math.sin(theta2) - phi2) / (
        m2 * lc2**2 + I2 - _libm_pow(d2, 2.0) / d1
    )
    ddtheta1 = -(d2 * ddtheta2 + phi1) / d1
    return dtheta1, dtheta2, ddtheta1, ddtheta2


@njit(inline="always")
def _wrap(x: float, low: float, high: float) -> float:
    diff = high - low
    while x > high:
        x = x - diff
    while x < low:
        x = x + diff
    return x


@njit
def step(env: Acrobot, state: tuple[float, float, float, float], action: int,
         rng: np.ndarray) -> tuple[tuple[float, float, float, float], float, bool]:
    """One RK4 step: ``(state, reward, terminated)``; ``rng`` is not drawn from."""
    torque = action - 1.0
    s0, s1, s2, s3 = state
    dt = DT - 0.0
    dt2 = dt / 2.0
    k1 = _dsdt(s0, s1, s2, s3, torque)
    k2 = _dsdt(s0 + dt2 * k1[0], s1 + dt2 * k1[1], s2 + dt2 * k1[2], s3 + dt2 * k1[3], torque)
    k3 = _dsdt(s0 + dt2 * k2[0], s1 + dt2 * k2[1], s2 + dt2 * k2[2], s3 + dt2 * k2[3], torque)
    k4 = _dsdt(s0 + dt * k3[0], s1 + dt * k3[1], s2 + dt * k3[2], s3 + dt * k3[3], torque)
    sixth = dt / 6.0
    theta1 = _wrap(s0 + sixth * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0]), -math.pi, math.pi)
    theta2 = _wrap(s1 + sixth * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1]), -math.pi, math.pi)
    dtheta1 = min(max(s2 + sixth * (k1[2] + 2 * k2[2] + 2 * k3[2] + k4[2]), -MAX_VEL_1), MAX_VEL_1)
    dtheta2 = min(max(s3 + sixth * (k1[3] + 2 * k2[3] + 2 * k3[3] + k4[3]), -MAX_VEL_2), MAX_VEL_2)
    terminated = -math.cos(theta1) - math.cos(theta2 + theta1) > 1.0
    return (theta1, theta2, dtheta1, dtheta2), (0.0 if terminated else -1.0), terminated


@njit(inline="always")
def observe(env: Acrobot, state: tuple[float, float, float, float]) -> tuple[np.float32, ...]:
    """What Gymnasium returns: ``(cos theta1, sin theta1, cos theta2, sin theta2, dtheta1, dtheta2)`` rounded
    to float32."""
    theta1, theta2, dtheta1, dtheta2 = state
    return (np.float32(math.cos(theta1)), np.float32(math.sin(theta1)), np.float32(math.cos(theta2)),
            np.float32(math.sin(theta2)), np.float32(dtheta1), np.float32(dtheta2))
