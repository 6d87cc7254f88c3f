"""Whole reports: the sections of a scenario or of the paper, and the self-contained HTML page."""

from __future__ import annotations

import base64
import html
import json
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

import numpy as np

from delayform._files import write_text
from delayform._validation import validated
from delayform.errors import ScenarioError
from delayform.scenario import Scenario
from delayform.report.analysis import (
    chart_section,
    factors_section,
    map_section,
    region_section,
    roots_section,
)
from delayform.report.design import schedule_section
from delayform.report.simulation import settling_section, simulation_section
from delayform.report._common import (
    Figure,
    MapProgress,
    Progress,
    Section,
    _fmt_complex,
    _step,
    jsonable,
)


# ------------------------------------------------------------ whole reports
def report_scenario(scenario: Scenario) -> Scenario:
    """The scenario as :func:`scenario_sections` answers it: one delay pair on every link.

    Its chart, roots, map and schedule are of one delay pair on every link
    (paper, eq. 3): per-link ``[network]`` delays equal on every link are that
    pair; delays that differ between links (or are drawn per run) are refused
    (:meth:`~delayform.scenario.Scenario.at_one_delay_pair`). The simulation
    and the Monte Carlo run over the rest of the ``[network]``.

    Raises
    ------
    ScenarioError
        Per-link delays that differ between links, or a formation or start
        that does not fit the team.
    SimulationInputError
        An actuation delay the report's simulation cannot model.
    """
    from delayform.simulation.runs.runner import check_actuation

    one = scenario.at_one_delay_pair("report (its chart, roots, map and schedule)",
                                     "links / box for the certificates, simulate / montecarlo for runs over [network]")
    # the simulation's own checks of what only it uses, made before the first section is computed
    one.desired_positions()
    one.initial_positions()
    check_actuation(one.robot_spec, one.network, one.simulation.dt)
    return one


def scenario_sections(
    scenario: Scenario, out: Path, *, progress: Progress | None = None, map_progress: MapProgress | None = None,
    jitter_grid: int | None = None,
) -> list[Section]:
    """Every analysis of one scenario, in the order of the data flow.

    Parameters
    ----------
    scenario
        The validated scenario (topology, gains, delays, windows).
    out
        Folder the section writes its files into.
    progress
        Optional Rich progress bar advanced once per analysis.
    map_progress
        Optional callback for the dominant-root map (see :func:`map_section`).
    jitter_grid
        Points per axis of the jitter-margin contours on the chart; 0: none; None
        (default): :func:`~delayform.report.jitter_overlay.auto_grid` (drawn when the
        scenario's network jitters or varies its delays).
    """
    from delayform.report.jitter_overlay import auto_grid

    scenario = report_scenario(scenario)
    jitter_grid = auto_grid(scenario) if jitter_grid is None else jitter_grid
    steps: list[tuple[str, Callable[[], Section]]] = [
        ("factors", lambda: factors_section(scenario, out)),
        ("stability chart", lambda: chart_section(scenario, out, jitter_grid=jitter_grid)),
        ("eigenvalue plane", lambda: region_section(scenario, out)),
        ("roots", lambda: roots_section(scenario, out)),
        ("dominant-root map", lambda: map_section(scenario, out, progress=map_progress)),
        ("delay scheduling", lambda: schedule_section(scenario, out, report_failure=True)),
        # the run over the scenario's [network], as `delayform simulate` makes it
        ("simulation", lambda: simulation_section(scenario, out, network=True)),
    ]
    sections = []
    for text, run in steps:
        _step(progress, text)
        sections.append(run())
    sections.append(settling_section([sections[-1]]))
    return sections


