"""The explorer: a local web page to click the stability chart, see the roots and watch the robots.

``delayform explore [SCENARIO]`` starts it; from Python::

    from delayform.app import Explorer, start
    from delayform.scenario import paper_scenario

    with start(Explorer(paper_scenario(), out_dir="out/explore")) as running:
        print(running.url)   # http://127.0.0.1:<port>/

The page (``static/``) draws with Plotly's JavaScript served from the
installed ``plotly`` package; the server (Starlette on uvicorn) listens on
127.0.0.1 only. See docs/explorer.md.
"""

from delayform.app.explorer import Animation, ChartData, Explorer, PointReport, RootsReport, crossing_frequency_bound
from delayform.app.params import ExplorerLimits
from delayform.app.plane import RegionReport, region_report
from delayform.scenario.write import scenario_toml
from delayform.app.server import LOOPBACK, RunningExplorer, check_host, create_app, serve, start

__all__ = [
    "Explorer",
    "ExplorerLimits",
    "PointReport",
    "RootsReport",
    "RegionReport",
    "region_report",
    "crossing_frequency_bound",
    "ChartData",
    "Animation",
    "scenario_toml",
    "create_app",
    "check_host",
    "serve",
    "start",
    "RunningExplorer",
    "LOOPBACK",
]
