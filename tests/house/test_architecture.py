"""The layers of the package, read from the code's own imports: each layer imports only the layers below it, the
statistics import no pictures, no JAX and no engine, the pictures reach no deep engine, and no package holds a
circle of imports. An import under ``if TYPE_CHECKING:`` loads nothing and only lets the type checker hold a
module to a contract, so it is not counted."""

from __future__ import annotations

import ast
import graphlib
from pathlib import Path

import pytest

import rlcompare

PACKAGE = Path(rlcompare.__file__).parent
LAYERS = (
    ("formatting", "machine", "atomic"),
    ("compiled", "pace"),
    ("validation", "rng"),
    ("algorithms", "envs"),
    ("players",),
    ("tabular", "deep"),
    ("experiment",),
    ("stats",),
    ("report",),
    ("studies",),
    ("bench",),
    ("cli", "__init__", "__main__"),
)
"""From the bottom up: what each top-level package or module of rlcompare is, by the layer it stands in."""
PICTURES = ("matplotlib", "imageio", "imageio_ffmpeg", "PIL", "pygame")
JAX = ("jax", "jaxlib", "flax", "optax", "gymnax")


def module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def runtime_imports(path: Path) -> list[str]:
    """Every module ``path`` imports when it runs (at its top or in a function), its own relative imports resolved;
    not those under ``if TYPE_CHECKING:``."""
    tree = ast.parse(path.read_text())
    typing_only = {id(node) for block in ast.walk(tree) if isinstance(block, ast.If)
                   and isinstance(block.test, ast.Name) and block.test.id == "TYPE_CHECKING"
                   for statement in block.body for node in ast.walk(statement)}
    found = []
    for node in ast.walk(tree):
        if id(node) in typing_only:
            continue
        if isinstance(node, ast.Import):
            found += [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            submodules = [f"{node.module}.{alias.name}" for alias in node.names]
            modules = [name for name in submodules if name in MODULE_FILES]  # modules imported from their package
            found += modules if len(modules) == len(submodules) else [node.module, *modules]
    return found


MODULES = {module_name(path): path for path in PACKAGE.rglob("*.py")}
MODULE_FILES = set(MODULES)
IMPORTS = {name: runtime_imports(path) for name, path in MODULES.items()}


def top(module: str) -> str:
    """``experiment`` for ``rlcompare.experiment.store``, ``validation`` for ``rlcompare.validation``."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def edges_between_packages() -> dict[tuple[str, str], set[str]]:
    """(importing package, imported package) -> the modules that import so."""
    edges: dict[tuple[str, str], set[str]] = {}
    for name, imported in IMPORTS.items():
        for other in imported:
            if other.split(".")[0] == "rlcompare" and other in MODULES and top(other) != top(name):
                edges.setdefault((top(name), top(other)), set()).add(name)
    return edges


def layer_of(package: str) -> int:
    return next(index for index, layer in enumerate(LAYERS) if package in layer)


BASE = {package for layer in LAYERS[:layer_of("algorithms")] for package in layer}
"""What every layer may import: the machine, files, compiled code, validation and random streams."""


def test_every_package_has_a_layer():
    assert {top(name) for name in MODULES} <= {package for layer in LAYERS for package in layer}


def test_each_layer_imports_only_the_layers_below_it():
    upward = {edge: sorted(modules) for edge, modules in edges_between_packages().items()
              if layer_of(edge[0]) <= layer_of(edge[1])}
    assert not upward


def external(module: str, roots: tuple[str, ...]) -> list[str]:
    return sorted({other for other in IMPORTS[module] if other.split(".")[0] in roots})


@pytest.mark.parametrize("module", sorted(name for name in MODULES if top(name) == "stats"))
def test_the_statistics_import_no_pictures_no_jax_and_nothing_of_rlcompare_but_the_base(module):
    assert not external(module, PICTURES + JAX)
    assert {top(other) for other in IMPORTS[module] if other in MODULES} <= {"stats", *BASE}


@pytest.mark.parametrize("module", sorted(name for name in MODULES if top(name) == "report"))
def test_the_pictures_reach_no_deep_engine_and_no_jax(module):
    assert not external(module, JAX)
    assert "deep" not in {top(other) for other in IMPORTS[module] if other in MODULES}


@pytest.mark.parametrize("engine", ["tabular", "deep"])
def test_an_engine_reaches_no_other_engine_and_nothing_above_it(engine):
    reached = {there for (here, there) in edges_between_packages() if here == engine}
    below_the_engines = LAYERS[:layer_of("tabular")]
    assert reached <= {package for layer in below_the_engines for package in layer}


def test_no_circle_of_imports_inside_a_package():
    graph = {name: {other for other in imported if other in MODULES and other != name and top(other) == top(name)}
             for name, imported in IMPORTS.items()}
    graphlib.TopologicalSorter(graph).prepare()  # CycleError names the circle
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


@pytest.mark.slow("imports every module in a process of its own")
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


@pytest.mark.slow("imports every module in a process of its own")
def test_the_deep_engine_turns_float64_on_for_its_own_calls_only():
    """Its entry points trace in float64 (the physics is Gymnasium's float64) and leave JAX's 32-bit default to the
    caller when they return."""
    jax = pytest.importorskip("jax")
    from rlcompare.deep.config import DeepConfig
    from rlcompare.deep.train import params_template

    assert not jax.config.jax_enable_x64
    params_template(DeepConfig(algorithm="pqn_q_lambda", env="MountainCar-v0", seeds=(0,)))
    assert not jax.config.jax_enable_x64
    assert jax.numpy.zeros(1).dtype == jax.numpy.float32
