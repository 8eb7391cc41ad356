"""Shared fixtures, the order the files run in, and the fast tier.

``tests/durations.json`` holds how long each test took in a full run on a cold cache (setup, call and teardown),
and how long each fixture shared by several tests (module or session scope) took to set up. The suite writes it,
never a hand: ``RLCOMPARE_WRITE_DURATIONS=1 ./scripts/test`` updates the tests that passed and drops the files
that are gone. From it:

- the files run longest first (``scripts/test`` hands whole files to its workers in collection order, so the
  workers end together); the order changes no result;
- a test whose own time, plus the set-up of the shared fixtures it needs (counted against whichever test came
  first in the full run), reaches :data:`FAST_SECONDS` is marked ``slow``, with all its parametrizations (they
  share what the first of them compiled), and ``--fast``
  (``./scripts/test --fast``) leaves the ``slow`` tests out, for everyday work. A test not recorded yet counts as
  fast until the file is rewritten.
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from rlcompare import ExperimentConfig

DURATIONS = Path(__file__).with_name("durations.json")
FAST_SECONDS = 0.5
"""The fast tier's bound on a test's recorded time."""
FIXTURE_SECONDS = "shared fixtures' set-up seconds"
"""The name under which a test's report carries the shared fixtures set up for it (from xdist's workers)."""


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption("--fast", action="store_true",
                     help=f"leave out the tests marked slow: those that took {FAST_SECONDS:g} s or more in the "
                          f"recorded full run ({DURATIONS.name})")


def recorded() -> dict[str, dict[str, float]]:
    """``{"tests": {nodeid: seconds}, "fixtures": {key: seconds}}`` of the last full run."""
    data = json.loads(DURATIONS.read_text()) if DURATIONS.is_file() else {}
    return {"tests": data.get("tests", {}), "fixtures": data.get("fixtures", {})}


def fixture_key(scope: str, name: str, nodeid: str) -> str:
    """Where a shared fixture's set-up is paid: once a session, or once in each file that uses it."""
    return f"{name} (session)" if scope == "session" else f"{nodeid.split('::')[0]}::{name}"


def expected_seconds(item: pytest.Item, durations: dict[str, dict[str, float]]) -> float:
    """A test's own recorded time plus the set-up of every shared fixture it needs, as if it ran alone."""
    fixtures = durations["fixtures"]
    shared = sum(fixtures.get(fixture_key("session", name, item.nodeid),
                              fixtures.get(fixture_key("module", name, item.nodeid), 0.0))
                 for name in item.fixturenames)
    return durations["tests"].get(item.nodeid, 0.0) + shared


def family(item: pytest.Item) -> tuple[Path, str]:
    """A test and its parametrizations: the first of them to run compiles what they share, so the recorded run
    charges the compile to one member and would call the others fast."""
    return item.path, getattr(item, "originalname", item.name)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """The files that took longest first, each file's tests in their own order; tests at or over
    :data:`FAST_SECONDS` marked ``slow``, and left out with ``--fast``."""
    durations = recorded()
    per_file: dict[Path, float] = {}
    slow_families: set[tuple[Path, str]] = set()
    for item in items:
        per_file[item.path] = per_file.get(item.path, 0.0) + durations["tests"].get(item.nodeid, 0.0)
        if expected_seconds(item, durations) >= FAST_SECONDS:
            slow_families.add(family(item))
    for item in items:
        if family(item) in slow_families:
            item.add_marker(pytest.mark.slow)
    items.sort(key=lambda item: -per_file[item.path])
    if config.getoption("--fast"):
        slow = [item for item in items if item.get_closest_marker("slow")]
        config.hook.pytest_deselected(items=slow)
        items[:] = [item for item in items if not item.get_closest_marker("slow")]


_pending_fixtures: dict[str, float] = {}


@pytest.hookimpl(hookwrapper=True)
def pytest_fixture_setup(fixturedef: pytest.FixtureDef, request: pytest.FixtureRequest) -> Iterator[None]:
    """Time the set-up of fixtures wider than a test; a test's own set-up time already holds its others."""
    started = time.perf_counter()
    yield
    if fixturedef.scope != "function":
        key = fixture_key(fixturedef.scope, fixturedef.argname, request.node.nodeid)
        _pending_fixtures[key] = _pending_fixtures.get(key, 0.0) + time.perf_counter() - started


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo) -> Iterator[None]:
    """The shared fixtures set up for this test travel in its set-up report, which xdist's workers send on."""
    outcome = yield
    if call.when == "setup" and _pending_fixtures:
        outcome.get_result().user_properties.append((FIXTURE_SECONDS, dict(_pending_fixtures)))
        _pending_fixtures.clear()


_measured: dict[str, dict[str, float]] = {"tests": {}, "fixtures": {}}
_failed: set[str] = set()


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    if not report.passed:
        _failed.add(report.nodeid)
    tests = _measured["tests"]
    tests[report.nodeid] = tests.get(report.nodeid, 0.0) + report.duration
    for name, value in report.user_properties:
        if name == FIXTURE_SECONDS and report.passed:
            _measured["fixtures"].update(value)


def updated(durations: dict[str, dict[str, float]], measured: dict[str, dict[str, float]], failed: set[str],
            root: Path) -> dict[str, dict[str, float]]:
    """The recorded durations with those of the tests that passed in this run, the files gone dropped."""
    passed = {nodeid: seconds for nodeid, seconds in measured["tests"].items() if nodeid not in failed}
    merged = {"tests": {**durations["tests"], **passed}, "fixtures": {**durations["fixtures"], **measured["fixtures"]}}
    return {kind: {key: round(seconds, 2) for key, seconds in sorted(entries.items())
                   if key.endswith(" (session)") or (root / key.split("::")[0]).is_file()}
            for kind, entries in merged.items()}


def pytest_sessionfinish(session: pytest.Session) -> None:
    """Update :data:`DURATIONS` when ``RLCOMPARE_WRITE_DURATIONS`` is set (on xdist's controller, which receives
    every worker's reports)."""
    if os.environ.get("RLCOMPARE_WRITE_DURATIONS") and not hasattr(session.config, "workerinput"):
        durations = updated(recorded(), _measured, _failed, session.config.rootpath)
        DURATIONS.write_text(json.dumps(durations, indent=0) + "\n")


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
