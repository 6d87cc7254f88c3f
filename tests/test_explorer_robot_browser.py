"""The explorer's robot controls in headless Chromium: the actuation delay turns point a unstable.

As tests/test_explorer_browser.py (system Chromium through Playwright's
``executable_path``; skipped without it). The page must send the controls
with the requests that take them and draw the server's answer: at point a,
stable at tau_a = 0, an actuation delay of 0.3 s makes the team unstable
(the certified count of tests/test_actuation.py: NU = 2).
"""

from __future__ import annotations

from pathlib import Path
from urllib.parse import parse_qs, urlparse

import pytest
from test_explorer_browser import CHROMIUM, CHROMIUM_ARGS

from delayform.app import Explorer, start
from delayform.scenario import paper_scenario

pytestmark = [pytest.mark.browser, pytest.mark.slow]  # a headless Chromium per test: 12-26 s under load


def test_actuation_delay_and_switches_from_the_page(tmp_path: Path) -> None:
    if CHROMIUM is None:
        pytest.skip("chromium is not installed (make test installs it as root where apt-get exists)")
    from playwright.sync_api import sync_playwright

    requests: list[str] = []
    problems: list[str] = []
    with start(Explorer(paper_scenario(), out_dir=tmp_path / "out")) as running, sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, headless=True, args=CHROMIUM_ARGS)
        try:
            page = browser.new_page(viewport={"width": 1400, "height": 1000})
            page.on("request", lambda r: requests.append(r.url))
            page.on("pageerror", lambda e: problems.append(f"page error: {e}"))
            page.goto(running.url)
            page.wait_for_function("() => document.body.dataset.chartReady && document.body.dataset.point",
                                   timeout=30_000)  # fmt: skip
            page.wait_for_function("() => document.getElementById('verdict').textContent === 'stable'", timeout=30_000)
            before = page.inner_text("#verdict")
            page.fill("#robot-actuation", "0.3")
            page.dispatch_event("#robot-actuation", "change")
            page.wait_for_function("() => document.getElementById('verdict').textContent === 'unstable'",
                                   timeout=30_000)  # fmt: skip
            count = int(page.inner_text("#unstable-count"))
            page.check("#toggle-limits")  # robots that can apply a late command
            page.check("#robot-safety")
            page.check("#robot-assignment")
            page.wait_for_function(
                "() => document.getElementById('download-figures').href.includes('assignment=1')", timeout=10_000
            )
            page.wait_for_timeout(500)
            download = page.get_attribute("#download-scenario", "href")
        finally:
            browser.close()

    assert before == "stable" and count == 2
    sent = [(urlparse(u).path, parse_qs(urlparse(u).query)) for u in requests if "/api/" in u]
    assert any(p == "/api/chart" and q.get("actuation_delay") == ["0.3"] for p, q in sent)
    assert any(p == "/api/point" and q.get("actuation_delay") == ["0.3"] and "safety" not in q for p, q in sent)
    runs = [q for p, q in sent if p == "/api/simulate" and q.get("limits") == ["1"]]
    assert runs and runs[-1]["actuation_delay"] == ["0.3"] and "safety" in runs[-1]
    query = parse_qs(urlparse(download).query)
    assert (query["actuation_delay"], query["safety"], query["assignment"]) == (["0.3"], ["1"], ["1"])
    assert not problems, problems
