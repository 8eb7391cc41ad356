"""What an agent accepts as an observation of its environment, checked before any compiled code or network reads it:
for a Box environment a real array of exactly the environment's shape with finite entries, for a finite one an
integer state in ``[0, n_states)``; anything else raises :class:`ValueError` naming what was expected and what
came."""

from __future__ import annotations

import numpy as np

from rlcompare.formatting import quote

_REAL = "iuf"
"""numpy dtype kinds ``act`` accepts in a Box observation: integers and floats (not bool, complex, object,
strings)."""


def _given(observation: object) -> str:
    """What came, briefly: the shape and dtype of an array, else the type and value."""
    if isinstance(observation, np.ndarray) and observation.ndim:
        return f"shape {observation.shape} {observation.dtype}"
    return f"{type(observation).__name__} {quote(observation, 40)}"


def _refuse(given: str, expected: str, env: str) -> ValueError:
    return ValueError(f"observation: got {given}; expected {expected}, as {env}'s env.step returns")


def check_box_observation(observation: object, shape: tuple[int, ...], env: str) -> np.ndarray:
    """``observation`` as a float64 array, if it is a real array of exactly ``shape`` with finite entries."""
    expected = f"shape {shape} of finite numbers"
    try:
        array = np.asarray(observation)
    except (TypeError, ValueError):  # a ragged sequence, say
        raise _refuse(_given(observation), expected, env) from None
    if array.shape != shape or array.dtype.kind not in _REAL:
        raise _refuse(_given(array if array.ndim else observation), expected, env)
    array = array.astype(np.float64)
    if not np.isfinite(array).all():
        raise _refuse(quote(array.tolist(), 40), expected, env)
    return array


def check_state(observation: object, n_states: int, env: str) -> int:
    """``observation`` as an int, if it is an integer (Python, numpy or a 0-d array) in ``[0, n_states)``."""
    value = observation
    if isinstance(value, np.ndarray) and value.ndim == 0 and value.dtype.kind in "iu":
        value = value[()]
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not 0 <= value < n_states:
        raise _refuse(_given(observation), f"an integer state in [0, {n_states})", env)
    return int(value)


def check_observation(observation: object, shape: tuple[int, ...], n_states: int, env: str) -> np.ndarray | int:
    """A valid observation of ``env`` in the form the features read: a finite state's int, a Box's float64
    array. ``n_states`` is 0 for a Box of ``shape``."""
    return check_state(observation, n_states, env) if n_states else check_box_observation(observation, shape, env)
