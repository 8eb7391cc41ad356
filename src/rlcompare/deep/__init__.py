"""The deep engine: neural-network methods in JAX (the optional ``deep`` extra).

Nothing outside this package imports JAX. Importing it turns on JAX's float64, which the environments'
physics need (networks and their inputs are float32 by explicit dtype), and JAX's persistent compilation cache
in ``~/.cache/rlcompare/jax`` (``JAX_COMPILATION_CACHE_DIR``, when set, wins), so that a configuration compiles
once per machine, not once per run. JAX keys the cache by the program itself, so a change to the source cannot
load stale code.
"""

from __future__ import annotations

import os
from pathlib import Path

INSTALL_HINT = "the deep engine needs JAX, flax and optax: pip install -e '.[deep]'"


class DeepUnavailable(ImportError):
    """JAX, flax or optax is not installed."""


try:
    import flax  # noqa: F401
    import jax
    import optax  # noqa: F401
except ImportError as error:  # pragma: no cover - exercised where the extra is absent
    raise DeepUnavailable(f"{INSTALL_HINT} ({error})") from error

jax.config.update("jax_enable_x64", True)
if not os.environ.get("JAX_COMPILATION_CACHE_DIR"):
    _cache = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "rlcompare" / "jax"
    jax.config.update("jax_compilation_cache_dir", str(_cache))
jax.config.update("jax_persistent_cache_min_compile_time_secs", 1.0)
