"""The layers of the package: imports point down, so no two packages import each other, however deep the import."""

from __future__ import annotations

import ast
import graphlib
from pathlib import Path

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