def paper_sections(
    scenario: Scenario, out: Path, *, progress: Progress | None = None, map_progress: MapProgress | None = None
) -> list[Section]:
    """The paper's Section "Simulation Examples" end to end, on the given (paper) scenario.

    Eigenvalues and factors, the stability chart with points a..e, x/y
    versus time at a and b, traces at a, the dominant-root surface and
    contour, the best delays, and the settling times.

    Parameters
    ----------
    scenario
        The validated scenario (topology, gains, delays, windows).
    out
        Folder the section writes its files into.
    progress
        Optional Rich progress bar advanced once per analysis.
    map_progress
        Optional callback for the dominant-root map (see :func:`map_section`).
    """
    points = {p[0]: p[1:] for p in scenario.chart.points}
    missing = [k for k in "abc" if k not in points]
    if missing:
        raise ScenarioError(f"{scenario.source}: chart.points: expected the paper's points a, b, c; missing {missing}")
    a, b, c = points["a"], points["b"], points["c"]
    window = (scenario.chart.tau1_max, scenario.chart.tau2_max)
    steps: list[tuple[str, Callable[[], Section]]] = [
        ("eigenvalues and factors", lambda: factors_section(scenario, out)),
        ("stability chart", lambda: chart_section(scenario, out)),
        ("simulation at a", lambda: simulation_section(scenario, out, label="a", tau1=a[0], tau2=a[1], gif=True)),
        ("simulation at b", lambda: simulation_section(scenario, out, label="b", tau1=b[0], tau2=b[1], traces=False)),
        ("eigenvalue plane at c", lambda: region_section(scenario, out, tau1=c[0], tau2=c[1])),
        ("roots", lambda: roots_section(scenario, out)),
        ("dominant-root map", lambda: map_section(scenario, out, progress=map_progress)),
        ("delay scheduling", lambda: schedule_section(scenario, out)),
        # the paper's point c is unstable; increasing the delays recovers stability (points d, e)
        ("delay scheduling from c", lambda: schedule_section(scenario, out, tau_min=c, tau_max=window, label="c")),
    ]  # fmt: skip
    sections = []
    for text, run in steps:
        _step(progress, text)
        sections.append(run())
    sections.append(settling_section([s for s in sections if s.key.startswith("simulation_")]))
    return sections


def highlights(sections: Sequence[Section]) -> tuple[tuple[str, str], ...]:
    """The key numbers of a report, for the table at the top of the page.

    Parameters
    ----------
    sections
        The report's sections; those present contribute their numbers.
    """
    by_key = {s.key: s.summary for s in sections}
    rows: list[tuple[str, str]] = []
    if "factors" in by_key:
        eig = by_key["factors"]["eigenvalues"]
        shown = ", ".join(_fmt_complex(complex(v)) for v in eig[:8]) + (" ..." if len(eig) > 8 else "")
        rows.append(("eigenvalues of C", shown))
    if "chart" in by_key:
        chart = by_key["chart"]
        rows.append(("stable share of the delay window", f"{chart['stable_fraction']:.1%}"))
        rows.extend(
            (f"point {p['label']} ({p['tau1']:g}, {p['tau2']:g})", "stable" if p["stable"] else f"unstable, NU = {p['unstable_roots']}")
            for p in chart["points"]
        )  # fmt: skip
    if "region" in by_key and by_key["region"].get("computed", True) is False:  # e.g. with an actuation delay
        rows.append(("eigenvalue plane", "not computed (see its section)"))
    elif "region" in by_key:
        reg = by_key["region"]
        rows.append((f"safe at ({reg['tau1']:g}, {reg['tau2']:g}) for every undirected team",
                     "yes" if reg["safe_for_every_undirected_team"] else "no"))  # fmt: skip
    if "roots" in by_key:
        roots = by_key["roots"]
        rows.append((f"dominant root at ({roots['tau1']:g}, {roots['tau2']:g})", _fmt_complex(roots["dominant_root"])))
    if "montecarlo" in by_key:  # what is guaranteed beside what the runs observed; a bug first
        mc = by_key["montecarlo"]
        held = [g["name"] for g in mc.get("guarantees", []) if g["holds"] is True]
        diverged = sum(mc.get("statuses", {}).get(k, 0) for k in ("diverging", "stopped"))
        if mc.get("contradictions"):
            rows.append(("BUG: a run diverged where a certificate holds", mc["contradictions"][0]))
        rows.append(("guaranteed for this network", ", ".join(held) if held else "nothing (see the Monte Carlo section)"))
        rows.append(("observed", f"{diverged} of {mc.get('runs', '?')} runs diverged"))
    for key, summary in by_key.items():
        if key.startswith("schedule") and summary.get("stable_delays_found"):
            lo = summary["tau_min"]
            rows.append((f"best delays from ({lo[0]:g}, {lo[1]:g})",
                         f"({summary['tau1']:.3g}, {summary['tau2']:.3g}) s, settling about {summary['settling_time']:.3g} s"))  # fmt: skip
        if key == "gain_comparison":
            for r in summary["rows"]:
                if r["method"] == "gain design" and r.get("found", True):
                    t = r["simulated_settling"]
                    rows.append((f"designed gains at {r['point']} ({r['tau1']:g}, {r['tau2']:g})",
                                 f"P = {r['P']:.3g}, D = {r['D']:.3g}, simulated settling "
                                 + (f"{t:.3g} s" if np.isfinite(t) else "none")))  # fmt: skip
        if key.startswith("simulation_"):
            t = summary["settling_time"]
            rows.append((f"simulated settling at {summary['label']} ({summary['tau1']:g}, {summary['tau2']:g})",
                         f"{t:.3g} s" if np.isfinite(t) else f"not within {summary['duration']:g} s"))  # fmt: skip
    return tuple(rows)


