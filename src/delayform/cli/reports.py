"""Whole reports: report and paper."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from delayform.cli._common import (
    OutDir,
    _emit,
    _out_dir,
    _progress,
    _scenario,
    actuation_option,
    cli,
    scenario_options,
    with_actuation,
)

if TYPE_CHECKING:
    from delayform.scenario import Scenario


def _write_full_report(sc: Scenario, directory: Path, *, paper: bool, as_json: bool, jitter_grid: int | None = None) -> None:
    """Build the report in a hidden folder inside ``directory`` and move it in when complete.

    The previous report's files are replaced all at once (:func:`delayform._files.staged_folder`):
    Ctrl-C or an error during the build leaves the previous report as it was.
    """
    from delayform._files import staged_folder
    from delayform.report import jsonable

    with staged_folder(directory) as staging:
        sections, index, seconds = _build_full_report(sc, staging, paper=paper, jitter_grid=jitter_grid)
    index = directory / index.name
    if as_json:
        click.echo(json.dumps(jsonable({s.key: s.summary for s in sections} | {"index": str(index)}), indent=2))
    else:
        for section in sections:
            _emit(section, directory, as_json=False)
        click.echo(f"Report: {index} ({seconds:.1f} s)")
    from delayform.cli.montecarlo import shout_bugs

    for section in sections:  # the Monte Carlo's contradictions, if any: loudly, after the report is written
        shout_bugs(section.summary if section.key == "montecarlo" else {})


def _build_full_report(sc: Scenario, directory: Path, *, paper: bool,
                       jitter_grid: int | None = None) -> tuple[list[Any], Path, float]:  # fmt: skip
    from delayform.report import paper_sections, scenario_sections, write_report

    network = paper or sc.network is not None  # the network section: promises (paper) or a Monte Carlo
    steps = (10 if paper else 7) + network
    start = time.perf_counter()
    with _progress(steps, title="paper" if paper else "report") as step:
        # jitter_grid only when asked: None is scenario_sections' own default (automatic)
        extra = {} if jitter_grid is None else {"jitter_grid": jitter_grid}
        sections = paper_sections(sc, directory, progress=step) if paper else \
            scenario_sections(sc, directory, progress=step, **extra)
        if paper:  # gain design: what new gains do where the paper can only add delay
            from delayform.report import gain_comparison_section

            step("gain design vs delay scheduling")
            points = {k: (a, b) for k, a, b in sc.chart.points if k in "abc"}
            sections.append(gain_comparison_section(sc, directory, points))
        if network:
            from delayform.report import montecarlo_section, promises_section

            step("imperfect network" if paper else "Monte Carlo over the network")
            sections.append(promises_section(sc, directory) if paper else montecarlo_section(sc, directory, runs=20))
        step("writing index.html")
        seconds = time.perf_counter() - start
        if paper:
            title = "Formation control under two delays: the paper's example reproduced"
            intro = ("Cepeda-Gomez and Perico, Formation Control of Non-holonomic Vehicles under Time Delayed "
                     "Communications, Section 'Simulation Examples': six robots (paper, Fig. 2), P = 1, D = 0.5, "
                     "computed by delayform from scratch.")  # fmt: skip
        else:
            title = f"delayform report: {sc.name}"
            intro = sc.description or f"Scenario {sc.source}."
        index = write_report(sections, directory, title=title, intro=intro, scenario=sc, seconds=seconds)
    return sections, index, seconds


@cli.command("report")
@scenario_options
@actuation_option
@click.option("--jitter-grid", type=click.IntRange(min=0, max=200),
              help="Contour lines of the certified jitter margin on the chart, N points per axis; 0: none "
                   "[default: 24 when the scenario's network jitters or varies its delays, else none].")  # fmt: skip
def report_command(scenario: Path | None, actuation_delay: float | None, jitter_grid: int | None, out: Path | None,
                   as_json: bool,
                   **overrides: Any) -> None:  # fmt: skip
    """All analyses of one scenario as one self-contained HTML page.

    Runs factors, chart, roots, map, schedule and simulate and writes their
    files plus index.html (figures embedded, a table of numbers and a short
    text per figure) and summary.json into --out. With a [network] table also
    a Monte Carlo over it, with the certificates that cover it beside what the
    runs observed.
    """
    sc = with_actuation(_scenario(scenario, **overrides), actuation_delay)
    from delayform.report.page import report_scenario

    sc = report_scenario(sc)  # what the report cannot answer is refused here, before anything is computed
    _write_full_report(sc, _out_dir(out, sc, create=False), paper=False, as_json=as_json, jitter_grid=jitter_grid)


@cli.command("paper")
@click.option("--out", type=OutDir(), default=Path("out/paper"),
              show_default=True, help="Output directory.")
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON on stdout.")
def paper_command(out: Path, as_json: bool) -> None:
    """Reproduce the paper's example end to end (what `make demo` runs).

    Eigenvalues and factors of the six-robot team, the stability chart with
    points a..e, x/y versus time at a and b, traces at a, the dominant-root
    surface and contour, the best delays by scheduling and the settling
    times, and gain design compared with delay scheduling at a, b and c;
    all into --out with index.html and summary.json.
    """
    from delayform.scenario import paper_scenario

    sc = paper_scenario()
    _write_full_report(sc, _out_dir(out, sc), paper=True, as_json=as_json)


