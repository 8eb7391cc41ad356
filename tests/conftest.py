"""Shared fixtures, the order the files run in, and the fast tier.

``tests/durations.json`` holds how long each test took in a full run on a cold cache (setup, call and teardown);
it is written by the suite itself, never by hand: ``RLCOMPARE_WRITE_DURATIONS=1 ./scripts/test`` rewrites it.
From it:

- the files run longest first (``scripts/test`` hands whole files to its workers in collection order, so the
  workers end together); the order changes no result;
- ``--fast`` (``./scripts/test --fast``) runs only the tests that took under :data:`FAST_SECONDS` there, for
  everyday work; a test not recorded yet counts as fast until the file is rewritten.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from rlcompare import ExperimentConfig

DURATIONS = Path(__file__).with_name("durations.json")
FAST_SECONDS = 1.0
"""The fast tier's bound on a test's recorded time."""


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption("--fast", action="store_true",
                     help=f"run only the tests that took under {FAST_SECONDS:g} s in the recorded full run "
                          f"({DURATIONS.name})")


def _recorded() -> dict[str, float]:
    return json.loads(DURATIONS.read_text()) if DURATIONS.is_file() else {}


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """The files that took longest first, each file's tests in their own order; with ``--fast``, only the tests
    that took under :data:`FAST_SECONDS`."""
    recorded = _recorded()
    per_file: dict[Path, float] = {}
    for item in items:
        per_file[item.path] = per_file.get(item.path, 0.0) + recorded.get(item.nodeid, 0.0)
    items.sort(key=lambda item: -per_file[item.path])
    if config.getoption("--fast"):
        slow = [item for item in items if recorded.get(item.nodeid, 0.0) >= FAST_SECONDS]
        config.hook.pytest_deselected(items=slow)
        items[:] = [item for item in items if recorded.get(item.nodeid, 0.0) < FAST_SECONDS]


_durations: dict[str, float] = {}


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    _durations[report.nodeid] = _durations.get(report.nodeid, 0.0) + report.duration


def pytest_sessionfinish(session: pytest.Session) -> None:
    """Rewrite :data:`DURATIONS` after a full run when ``RLCOMPARE_WRITE_DURATIONS`` is set (on xdist's
    controller, which receives every worker's reports)."""
    if os.environ.get("RLCOMPARE_WRITE_DURATIONS") and not hasattr(session.config, "workerinput") and _durations:
        rounded = {nodeid: round(seconds, 2) for nodeid, seconds in sorted(_durations.items())}
        DURATIONS.write_text(json.dumps(rounded, indent=0) + "\n")


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