_CSS = """
body { font-family: system-ui, sans-serif; max-width: 60rem; margin: 2rem auto; padding: 0 1rem; color: #222; }
h1 { font-size: 1.6rem; } h2 { font-size: 1.25rem; margin-top: 2.2rem; border-bottom: 1px solid #ccc; }
figure { margin: 1rem 0; } figure img { max-width: 100%; border: 1px solid #ddd; }
figcaption { font-size: 0.92rem; color: #444; }
table { border-collapse: collapse; margin: 0.6rem 0; } td, th { border: 1px solid #ccc; padding: 0.25rem 0.6rem; text-align: left; }
.files { font-size: 0.85rem; color: #555; }
"""


def _figure_html(out: Path, figure: Figure) -> str:
    kind = "gif" if figure.animated else "png"
    data = base64.b64encode((out / f"{figure.stem}.{kind}").read_bytes()).decode("ascii")
    vector = "" if figure.animated else f' (<a href="{html.escape(figure.stem)}.svg">SVG</a>)'
    return (
        f'<figure id="{html.escape(figure.stem)}"><img alt="{html.escape(figure.title)}" '
        f'src="data:image/{kind};base64,{data}">'
        f"<figcaption><b>{html.escape(figure.title)}.</b> {html.escape(figure.text)}"
        f"{vector}</figcaption></figure>"
    )


def _table_html(rows: Iterable[tuple[str, str]]) -> str:
    body = "".join(f"<tr><th>{html.escape(k)}</th><td>{html.escape(v)}</td></tr>" for k, v in rows)
    return f"<table>{body}</table>" if body else ""


@validated()
def write_report(
    sections: Sequence[Section], out: Path, *, title: str, intro: str, scenario: Scenario, seconds: float | None = None
) -> Path:
    """Write ``index.html`` (self-contained: PNGs embedded) and ``summary.json`` into ``out``.

    Parameters
    ----------
    sections
        The analyses to show, in order.
    out
        Folder of the report; the sections' files are already there.
    title, intro
        Heading and first paragraph of the page.
    scenario
        The scenario, shown as a table.
    seconds
        Wall time of the analyses, shown on the page when given.

    Returns
    -------
    Path
        The HTML file.
    """
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f"<title>{html.escape(title)}</title><style>{_CSS}</style></head><body>",
        f"<h1>{html.escape(title)}</h1>",
        f"<p>{html.escape(intro)}</p>",
        "<h2>At a glance</h2>",
        _table_html(highlights(sections)),
        "<h2>Scenario</h2>",
        _table_html((k, json.dumps(jsonable(v)) if not isinstance(v, str) else v)
                    for k, v in scenario.summary().items()),
    ]  # fmt: skip
    for section in sections:
        parts.append(f'<section id="{html.escape(section.key)}"><h2>{html.escape(section.title)}</h2>')
        parts.append(f"<p>{html.escape(section.text)}</p>")
        parts.extend(_figure_html(out, f) for f in section.figures)
        parts.append(_table_html(section.table))
        if section.files:
            links = ", ".join(f'<a href="{html.escape(f)}">{html.escape(f)}</a>' for f in section.files)
            parts.append(f'<p class="files">Files: {links}</p>')
        parts.append("</section>")
    footer = "Generated by delayform" + (f" in {seconds:.1f} s" if seconds is not None else "") + "."
    parts.append(f'<p class="files">{html.escape(footer)}</p></body></html>')
    index = out / "index.html"
    write_text(index, "\n".join(parts))
    summary = {
        "title": title,
        "scenario": scenario.summary(),
        "seconds": seconds,
        "sections": {s.key: s.summary for s in sections},
        "files": sorted({f for s in sections for f in s.files} | {"index.html", "summary.json"}),
    }
    write_text(out / "summary.json", json.dumps(jsonable(summary), indent=2))
    return index
