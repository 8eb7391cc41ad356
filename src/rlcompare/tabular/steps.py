"""The parts a training loop is composed of, each chosen by the type of the value it is given when the loop
compiles: an environment's dynamics and its features (the functions of the module the type is defined in:
:mod:`rlcompare.envs.registry`) and a method's rule (:data:`rlcompare.algorithms.registry.METHODS`).

Compiled code calls ``step(env, state, action, rng)`` and gets Mountain Car's step when ``env`` is a
``MountainCar``: no code tests a kind at run time, and a configuration compiles only the parts it uses. The
functions here are signatures; their bodies are the registered implementations. A method's update and values,
called several times a step, are compiled into its own loops instead (:mod:`rlcompare.tabular.episodes`).
"""

from __future__ import annotations

import inspect
import sys
from collections.abc import Callable, Mapping

from numba.extending import overload

from rlcompare.algorithms.registry import METHODS
from rlcompare.compiled import njit


def by_type(implementations: Mapping[type, Callable] | Callable[[type], Callable | None],
            default: Callable | None = None) -> Callable:
    """Make a signature a function of compiled code whose implementation is ``implementations[type of its
    first argument]``, or ``implementations(type)`` (else ``default``); each implementation takes the same
    arguments by the same names."""

    def decorate(signature: Callable) -> Callable:
        parameters = ", ".join(inspect.signature(signature).parameters)
        find = implementations.get if isinstance(implementations, Mapping) else implementations

        def choose(*types):
            kind = getattr(types[0], "instance_class", None)
            chosen = (find(kind) if kind is not None else None) or default
            return None if chosen is None else _calling(chosen, parameters)

        choose.__signature__ = inspect.signature(signature)
        overload(signature)(choose)
        return signature

    return decorate


def _calling(function: Callable, parameters: str) -> Callable:
    """``lambda <parameters>: function(<parameters>)``, with the parameters named as the signature names them."""
    namespace = {"function": function}
    exec(f"def call({parameters}):\n    return function({parameters})", namespace)
    return namespace["call"]


def in_module_of(name: str) -> Callable[[type], Callable | None]:
    """The function ``name`` of the module a type is defined in (a port's ``step``, a grid's ``features_of``)."""

    def find(kind: type) -> Callable | None:
        return getattr(sys.modules[kind.__module__], name, None)

    return find


def _of_methods(name: str) -> dict[type, Callable]:
    return {m.rule: getattr(m, name) for m in METHODS.values() if getattr(m, name) is not None}


# --- environments ---------------------------------------------------------------------------------------


@njit(inline="always")
def _same_instance(env, instance):
    return env


@by_type(in_module_of("reset"))
def reset(env, rng):
    """A start state, drawn from the reset stream ``rng``."""


@by_type(in_module_of("step"))
def step(env, state, action, rng):
    """``(next state, reward, terminated)``; a stochastic environment draws its outcome from ``rng``."""


@by_type(in_module_of("observe"))
def observe(env, state):
    """What Gymnasium would return for ``state``."""


@by_type(in_module_of("for_instance"), default=_same_instance)
def for_instance(env, instance):
    """``env`` naming one of the Gymnasium environments opened for the adapter (a port is itself)."""


# --- features -------------------------------------------------------------------------------------------


@by_type(in_module_of("states_buffer"))
def states_buffer(features, size):
    """Room for the active features of ``size`` states; ``buffer[at]`` gives back the state kept at ``at``."""


@by_type(in_module_of("features_of"))
def features_of(features, observation, buffer, at):
    """The features active in ``observation`` (:mod:`rlcompare.algorithms.linear`), also kept in ``buffer[at]``."""


# --- methods --------------------------------------------------------------------------------------------


@njit(inline="always")
def _copy_w(rule, w, w2, out):
    for i in range(w.shape[0]):
        for a in range(w.shape[1]):
            out[i, a] = w[i, a]


@by_type(_of_methods("snapshot"), default=_copy_w)
def snapshot(rule, w, w2, out):
    """Write the weights a snapshot keeps into ``out`` (element by element: an array assignment would compile
    numba's shape-error messages, seconds of compile time)."""


