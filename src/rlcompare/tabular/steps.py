"""The parts a training loop is composed of, each chosen by the type of the value it is given when the loop
compiles: an environment's dynamics and its features (the functions of the module the type is defined in:
:mod:`rlcompare.envs.registry`) and a method's rule (:data:`rlcompare.algorithms.registry.METHODS`).

Compiled code calls ``step(env, state, action, rng)`` and gets Mountain Car's step when ``env`` is a
``MountainCar``: no code tests a kind at run time, and a configuration compiles only the parts it uses. The
functions here are signatures; their bodies are the registered implementations. A method's update and values,
called several times a step, are compiled into its own loops instead (:mod:`rlcompare.tabular.episodes`).
"""

from __future__ import annotations

import functools
import inspect
import sys
from collections.abc import Callable, Mapping
from types import FunctionType
from typing import Any, TypeVar

import numpy as np
from numba.extending import overload

from rlcompare.algorithms.registry import METHODS
from rlcompare.compiled import njit

Signature = TypeVar("Signature", bound=Callable[..., Any])
Implementation = Callable[..., Any]
"""A compiled function (a numba dispatcher) or a Python function compiled code inlines."""


def by_type(implementations: Mapping[type, Implementation] | Callable[[type], Implementation | None],
            default: Implementation | None = None) -> Callable[[Signature], Signature]:
    """Make a signature a function of compiled code whose implementation is ``implementations[type of its
    first argument]``, or ``implementations(type)`` (else ``default``); each implementation takes the same
    arguments by the same names."""

    def decorate(signature: Signature) -> Signature:
        find = implementations.get if isinstance(implementations, Mapping) else implementations

        @functools.wraps(signature)  # numba reads the signature's parameters from it
        def choose(*types: Any) -> Implementation | None:
            kind = getattr(types[0], "instance_class", None)
            chosen = (find(kind) if kind is not None else None) or default
            return None if chosen is None else _calling(chosen, signature)

        overload(signature)(choose)
        return signature

    return decorate


def _calling(function: Implementation, signature: Callable[..., Any]) -> Implementation:
    """``lambda <parameters>: function(<parameters>)``, with the parameters of the signature, named and annotated
    as it names and annotates them (numba checks that an implementation's parameters are its signature's)."""
    parameters = ", ".join(inspect.signature(signature).parameters)
    namespace: dict[str, Any] = {"function": function}
    exec(f"def call({parameters}):\n    return function({parameters})", namespace)
    call: FunctionType = namespace["call"]
    call.__annotations__ = dict(signature.__annotations__)
    return call


def in_module_of(name: str) -> Callable[[type], Implementation | None]:
    """The function ``name`` of the module a type is defined in (a port's ``step``, a grid's ``features_of``)."""

    def find(kind: type) -> Implementation | None:
        found: Implementation | None = getattr(sys.modules[kind.__module__], name, None)
        return found

    return find


def _of_methods(name: str) -> dict[type, Implementation]:
    return {m.rule: getattr(m, name) for m in METHODS.values() if getattr(m, name) is not None}


# --- environments ---------------------------------------------------------------------------------------

COMPILED_ONLY = "a signature: compiled code calls the implementation its argument's type chooses"


@njit(inline="always")
def _same_instance(env: Any, instance: int) -> Any:
    return env


@by_type(in_module_of("reset"))
def reset(env: Any, rng: np.ndarray) -> Any:
    """A start state, drawn from the reset stream ``rng``."""
    raise NotImplementedError(COMPILED_ONLY)


@by_type(in_module_of("step"))
def step(env: Any, state: Any, action: int, rng: np.ndarray) -> tuple[Any, float, bool]:
    """``(next state, reward, terminated)``; a stochastic environment draws its outcome from ``rng``."""
    raise NotImplementedError(COMPILED_ONLY)


@by_type(in_module_of("observe"))
def observe(env: Any, state: Any) -> Any:
    """What Gymnasium would return for ``state``."""
    raise NotImplementedError(COMPILED_ONLY)


@by_type(in_module_of("for_instance"), default=_same_instance)
def for_instance(env: Any, instance: int) -> Any:
    """``env`` naming one of the Gymnasium environments opened for the adapter (a port is itself)."""
    raise NotImplementedError(COMPILED_ONLY)


# --- features -------------------------------------------------------------------------------------------


@by_type(in_module_of("states_buffer"))
def states_buffer(features: Any, size: int) -> np.ndarray:
    """Room for the active features of ``size`` states; ``buffer[at]`` gives back the state kept at ``at``."""
    raise NotImplementedError(COMPILED_ONLY)


@by_type(in_module_of("features_of"))
def features_of(features: Any, observation: Any, buffer: np.ndarray, at: int) -> int | np.ndarray:
    """The features active in ``observation`` (:mod:`rlcompare.algorithms.linear`), also kept in ``buffer[at]``."""
    raise NotImplementedError(COMPILED_ONLY)


# --- methods --------------------------------------------------------------------------------------------


@njit(inline="always")
def _copy_w(rule: Any, w: np.ndarray, w2: np.ndarray, out: np.ndarray) -> None:
    for i in range(w.shape[0]):
        for a in range(w.shape[1]):
            out[i, a] = w[i, a]


@by_type(_of_methods("snapshot"), default=_copy_w)
def snapshot(rule: Any, w: np.ndarray, w2: np.ndarray, out: np.ndarray) -> None:
    """Write the weights a snapshot keeps into ``out`` (element by element: an array assignment would compile
    numba's shape-error messages, seconds of compile time)."""
    raise NotImplementedError(COMPILED_ONLY)
