"""The explorer's issue-20 views in a real headless browser.

The jitter-margin layer: toggle it on, see the contour trace, redraw, off; and the
guaranteed-vs-observed table filled after the robots' run.

Same Chromium as tests/test_explorer_browser.py (skips without it).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from delayform.app import Explorer, start
from delayform.scenario import paper_scenario
from test_explorer_browser import CHROMIUM, CHROMIUM_ARGS

pytestmark = [pytest.mark.browser, pytest.mark.slow]  # a headless Chromium per test: 12-26 s under load

TRACE = """() => (document.getElementById("chart").data || []).filter((t) => t.name === "jitter margin (s)")
  .map((t) => ({ type: t.type, levels: t.contours.start, n: t.x.length }))"""


def test_toggle_the_jitter_layer_in_chromium(tmp_path: Path) -> None:
    if CHROMIUM is None:
        pytest.skip("chromium is not installed (make test installs it as root where apt-get exists)")
    from playwright.sync_api import sync_playwright

    problems: list[str] = []
    with start(Explorer(paper_scenario(), out_dir=tmp_path / "out")) as running, sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, headless=True, args=CHROMIUM_ARGS)
        try:
            page = browser.new_page(viewport={"width": 1400, "height": 1000})
            page.on("pageerror", lambda e: problems.append(f"page error: {e}"))
            page.on("console", lambda m: problems.append(f"console {m.type}: {m.text}") if m.type == "error" else None)
            page.goto(running.url)
            page.wait_for_function("() => document.body.dataset.chartReady", timeout=30_000)
            # the first run (the scenario's point a): its certificates beside what it observed
            page.wait_for_function("() => document.body.dataset.sideBySide", timeout=90_000)
            beside = page.inner_text("#side-by-side-table")
            page.fill("#tau1_max", "3")
            page.fill("#tau2_max", "3")
            page.dispatch_event("#tau2_max", "change")
            page.check("#jitter-layer")
            page.wait_for_function("() => (document.body.dataset.jitterReady || '').startsWith('3,3,')", timeout=90_000)
            first = page.evaluate(TRACE)
            status = page.inner_text("#jitter-layer-status")
            # a new window redraws the chart (its traces replaced): the layer comes back for the new window
            page.fill("#tau1_max", "2")
            page.dispatch_event("#tau1_max", "change")
            page.wait_for_function("() => (document.body.dataset.jitterReady || '').startsWith('2,3,')", timeout=90_000)
            again = page.evaluate(TRACE)
            page.uncheck("#jitter-layer")
            page.wait_for_function("() => !document.body.dataset.jitterReady", timeout=10_000)
            off = page.evaluate(TRACE)
        finally:
            browser.close()
    assert len(first) == 1 and first[0]["type"] == "contour" and first[0]["n"] == 12, first
    assert "largest" in status and "s at" in status, status
    assert len(again) == 1, again
    assert off == []
    assert "constant delays (exact, per link)\tguaranteed" in beside and "observed\t" in beside, beside
    assert "BUG" not in beside
    assert not problems, problems
