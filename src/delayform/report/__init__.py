"""Reports: the analyses of a scenario written as files, and one self-contained HTML page.

Each ``*_section`` function runs one analysis of the library on a
:class:`~delayform.scenario.Scenario`, writes its figures (PNG and SVG), data
(CSV and NPZ) into an output directory and returns a :class:`Section`: a
title, a short text, the figures with a caption each, a table of numbers and
the JSON-ready summary. :func:`write_report` turns sections into
``index.html`` (figures embedded as base64 data URIs, so the page is one
file that opens anywhere) and ``summary.json``.

The ``delayform`` subcommands call these functions one at a time; ``report``
and ``paper`` call them all. Figures are drawn with the Agg backend: nothing
here opens a window.

The sections live in modules by stage: :mod:`~delayform.report.analysis`,
:mod:`~delayform.report.design`, :mod:`~delayform.report.simulation`,
:mod:`~delayform.report.network`; :mod:`~delayform.report.page` assembles
whole reports. Every public name is importable from :mod:`delayform.report`.
"""

from delayform.report._common import Figure, Section, jsonable
from delayform.report.analysis import (
    chart_section,
    factors_section,
    map_section,
    region_section,
    roots_section,
    safe_delays_section,
)
from delayform.report.design import DEFAULT_GAIN_BOUNDS, gain_comparison_section, gains_section, schedule_section
from delayform.report.network import (
    JITTER_FRACTIONS,
    LOSS_PROBABILITIES,
    montecarlo_section,
    promises_section,
    scenario_setup,
    sweep_section,
)
from delayform.report.page import highlights, paper_sections, scenario_sections, write_report
from delayform.report.simulation import CSV_AUTO_LIMIT, settling_section, simulation_section

__all__ = [
    "Figure",
    "Section",
    "jsonable",
    "factors_section",
    "chart_section",
    "roots_section",
    "map_section",
    "schedule_section",
    "gains_section",
    "gain_comparison_section",
    "DEFAULT_GAIN_BOUNDS",
    "simulation_section",
    "CSV_AUTO_LIMIT",
    "settling_section",
    "region_section",
    "safe_delays_section",
    "montecarlo_section",
    "sweep_section",
    "scenario_setup",
    "promises_section",
    "JITTER_FRACTIONS",
    "LOSS_PROBABILITIES",
    "scenario_sections",
    "paper_sections",
    "highlights",
    "write_report",
]
