"""The deep engine: neural-network methods in JAX (the optional ``deep`` extra).

Nothing outside this package imports JAX. Importing it turns on JAX's float64, which the environments'
physics need; networks and their inputs are float32 by explicit dtype.
"""

from __future__ import annotations

INSTALL_HINT = "the deep engine needs JAX: pip install -e '.[deep]'"


class DeepUnavailable(RuntimeError):
    """JAX, flax or optax is not installed."""


try:
    import jax
except ImportError as error:  # pragma: no cover - exercised where the extra is absent
    raise DeepUnavailable(INSTALL_HINT) from error

jax.config.update("jax_enable_x64", True)
