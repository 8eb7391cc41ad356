"""The README's map of the package matches the tree: every module is listed under its package, and every name listed
is a module that exists."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).parents[2]
PACKAGE = ROOT / "src" / "rlcompare"
MODULE = re.compile(r"\b(\w+\.py)\b")


def layout_block() -> list[str]:
    readme = (ROOT / "README.md").read_text()
    section = readme[readme.index("## Layout"):]
    start = section.index("```\nsrc/rlcompare/") + 4
    return section[start:section.index("```", start)].splitlines()[1:]


def listed_modules() -> set[str]:
    """``cli/commands.py``, ``envs/chess/rules.py``, ``validation.py``: each module the layout names, by its path in
    the package; a package's line (``chess/``) holds the lines indented below it."""
    listed, packages = set(), {}  # indent -> the package a line at that indent opened
    for line in layout_block():
        if not line.strip():
            continue
        indent = len(line) - len(line.lstrip())
        packages = {level: name for level, name in packages.items() if level < indent}
        package = "".join(packages[level] for level in sorted(packages))
        first = line.split()[0]
        if first.endswith("/"):
            packages[indent] = first
            continue
        listed |= {package + name for name in MODULE.findall(_names_part(line))}
    return listed


def _names_part(line: str) -> str:
    """The part of a layout line before its description: the names, separated by commas."""
    return re.split(r"\s{2,}", line.strip(), maxsplit=1)[0]


def modules_in_tree() -> set[str]:
    return {str(path.relative_to(PACKAGE)) for path in PACKAGE.rglob("*.py")
            if path.name not in ("__init__.py", "__main__.py")}


def test_the_layout_lists_every_module_under_its_package():
    assert modules_in_tree() - listed_modules() == set()


def test_every_module_the_layout_names_exists():
    assert listed_modules() - modules_in_tree() == set()


def test_the_layout_names_every_package():
    packages = {line.split()[0] for line in layout_block() if line.startswith("  ") and not line.startswith("   ")
                and line.split()[0].endswith("/")}
    assert packages == {f"{path.name}/" for path in PACKAGE.iterdir() if (path / "__init__.py").is_file()}
