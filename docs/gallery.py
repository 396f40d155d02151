"""Refresh the results gallery from a ``pbvs-pin reproduce`` output folder.

    python docs/gallery.py RESULTS

Copies the figures :data:`FIGURES` names from ``RESULTS`` into ``docs/_static/gallery/``, takes
a screenshot of Experiment 2's replay in headless Chromium (``/usr/bin/chromium``, driven by
Playwright; override with ``PBVS_CHROMIUM``), and rewrites the generated tables of
``docs/gallery.md`` and of the README from the run summaries (:mod:`pbvs_pin.study.report`).
"""

from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path

from pbvs_pin.study.report import update_readme

DOCS = Path(__file__).resolve().parent
GALLERY = DOCS / "_static" / "gallery"

FIGURES = {
    "experiment1_feature_errors.png": "experiment1/feature_errors.png",
    "experiment2_motion_xyz.png": "experiment2/motion_xyz.png",
    "experiment2_arm_commands.png": "experiment2/arm_commands.png",
    "experiment3_feature_errors.png": "experiment3/feature_errors.png",
    "experiment4_feature_errors.png": "experiment4/feature_errors.png",
    "experiment1_bound.png": "experiment1/analysis/bound.png",
    "robustness.png": "robustness.png",
}
"""Gallery file -> its source in a ``reproduce`` folder."""

REPLAY = ("replay_experiment2.png", "experiment2/replay.html", 0.8)
"""The replay screenshot: gallery file, source page, instant shown [s]."""


def screenshot(page: Path, when: float, out: Path) -> None:
    """A 1000 x 640 screenshot of a replay page paused at ``when`` [s]."""
    from playwright.sync_api import sync_playwright

    chromium = os.environ.get("PBVS_CHROMIUM", "/usr/bin/chromium")
    with sync_playwright() as p:
        browser = p.chromium.launch(
            executable_path=chromium,
            args=["--headless", "--no-sandbox", "--enable-unsafe-swiftshader"],
        )
        tab = browser.new_page(viewport={"width": 1000, "height": 640})
        tab.goto(page.resolve().as_uri())
        tab.wait_for_function("() => window.viewer && viewer.animator.actions.length > 0")
        tab.evaluate(
            "(t) => { const a = viewer.animator; a.pause(); a.seek(t); viewer.set_dirty();"
            " return new Promise(r => requestAnimationFrame(() =>"
            " requestAnimationFrame(() => r(true)))); }",
            when,
        )
        tab.screenshot(path=str(out))
        browser.close()


def refresh(results: Path) -> None:
    """Copy the figures, take the replay's screenshot and regenerate the tables."""
    GALLERY.mkdir(parents=True, exist_ok=True)
    for name, source in FIGURES.items():
        shutil.copy(results / source, GALLERY / name)
    name, page, when = REPLAY
    screenshot(results / page, when, GALLERY / name)
    update_readme(DOCS / "gallery.md", results)
    update_readme(DOCS.parent / "README.md", results)


if __name__ == "__main__":
    refresh(Path(sys.argv[1]))
