"""report.html in a real headless browser: Debian's Chromium, driven by Playwright.

The test command (``scripts/test``) installs Chromium on a fresh machine; in CI its absence is a failure,
on a developer's machine without it the test is skipped.
"""

from __future__ import annotations

import os
import re
import shutil
from pathlib import Path

import pytest

from rlcompare.studies.paper.claims import CLAIMS
from rlcompare.studies.paper.report import build_report, load_study
from rlcompare.studies.paper.study import paper_configs, reproduce
from rlcompare.studies.paper.videos import CONFIGURATIONS, video_plan

pytestmark = pytest.mark.slow("renders a report in Chromium")

CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run", "--disable-sync",
                 "--disable-background-networking", "--disable-component-update"]


@pytest.fixture(scope="module")
def chromium() -> str:
    path = shutil.which("chromium")
    if path is None:
        if os.environ.get("CI"):
            pytest.fail("chromium is not installed; scripts/test installs it on a fresh machine")
        pytest.skip("chromium is not installed (scripts/test installs it)")
    return path


@pytest.mark.slow("starts a browser; where chromium is missing the recorded run only saw it skipped")
def test_report_renders_with_every_image_and_video_loaded(chromium: str, tmp_path: Path) -> None:
    sync_playwright = pytest.importorskip("playwright.sync_api").sync_playwright
    configs = paper_configs((0, 1, 2), episodes=300, max_steps=300, eval_every=50, eval_episodes=3)
    list(reproduce(tmp_path, configs))
    outcome = build_report(tmp_path, videos=True)
    assert outcome.problems == []

    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=chromium, args=CHROMIUM_ARGS)
        page = browser.new_page(viewport={"width": 1280, "height": 900})
        page.goto(outcome.path.resolve().as_uri())
        page.wait_for_function("() => [...document.images].every(i => i.complete)", timeout=30_000)
        page.wait_for_function(
            "() => [...document.querySelectorAll('video')].every(v => v.readyState >= 2 && v.duration > 0)",
            timeout=60_000,
        )
        images = page.evaluate("() => [...document.images].map(i => [i.getAttribute('src'), i.naturalWidth])")
        videos = page.evaluate(
            "() => [...document.querySelectorAll('video')].map(v => [v.getAttribute('src'), v.readyState, v.duration,"
            " v.videoWidth])"
        )
        tables = page.evaluate(
            "() => Object.fromEntries([...document.querySelectorAll('h3')].map(h => [h.firstChild.textContent.trim(),"
            " [...h.nextElementSibling.querySelectorAll('tbody tr')].map(r => r.cells[0].textContent)]))"
        )
        first_screen = page.evaluate(
            "() => ({answer: document.querySelector('h2 + p').getBoundingClientRect().top,"
            " text: document.querySelector('h2 + p').textContent,"
            " figure: document.querySelector('img').getBoundingClientRect().top})"
        )
        unresolved = page.evaluate(
            "() => [...document.querySelectorAll('nav a')].map(a => a.getAttribute('href'))"
            ".filter(h => !document.getElementById(h.slice(1)))"
        )
        links = page.evaluate("() => [...document.querySelectorAll('nav a')].length")
        widest = page.evaluate(
            "() => Math.max(...[...document.querySelectorAll('table')].map(t => t.getBoundingClientRect().right))"
        )
        cells = page.evaluate("() => [...document.querySelectorAll('td')].map(c => c.textContent)")
        csv = page.evaluate("() => [...document.querySelectorAll('h3 a.files')].map(a => a.getAttribute('href'))")
        page.screenshot(path=str(tmp_path / "first-screen.png"))
        browser.close()

    assert len(images) >= 7 + 4 + 2  # figures 3-9, a stage figure per learner, visits, first actions
    assert all(width > 0 for _, width in images), images
    assert len(videos) == len(video_plan(tmp_path, load_study(tmp_path)[0], None))  # median seed x 3, extremes
    assert len(videos) > 1 + 4 * 3
    assert all(state >= 2 and duration > 0 and width > 0 for _, state, duration, width in videos), videos
    ablation = ["q_learning-constant-before_update", "q_learning-decay-before_update", "sarsa-constant-after_update",
                "sarsa-decay-after_update"]
    assert tables["Table I"] == [*CONFIGURATIONS, *ablation]
    assert tables["Table II"] == [*CONFIGURATIONS, *ablation]
    assert tables["SARSA minus Q-Learning, decomposed"] == ["constant"] * 6 + ["decay"] * 6
    assert tables["Verdicts"] == [claim.text for claim in CLAIMS]
    assert first_screen["text"].startswith("With ε constant, SARSA collects")  # the answer, on the first screen
    assert first_screen["answer"] < 300
    assert first_screen["figure"] < 800  # with its figure
    assert links >= 8
    assert unresolved == []
    assert widest <= 1280
    assert not [c for c in cells if "nan" in c.split() or re.search(r"\de[+-]\d", c)]
    assert all((tmp_path / path).is_file() for path in csv)
    assert len(csv) >= 4
    assert (tmp_path / "first-screen.png").stat().st_size > 50_000
