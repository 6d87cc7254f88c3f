"""Benchmark: how long a click on the explorer's chart takes to answer (issue 15).

Run with ``.venv/bin/python benchmarks/bench_explorer.py`` (``--screenshot
docs/img/explorer.png`` also saves a picture of the page). Prints a markdown
table for docs/benchmarks.md.

The explorer for the paper's scenario (six robots, P = 1, D = 0.5) serves on a
free loopback port. The page loads, which computes the chart's exact map, as a
user's first view does; then:

1. ``GET /api/point`` at point a (0.3, 0.2), timed by a Python client from
   sending the request to holding the parsed JSON (a fresh connection each
   time; point answers are never cached, only the map is);
2. clicks at point a in headless Chromium (system package, driven by
   Playwright), timed inside the page from the click's handler to the
   verdict drawn (fetch, JSON, DOM and the roots' plot), alternating with a
   click at point b so every click at a is a new answer;
3. the robots' default run at a (``/api/simulate``, 40 s simulated), which the
   page starts after the verdict, on the paper's network and with the network
   switch on (packet loss 0.3, jitter +-0.05 s);
4. the eigenvalue plane at a (``/api/region``: boundary curve, NU on an 81 x 81
   grid of the lam plane, the team's eigenvalues), never cached.

Median, best and worst of the repeats; the machine is shared, so the medians are the figure.
"""

from __future__ import annotations

import argparse
import http.client
import json
import os
import platform
import shutil
import statistics
import tempfile
import time
from pathlib import Path

from delayform.analysis.ctcr.stability_map import PAPER_POINTS
from delayform.app import Explorer, start
from delayform.scenario import paper_scenario

GOAL_MS = 300.0


def timed_get(port: int, path: str) -> float:
    """Milliseconds from request to parsed JSON."""
    began = time.perf_counter()
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=60)
    conn.request("GET", path)
    resp = conn.getresponse()
    body = json.loads(resp.read())
    conn.close()
    assert resp.status == 200, body
    return (time.perf_counter() - began) * 1e3


def summary(name: str, times: list[float]) -> str:
    """One markdown row: median, best, worst, count."""
    return (f"| {name} | {statistics.median(times):.0f} | {min(times):.0f} | {max(times):.0f} | {len(times)} |")


def browser_clicks(url: str, repeats: int, screenshot: Path | None) -> list[float]:
    """In-page milliseconds from a click at a to its verdict, for ``repeats`` clicks."""
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        print("chromium not installed: browser clicks not measured")
        return []
    from playwright.sync_api import sync_playwright

    pixel_of = """([t1, t2]) => { const gd = document.getElementById("chart");
      const xa = gd._fullLayout.xaxis, ya = gd._fullLayout.yaxis, box = gd.getBoundingClientRect();
      return [box.left + xa._offset + xa.l2p(t1), box.top + ya._offset + ya.l2p(t2)]; }"""
    done = """(n) => Number(document.body.dataset.clicks || 0) >= n"""
    settled = """() => document.body.dataset.simPoint === document.body.dataset.point"""
    times = []
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=chromium, headless=True, args=["--no-sandbox"])
        page = browser.new_page(viewport={"width": 1400, "height": 1000})
        page.goto(url)
        page.wait_for_function("() => document.body.dataset.simPoint", timeout=60_000)
        # count finished clicks in the page: a MutationObserver on the verdict's data attribute
        page.evaluate("""() => { new MutationObserver(() => {
            document.body.dataset.clicks = String(Number(document.body.dataset.clicks || 0) + 1); })
          .observe(document.body, { attributeFilter: ["data-point"] }); }""")
        clicks = 0
        for k in range(2 * repeats):
            label = "a" if k % 2 else "b"
            page.mouse.click(*page.evaluate(pixel_of, list(PAPER_POINTS[label])))
            clicks += 1
            page.wait_for_function(done, arg=clicks, timeout=60_000)
            if label == "a":
                times.append(float(page.evaluate("() => document.body.dataset.pointMs")))
            # as a user does: look at the robots' run (it plays on) before the next click
            page.wait_for_function(settled, timeout=60_000)
            page.wait_for_timeout(300)
        if screenshot is not None:  # at exactly a, typed into the fields, with the mouse off the chart
            page.fill("#tau1", str(PAPER_POINTS["a"][0]))
            page.fill("#tau2", str(PAPER_POINTS["a"][1]))
            page.dispatch_event("#tau2", "change")
            page.mouse.move(5, 5)
            page.wait_for_function("() => document.body.dataset.simPoint === '0.3,0.2'", timeout=60_000)
            page.wait_for_function("() => document.body.dataset.region === '0.3,0.2'", timeout=60_000)
            page.wait_for_function("() => Number(document.body.dataset.simTime) > 6", timeout=60_000)
            screenshot.parent.mkdir(parents=True, exist_ok=True)
            page.screenshot(path=str(screenshot), full_page=True)
            print(f"screenshot: {screenshot}")
        browser.close()
    return times


def main() -> None:
    """Run the three measurements and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=15)
    parser.add_argument("--screenshot", type=Path, default=None)
    args = parser.parse_args()
    t1, t2 = PAPER_POINTS["a"]
    with tempfile.TemporaryDirectory() as tmp, start(Explorer(paper_scenario(), out_dir=tmp)) as running:
        timed_get(running.port, "/api/chart")  # the page's first view: the exact map is computed here
        timed_get(running.port, f"/api/point?tau1={t1}&tau2={t2}")  # warm-up
        api = [timed_get(running.port, f"/api/point?tau1={t1}&tau2={t2}") for _ in range(args.repeats)]
        clicks = browser_clicks(running.url, max(3, args.repeats // 2), args.screenshot)
        robots = [timed_get(running.port, f"/api/simulate?tau1={t1}&tau2={t2}&duration={40 + (k + 1) * 1e-6}")
                  for k in range(3)]  # fmt: skip
        lossy = [timed_get(running.port, f"/api/simulate?tau1={t1}&tau2={t2}&duration={40 + (k + 1) * 1e-6}"
                                         "&network=1&loss=0.3&jitter=0.05") for k in range(3)]  # fmt: skip
        plane = [timed_get(running.port, f"/api/region?tau1={t1}&tau2={t2}") for _ in range(args.repeats)]
    print(f"\nMeasured {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())} on {platform.machine()}, "
          f"{os.cpu_count()} cores, Python {platform.python_version()}; load average "
          f"{os.getloadavg()[0]:.1f} (shared machine)\n")  # fmt: skip
    print("| measurement | median (ms) | best (ms) | worst (ms) | repeats |")
    print("|---|---|---|---|---|")
    print(summary("`GET /api/point` at a (HTTP client)", api))
    if clicks:
        print(summary("click at a -> verdict drawn (headless Chromium)", clicks))
    print(summary("robots' run at a, 40 s simulated (`/api/simulate`)", robots))
    print(summary("the same over a network, loss 0.3, jitter +-0.05 s", lossy))
    print(summary("eigenvalue plane at a (`/api/region`)", plane))
    worst_median = max(statistics.median(api), statistics.median(clicks) if clicks else 0.0)
    print(f"\nGoal: a click at a answers in under {GOAL_MS:.0f} ms: "
          f"{'met' if worst_median < GOAL_MS else 'NOT met'} (median {worst_median:.0f} ms)")  # fmt: skip


if __name__ == "__main__":
    main()
