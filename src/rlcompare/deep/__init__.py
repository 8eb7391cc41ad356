"""The deep engine: neural-network methods in JAX (the optional ``deep`` extra).

Nothing outside this package imports JAX, and importing it changes no setting of JAX's. The environments'
physics is float64, as Gymnasium's (networks and their inputs are float32 by explicit dtype): every entry point
that traces, compiles or runs a program does so inside :func:`float64`, JAX's 64-bit mode for that thread alone,
so a user's own JAX code in the same process keeps JAX's defaults. Where training starts, JAX's persistent
compilation cache is pointed at ``~/.cache/rlcompare/jax`` unless the user chose one
(``JAX_COMPILATION_CACHE_DIR`` or ``jax.config``), so that a configuration compiles once per machine, not once per
run; JAX keys the cache by the program itself, so a change to the source cannot load stale code.
"""

from __future__ import annotations

import functools
import os
from collections.abc import Callable
from typing import ParamSpec, TypeVar

from rlcompare import machine

INSTALL_HINT = "the deep engine needs JAX, flax and optax: pip install -e '.[deep]'"


class DeepUnavailable(ImportError):
    """JAX, flax or optax is not installed."""


try:
    import flax  # noqa: F401
    import jax
    import optax  # noqa: F401
except ImportError as error:  # pragma: no cover - exercised where the extra is absent
    raise DeepUnavailable(f"{INSTALL_HINT} ({error})") from error

P = ParamSpec("P")
R = TypeVar("R")


def float64(function: Callable[P, R]) -> Callable[P, R]:
    """``function`` run with JAX's 64-bit types on, in the calling thread only (``jax.enable_x64``)."""

    @functools.wraps(function)
    def wrapped(*args: P.args, **kwargs: P.kwargs) -> R:
        with jax.enable_x64(True):
            return function(*args, **kwargs)

    return wrapped


def use_compilation_cache() -> None:
    """Point JAX's persistent compilation cache at rlcompare's, unless the user has chosen one."""
    # a setting is an attribute of jax.config, which JAX's types do not declare
    if os.environ.get("JAX_COMPILATION_CACHE_DIR") or jax.config.jax_compilation_cache_dir:  # type: ignore[attr-defined]
        return
    cache = machine.cache_root() / "jax"
    jax.config.update("jax_compilation_cache_dir", str(cache))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 1.0)
