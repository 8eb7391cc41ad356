"""Regenerate the screenshots in docs/images: the first screen (1,280 x 800) of the paper's report and of the
MinAtar report, each from a small study run in a temporary directory (a minute or two on 2 cores).

    .venv/bin/python scripts/screenshots.py

Needs the test extra (Playwright) and Chromium (``scripts/test`` installs it).
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
IMAGES = ROOT / "docs" / "images"
STUDIES = {
    "paper": ["paper", "--seeds", "10", "--episodes", "500", "--no-videos"],
    "minatar": ["minatar", "--seeds", "6", "--games", "breakout,asterix", "--steps", "81920", "--no-videos"],
}
VIEWPORT = {"width": 1280, "height": 800}


def run_study(arguments: list[str], out: Path) -> Path:
    command = [str(Path(sys.executable).parent / "rlcompare"), "reproduce", *arguments, "--out", str(out)]
    subprocess.run(command, check=True, stdout=subprocess.DEVNULL)
    return out / "report.html"


def first_screen(page_path: Path, image: Path) -> None:
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=shutil.which("chromium"),
                                             args=["--no-sandbox", "--disable-gpu"])
        page = browser.new_page(viewport=VIEWPORT)
        page.goto(page_path.resolve().as_uri())
        page.wait_for_function("() => [...document.images].every(i => i.complete)")
        page.screenshot(path=str(image))
        browser.close()


def main() -> None:
    if shutil.which("chromium") is None:
        sys.exit("scripts/screenshots.py: chromium is not installed (scripts/test installs it)")
    IMAGES.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as scratch:
        for name, arguments in STUDIES.items():
            image = IMAGES / f"{name}-first-screen.png"
            first_screen(run_study(arguments, Path(scratch) / name), image)
            print(f"{image.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
