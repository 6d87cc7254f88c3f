"""The explorer in a real headless browser: click the chart at the paper's points a and c.

The system Chromium (installed by ``make browser``, which ``make test`` runs)
is driven by Playwright's Python package through ``executable_path``: no
browser is downloaded. Without Chromium the test skips and says why.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from delayform.analysis.ctcr.stability_map import PAPER_POINTS
from delayform.app import Explorer, start
from delayform.scenario import paper_scenario

pytestmark = [pytest.mark.browser, pytest.mark.slow]  # a headless Chromium per test: 12-26 s under load

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
#: flags for a browser that reaches nothing but the explorer and keeps no state
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--no-first-run"]  # fmt: skip

#: page -> pixel of a delay pair, through the axes Plotly drew (the inverse of the page's click handler)
PIXEL_OF = """([t1, t2]) => {
  const gd = document.getElementById("chart");
  const xa = gd._fullLayout.xaxis, ya = gd._fullLayout.yaxis;
  const box = gd.getBoundingClientRect();
  return [box.left + xa._offset + xa.l2p(t1), box.top + ya._offset + ya.l2p(t2),
          xa._length / (xa.range[1] - xa.range[0])];
}"""


def _click_and_read(page, tau: tuple[float, float]) -> dict[str, object]:
    x, y, px_per_second = page.evaluate(PIXEL_OF, list(tau))
    page.mouse.click(x, y)
    page.wait_for_function(
        """() => {
          const d = document.body.dataset;
          const here = `${Number(document.getElementById("tau1").value)},${Number(document.getElementById("tau2").value)}`;
          return d.point === here && d.simPoint === here && d.region === here;
        }""",
        timeout=30_000,
    )
    return {
        "tau1": float(page.input_value("#tau1")),
        "tau2": float(page.input_value("#tau2")),
        "verdict": page.inner_text("#verdict"),
        "count": int(page.inner_text("#unstable-count")),
        # the eigenvalue plane: its verdict, and the team's eigenvalues drawn green or red
        "region_stable": page.evaluate("() => document.body.dataset.regionStable") == "true",
        "red_eigenvalues": page.evaluate("() => document.getElementById('region').data[4].x.length"),
        "tolerance": 1.5 / px_per_second,  # a click lands within a pixel or so
    }


def _sim_time(page) -> float:
    return float(page.evaluate("() => Number(document.body.dataset.simTime)"))


def test_click_a_then_c_in_chromium(tmp_path: Path) -> None:
    if CHROMIUM is None:
        pytest.skip("chromium is not installed (make test installs it as root where apt-get exists)")
    from playwright.sync_api import sync_playwright

    out = tmp_path / "out"
    requests: list[str] = []
    problems: list[str] = []
    with start(Explorer(paper_scenario(), out_dir=out)) as running, sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, headless=True, args=CHROMIUM_ARGS)
        try:
            page = browser.new_page(viewport={"width": 1400, "height": 1000})
            page.on("request", lambda r: requests.append(r.url))
            page.on("pageerror", lambda e: problems.append(f"page error: {e}"))
            page.on("console", lambda m: problems.append(f"console {m.type}: {m.text}") if m.type == "error" else None)
            page.goto(running.url)
            # the chart and the first verdict are in (the first run may still be computing)
            page.wait_for_function("() => document.body.dataset.chartReady && document.body.dataset.point",
                                   timeout=30_000)  # fmt: skip

            seen = {}
            for label in ("a", "c"):
                seen[label] = _click_and_read(page, PAPER_POINTS[label])
                t_first = _sim_time(page)
                page.wait_for_timeout(800)
                seen[label]["advanced"] = _sim_time(page) > t_first
            # both switches at once: robots with limits over the imperfect network
            page.check("#toggle-limits")
            page.check("#toggle-network")
            switches = (page.is_checked("#toggle-limits"), page.is_visible("#loss"))
        finally:
            browser.close()

    for label, verdict, count in (("a", "stable", 0), ("c", "unstable", 4)):
        got = seen[label]
        assert abs(got["tau1"] - PAPER_POINTS[label][0]) < got["tolerance"], got
        assert abs(got["tau2"] - PAPER_POINTS[label][1]) < got["tolerance"], got
        assert got["verdict"] == verdict, got
        assert got["count"] == count, got  # NU at c: two conjugate pairs (Fig. stability)
        assert got["advanced"], f"the animation did not advance at {label}"
        assert got["region_stable"] is (verdict == "stable"), got
    # at c the eigenvalues -0.5 and -0.64 of C lie outside the stable region (two roots each)
    assert seen["a"]["red_eigenvalues"] == 0 and seen["c"]["red_eigenvalues"] == 2, seen
    assert switches == (True, True)
    assert not problems, problems
    outside = [u for u in requests if not u.startswith(running.url)]
    assert not outside, f"the page loaded something from elsewhere: {outside[:3]}"
    assert not out.exists()  # nothing was downloaded, so nothing was written
