"""Shared fixtures, the fast tier, and the order the files run in.

A test that takes half a second or more, with warm compile caches, carries ``@pytest.mark.slow("why")`` (or its module
``pytestmark``), the reason in words: ``./scripts/test --fast`` leaves those out, for everyday work. A slow mark
without its reason is an error. The files with the most slow tests run first (``scripts/test`` hands whole files
to its workers in collection order, so the workers end together); the order changes no result.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from rlcompare import ExperimentConfig


def pytest_configure(config: pytest.Config) -> None:
    """The paces of the suite's tiny trainings kept in a file of its own, never in the user's cache, where they
    would make every plan's time a tiny training's (:mod:`rlcompare.pace`)."""
    import os
    import shutil
    import tempfile

    if "RLCOMPARE_PACE_FILE" not in os.environ:
        made = Path(tempfile.mkdtemp(prefix="rlcompare-pace-"))
        os.environ["RLCOMPARE_PACE_FILE"] = str(made / "pace.json")
        config.add_cleanup(lambda: shutil.rmtree(made, ignore_errors=True))


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption("--fast", action="store_true", help="leave out the tests marked slow (half a second or more)")


def slow_reason(item: pytest.Item) -> str | None:
    """Why ``item`` is slow, or None where it is not; a slow mark without its reason is a usage error."""
    mark = item.get_closest_marker("slow")
    if mark is None:
        return None
    if len(mark.args) != 1 or not isinstance(mark.args[0], str) or not mark.args[0]:
        raise pytest.UsageError(f"{item.nodeid}: @pytest.mark.slow needs its reason, e.g. "
                                '@pytest.mark.slow("trains a study")')
    return mark.args[0]


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """The files with the most slow tests first, each file's tests in their own order; with ``--fast``, the
    slow tests left out."""
    slow_per_file: dict[Path, int] = {}
    for item in items:
        slow_per_file[item.path] = slow_per_file.get(item.path, 0) + (slow_reason(item) is not None)
    items.sort(key=lambda item: -slow_per_file[item.path])
    if config.getoption("--fast"):
        slow = [item for item in items if slow_reason(item) is not None]
        config.hook.pytest_deselected(items=slow)
        items[:] = [item for item in items if slow_reason(item) is None]


@pytest.fixture(autouse=True, scope="module")
def _deep_float64(request: pytest.FixtureRequest):
    """The deep engine's internals in JAX's float64, for the tests that step its environments or call its updates
    directly (its entry points turn float64 on themselves, for their own thread only)."""
    if not request.path.name.startswith("test_deep_"):
        yield
        return
    import jax

    with jax.enable_x64(True):
        yield


@pytest.fixture
def small_config() -> ExperimentConfig:
    """Three seeds, 200 episodes, evaluation every 50 episodes."""
    return ExperimentConfig(algorithm="sarsa", schedule="decay", seeds=(0, 1, 2), episodes=200,
                            eval_every=50, eval_episodes=4)
