"""The layers of the package: imports point down, so no two packages import each other, however deep the import."""

from __future__ import annotations

import ast
import graphlib
from pathlib import Path

import pytest

import rlcompare

PACKAGE = Path(rlcompare.__file__).parent


def package_of(module: str) -> str | None:
    """``experiment`` for ``rlcompare.experiment.store``; None outside rlcompare."""
    parts = module.split(".")
    return parts[1] if parts[0] == "rlcompare" and len(parts) > 1 else None


def imports_between_packages() -> dict[tuple[str, str], list[str]]:
    """(importing package, imported package) -> the files that import so, counting imports inside functions."""
    edges: dict[tuple[str, str], list[str]] = {}
    for path in PACKAGE.rglob("*.py"):
        relative = path.relative_to(PACKAGE)
        here = relative.parts[0].removesuffix(".py")
        for node in ast.walk(ast.parse(path.read_text())):
            names = [alias.name for alias in node.names] if isinstance(node, ast.Import) else (
                [node.module] if isinstance(node, ast.ImportFrom) and node.module and not node.level else [])
            for there in filter(None, map(package_of, names)):
                if there != here:
                    edges.setdefault((here, there), []).append(str(relative))
    return edges


def test_no_two_packages_import_each_other():
    edges = imports_between_packages()
    cycles = {(a, b): (edges[(a, b)], edges[(b, a)]) for a, b in edges if (b, a) in edges and a < b}
    assert not cycles


def test_the_packages_form_layers_without_a_cycle():
    edges = imports_between_packages()
    graph = {a: {b for (x, b) in edges if x == a} for a, _ in edges}
    order = list(graphlib.TopologicalSorter(graph).static_order())  # CycleError names a cycle
    assert order.index("engine") < order.index("experiment") < order.index("studies") < order.index("cli")


def test_experiment_reaches_an_engine_only_through_the_registry():
    edges = imports_between_packages()
    assert ("experiment", "deep") not in edges
    assert ("experiment", "studies") not in edges
    assert ("analysis", "studies") not in edges


IMPORT_EVERYTHING = r"""
import importlib, json, os, pkgutil, time
from pathlib import Path

cache = Path(os.environ["XDG_CACHE_HOME"])
month_ago = time.time() - 60 * 86400
for stale in (cache / "rlcompare" / "numba-0000000000000000", cache / "rlcompare" / "jax"):
    stale.mkdir(parents=True)
    (stale / "entry").write_text("")
    os.utime(stale, (month_ago, month_ago))
before = sorted(str(path) for path in cache.rglob("*"))

import jax
import matplotlib

backend = matplotlib.rcParams._get_backend_or_none()
import rlcompare

names = sorted(m.name for m in pkgutil.walk_packages(rlcompare.__path__, "rlcompare.")
               if not m.name.endswith("__main__"))
for name in names:
    importlib.import_module(name)
print(json.dumps({"modules": len(names), "x64": bool(jax.config.jax_enable_x64),
                  "backend_before": backend, "backend_after": matplotlib.rcParams._get_backend_or_none(),
                  "cache_dir": jax.config.jax_compilation_cache_dir,
                  "deleted": sorted(set(before) - {str(path) for path in cache.rglob("*")})}))
"""


def test_importing_every_module_changes_no_setting_of_jax_or_matplotlib_and_nothing_on_disk(tmp_path):
    """A user's notebook that imports rlcompare keeps JAX's and matplotlib's defaults, and its caches: every module,
    the studies included, imports without choosing a backend (a module that called ``matplotlib.use`` would fail
    here), and nothing under the cache directory is deleted until a run starts (where old numba caches are pruned)."""
    import json
    import os
    import subprocess
    import sys

    environment = {key: value for key, value in os.environ.items()
                   if not key.startswith(("JAX_", "MPLBACKEND", "NUMBA_CACHE_DIR"))}
    done = subprocess.run([sys.executable, "-c", IMPORT_EVERYTHING], capture_output=True, text=True, check=True,
                          env={**environment, "XDG_CACHE_HOME": str(tmp_path)})
    found = json.loads(done.stdout.strip().splitlines()[-1])
    assert found["modules"] > 60
    assert found["x64"] is False
    assert found["backend_after"] == found["backend_before"]
    assert found["cache_dir"] is None
    assert found["deleted"] == []


def test_the_deep_engine_turns_float64_on_for_its_own_calls_only():
    """Its entry points trace in float64 (the physics is Gymnasium's float64) and leave JAX's 32-bit default to the
    caller when they return."""
    jax = pytest.importorskip("jax")
    from rlcompare.deep.run import DeepConfig, params_template

    assert not jax.config.jax_enable_x64
    params_template(DeepConfig(algorithm="pqn_q_lambda", env="MountainCar-v0", seeds=(0,)))
    assert not jax.config.jax_enable_x64
    assert jax.numpy.zeros(1).dtype == jax.numpy.float32
