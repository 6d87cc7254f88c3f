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
"""

from __future__ import annotations

import base64
import csv
import html
import json
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from delayform.errors import NoStableDelaysError, ScenarioError
from delayform.scenario import Scenario

__all__ = [
    "Figure",
    "Section",
    "jsonable",
    "factors_section",
    "chart_section",
    "roots_section",
    "map_section",
    "schedule_section",
    "simulation_section",
    "CSV_AUTO_LIMIT",
    "settling_section",
    "region_section",
    "safe_delays_section",
    "scenario_sections",
    "paper_sections",
    "highlights",
    "write_report",
]

#: Called with a short description before each step of a long computation.
Progress = Callable[[str], None]

#: Called with (grid points done, grid points in all) while a map is computed.
MapProgress = Callable[[int, int], None]


@dataclass(frozen=True)
class Figure:
    """A figure written as ``<stem>.png`` and ``<stem>.svg`` (or an animation ``<stem>.gif``), with its caption."""

    stem: str
    title: str
    text: str
    animated: bool = False


@dataclass(frozen=True)
class Section:
    """One analysis as the report shows it.

    Attributes
    ----------
    key
        Short identifier, the key of this section in ``summary.json``.
    title, text
        Heading and a paragraph saying what was computed.
    figures
        Figures written into the output directory.
    table
        Rows ``(quantity, value)`` shown as the table of numbers.
    summary
        JSON-ready numbers (what ``--json`` prints).
    files
        Every file written, relative to the output directory.
    """

    key: str
    title: str
    text: str
    figures: tuple[Figure, ...] = ()
    table: tuple[tuple[str, str], ...] = ()
    summary: Mapping[str, Any] = field(default_factory=dict)
    files: tuple[str, ...] = ()


# ------------------------------------------------------------------ helpers
def jsonable(value: Any) -> Any:
    """``value`` with NumPy scalars and arrays, complex numbers and tuples made JSON-ready.

    Complex numbers become ``{"re": ..., "im": ...}``; non-finite floats
    become ``None`` (JSON has no infinity).

    >>> jsonable({"s": 1 - 2j, "v": np.arange(2)})
    {'s': {'re': 1.0, 'im': -2.0}, 'v': [0, 1]}
    """
    if isinstance(value, Mapping):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (complex, np.complexfloating)):
        return {"re": jsonable(float(value.real)), "im": jsonable(float(value.imag))}
    if isinstance(value, (float, np.floating)):
        return float(value) if np.isfinite(value) else None
    return value


def _fmt(value: float, digits: int = 4) -> str:
    if value is None or not np.isfinite(value):
        return "n/a"
    return f"{value:.{digits}g}"


def _fmt_complex(value: complex) -> str:
    from delayform.characteristic import format_number

    # a real root polished in complex arithmetic keeps an imaginary part of rounding size
    return format_number(value, digits=5)


def _save(fig: Any, out: Path, stem: str) -> tuple[str, str]:
    """Write ``fig`` as PNG and SVG and close it; return the two file names."""
    import matplotlib.pyplot as plt

    from delayform.plots import save_figure

    paths = save_figure(fig, out / stem, formats=("png", "svg"), dpi=110)
    plt.close(fig)
    return paths[0].name, paths[1].name


def _pyplot() -> Any:
    """pyplot on the Agg backend (reports are written, never shown)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _write_csv(path: Path, header: Sequence[str], rows: Iterable[Sequence[Any]]) -> str:
    with path.open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(header)
        writer.writerows(rows)
    return path.name


def _step(progress: Progress | None, text: str) -> None:
    if progress is not None:
        progress(text)


# ------------------------------------------------------------ the sections
def factors_section(scenario: Scenario, out: Path) -> Section:
    """Eigenvalues of C and the factors of the characteristic equation (Lemma 1).

    Parameters
    ----------
    scenario
        The validated scenario (topology, gains, delays, windows).
    out
        Folder the section writes its files into.
    """
    from delayform.characteristic import factors

    team = scenario.topology
    fs = factors(team, scenario.P, scenario.D)
    rows = [
        (i, f.lam.real, f.lam.imag, f.order, f.multiplicity, f.is_centroid, f.quasi_polynomial.describe())
        for i, f in enumerate(fs, start=1)
    ]
    name = _write_csv(
        out / "factors.csv",
        ("factor", "lam_re", "lam_im", "order", "multiplicity", "centroid", "quasi_polynomial"),
        rows,
    )
    eig = team.eigenvalues
    summary = {
        "agents": team.n,
        "eigenvalues": [complex(v) for v in eig],
        "factors": [
            {"lam": complex(f.lam), "order": f.order, "multiplicity": f.multiplicity,
             "centroid": f.is_centroid, "description": f.describe()}
            for f in fs
        ],
    }  # fmt: skip
    shown = ", ".join(_fmt_complex(v) if abs(v.imag) > 1e-12 else f"{v.real:.4g}" for v in eig[:12])
    table = [("agents", str(team.n)), ("eigenvalues of C", shown + (" ..." if eig.size > 12 else ""))]
    table += [(f"factor q{i}", f.describe()) for i, f in enumerate(fs, start=1)][:20]
    return Section(
        key="factors",
        title="Eigenvalues of C and the factors of the characteristic equation",
        text=(
            f"C = Delta^-1 A of the topology {scenario.topology_spec.describe()} has {eig.size} eigenvalues; "
            f"each real one gives a second-order factor and each complex pair a fourth-order factor "
            f"(eq. factorized). The factor of lam = 1 is the centroid factor with its root s = 0 at "
            f"every delay; the others are the disagreement dynamics. Gains P = {scenario.P:g}, D = {scenario.D:g}."
        ),
        table=tuple(table),
        summary=summary,
        files=(name,),
    )


def _chart_points(scenario: Scenario) -> tuple[tuple[str, float, float], ...]:
    """The scenario's marked points with its actual operating delays labelled "operating".

    A point the file labels "operating" is replaced by the delays in use (the
    command line may have changed them); the operating pair is added unless a
    marked point already sits there.
    """
    op = (scenario.tau1, scenario.tau2)
    points = tuple(p for p in scenario.chart.points if p[0] != "operating")
    if not any((a, b) == op for _, a, b in points):
        points = (("operating", *op), *points)
    return points


def chart_section(scenario: Scenario, out: Path) -> Section:
    """The exact CTCR stability map over the chart window, its figure, curves and the marked points.

    Parameters
    ----------
    scenario
        The validated scenario (topology, gains, delays, windows).
    out
        Folder the section writes its files into.
    """
    from delayform.analysis.ctcr import stability_map

    plt = _pyplot()
    points = _chart_points(scenario)
    # the window grows to hold the operating point, so it is always classified
    cs = replace(
        scenario.chart,
        tau1_max=max([scenario.chart.tau1_max] + [a for _, a, _ in points]),
        tau2_max=max([scenario.chart.tau2_max] + [b for _, _, b in points]),
    )
    smap = stability_map(scenario.topology, scenario.P, scenario.D, cs.tau1_max, cs.tau2_max)
    t1 = np.array([p[1] for p in points])
    t2 = np.array([p[2] for p in points])
    counts = np.asarray(smap.unstable_count(t1, t2))
    stable = np.asarray(smap.is_stable(t1, t2))
    fig, ax = plt.subplots(figsize=(6.4, 5.6))
    smap.plot(ax=ax, points={label: (a, b) for label, a, b in points})
    ax.set_title(f"Stability chart: {scenario.name}, P = {scenario.P:g}, D = {scenario.D:g}")
    files = list(_save(fig, out, "stability_chart"))
    curve_rows, arrays = _curve_rows(smap)
    files.append(_write_csv(out / "ctcr_curves.csv", ("curve", "source", "kind", "tau1", "tau2", "omega"), curve_rows))
    np.savez_compressed(out / "ctcr_curves.npz", **arrays)
    files.append("ctcr_curves.npz")
    fraction = float(smap.stable_fraction())
    summary = {
        "window": [cs.tau1_max, cs.tau2_max],
        "curves": len(smap.curves),
        "kernel_curves": len(smap.kernel_curves),
        "delay_free_unstable_roots": int(smap.delay_free_count),
        "stable_fraction": fraction,
        "points": [
            {"label": label, "tau1": a, "tau2": b, "unstable_roots": int(n), "stable": bool(s)}
            for (label, a, b), n, s in zip(points, counts, stable, strict=True)
        ],
    }
    table = [("window", f"[0, {cs.tau1_max:g}] x [0, {cs.tau2_max:g}] s"),
             ("crossing curves", str(len(smap.curves))),
             ("stable fraction of the window", f"{fraction:.3f}")]  # fmt: skip
    table += [
        (f"point {label} ({a:g}, {b:g})", f"{'stable' if s else 'unstable'}, NU = {int(n)}")
        for (label, a, b), n, s in zip(points, counts, stable, strict=True)
    ]
    return Section(
        key="chart",
        title="Stability chart in the delay plane (CTCR)",
        text=(
            "Kernel and offspring curves of every factor are the delay pairs with an imaginary root; "
            "crossing one changes the number of unstable roots NU by twice its root tendency. "
            "The shaded region, NU = 0, is exactly the set of delays that give convergence to the formation."
        ),
        figures=(
            Figure("stability_chart", "Stability chart",
                   "Kernel curves (red), offspring curves (blue) and the stable region (shaded) "
                   f"in [0, {cs.tau1_max:g}] x [0, {cs.tau2_max:g}] s, with the marked delay points."),
        ),  # fmt: skip
        table=tuple(table),
        summary=summary,
        files=tuple(files),
    )


def _curve_rows(smap: Any) -> tuple[list[tuple[Any, ...]], dict[str, np.ndarray]]:
    """Curve points as CSV rows and as flat arrays for NPZ (one row per point)."""
    rows: list[tuple[Any, ...]] = []
    for index, curve in enumerate(smap.curves):
        tau1 = np.asarray(curve.tau1, dtype=float)
        tau2 = np.asarray(curve.tau2, dtype=float)
        omega = np.asarray(curve.omega, dtype=float)
        rows.extend((index, curve.source, curve.kind, a, b, w) for a, b, w in zip(tau1, tau2, omega, strict=True))
    arr = np.array([r[3:] for r in rows], dtype=float).reshape(-1, 3)
    return rows, {
        "curve": np.array([r[0] for r in rows], dtype=np.int64),
        "kernel": np.array([r[2] == "kernel" for r in rows], dtype=bool),
        "tau1": arr[:, 0],
        "tau2": arr[:, 1],
        "omega": arr[:, 2],
    }


def roots_section(
    scenario: Scenario, out: Path, *, region: tuple[float, float, float, float] | None = None
) -> Section:
    """Dominant root at the operating delays, at the chart points, and each factor's roots in a region.

    Parameters
    ----------
    scenario
        The validated scenario (topology, gains, delays, windows).
    out
        Folder the section writes its files into.
    region
        Rectangle (re_min, re_max, im_min, im_max) for the roots table; by default one
        reaching twice as far left as the dominant root.
    """
    from delayform.characteristic import factors
    from delayform.analysis.spectrum import dominant_root, roots_in

    team, P, D = scenario.topology, scenario.P, scenario.D
    dom = dominant_root(team, P, D, scenario.tau1, scenario.tau2)
    s_dom = complex(dom.root)
    # Im from just below 0, so real roots lie inside and not on the boundary
    region = region or (min(-2.0, 2.0 * s_dom.real), 1.0, -0.01, 10.0)
    rows = []
    for i, f in enumerate(factors(team, P, D), start=1):
        for s in np.atleast_1d(roots_in(f, scenario.tau1, scenario.tau2, region)):
            rows.append((i, complex(f.lam).real, complex(f.lam).imag, float(s.real), float(s.imag)))
    files = [_write_csv(out / "roots.csv", ("factor", "lam_re", "lam_im", "re", "im"), rows)]
    at_points = []
    for label, a, b in _chart_points(scenario):
        d = dominant_root(team, P, D, a, b)
        at_points.append({"label": label, "tau1": a, "tau2": b, "root": complex(d.root),
                          "time_constant": _time_constant(complex(d.root))})  # fmt: skip
    formation_root = complex(dom.formation_root if dom.formation_root is not None else s_dom)
    summary = {
        "tau1": scenario.tau1,
        "tau2": scenario.tau2,
        "dominant_root": s_dom,
        "stable": bool(dom.is_stable),
        "time_constant": _time_constant(s_dom),
        "growth_rate": float(dom.growth_rate),
        "dominant_is_centroid": bool(dom.is_centroid_drift),
        "formation_root": formation_root,
        "formation_time_constant": _time_constant(formation_root),
        "centroid_root": None if dom.centroid_root is None else complex(dom.centroid_root),
        "centroid_time_constant": dom.centroid_time_constant,
        "centroid_drifts": bool(dom.is_drift),
        "region": list(region),
        "roots_in_region": [{"factor": r[0], "root": complex(r[3], r[4])} for r in rows],
        "points": at_points,
    }
    table = [(f"dominant root at ({scenario.tau1:g}, {scenario.tau2:g})", _fmt_complex(s_dom))]
    if not dom.is_stable:
        table.append(("growth rate Re (unstable)", f"{_fmt(dom.growth_rate)} 1/s"))
    elif dom.is_centroid_drift:  # the slowest mode is the centroid's speed, not the shape
        centroid = (("centroid", "drifts at constant speed (the second root s = 0 on tau1 = 0)") if dom.is_drift
                    else ("centroid time constant", f"{_fmt(_time_constant(s_dom))} s (the centroid's speed settles)"))
        table += [
            centroid,
            ("formation time constant", f"{_fmt(_time_constant(formation_root))} s (the shape settles, root "
                                        f"{_fmt_complex(formation_root)})"),
        ]  # fmt: skip
    else:
        table.append(("time constant 1/|Re|", f"{_fmt(_time_constant(s_dom))} s"))
    table += [
        (f"roots in Re [{region[0]:g}, {region[1]:g}], Im [{region[2]:g}, {region[3]:g}]", str(len(rows))),
    ]
    table += [(f"dominant root at {p['label']} ({p['tau1']:g}, {p['tau2']:g})", _fmt_complex(p["root"]))
              for p in at_points]  # fmt: skip
    return Section(
        key="roots",
        title="Characteristic roots and the dominant root",
        text=(
            "The dominant root is the rightmost characteristic root over all factors, the centroid "
            "factor's roots at s = 0 excluded (the team's freedom to sit anywhere and, on tau1 = 0, to drift "
            "at constant speed: neither changes the shape). Its real part sets how fast the team settles "
            "(time constant 1/|Re|); when it is the centroid's, the shape's own time constant is given too. "
            "A positive real part means the delays are unstable."
        ),
        table=tuple(table),
        summary=summary,
        files=tuple(files),
    )


def _time_constant(s: complex) -> float:
    return float(1.0 / abs(s.real)) if s.real < 0 else float("inf")


def map_section(scenario: Scenario, out: Path, *, progress: MapProgress | None = None) -> Section:
    """Real part of the dominant root over the map grid: surface, contour, NPZ and CSV.

    Parameters
    ----------
    scenario
        The validated scenario (topology, gains, delays, windows).
    out
        Folder the section writes its files into.
    progress
        Optional callback ``progress(done, total)`` passed to
        :func:`~delayform.analysis.spectrum.dominant_root_map` (for a progress bar).
    """
    from delayform.analysis.spectrum import dominant_root_map

    plt = _pyplot()
    grid = scenario.map
    t1, t2 = grid.tau1_values(), grid.tau2_values()
    dmap = dominant_root_map(scenario.topology, scenario.P, scenario.D, t1, t2, progress=progress or False)
    re = np.asarray(dmap.real, dtype=float)
    files = []
    fig = plt.figure(figsize=(7.0, 5.6))
    ax = fig.add_subplot(projection="3d")
    dmap.plot_surface(ax=ax)
    files += _save(fig, out, "dominant_surface")
    fig, ax = plt.subplots(figsize=(6.4, 5.6))
    dmap.plot_contour(ax=ax)
    files += _save(fig, out, "dominant_contour")
    roots = np.asarray(dmap.roots, dtype=complex)
    np.savez_compressed(out / "dominant_map.npz", tau1=t1, tau2=t2, real_part=re, roots=roots)
    files.append("dominant_map.npz")
    T1, T2 = np.meshgrid(t1, t2, indexing="ij")
    files.append(_write_csv(
        out / "dominant_map.csv", ("tau1", "tau2", "re", "im"),
        zip(T1.ravel(), T2.ravel(), roots.real.ravel(), roots.imag.ravel(), strict=True),
    ))  # fmt: skip
    best = np.unravel_index(np.nanargmin(re), re.shape)
    summary = {
        "tau1": [float(t1[0]), float(t1[-1]), int(t1.size)],
        "tau2": [float(t2[0]), float(t2[-1]), int(t2.size)],
        "stable_fraction": float(np.mean(re < 0)),
        "min_real_part": float(re[best]),
        "argmin": [float(t1[best[0]]), float(t2[best[1]])],
    }
    table = (
        ("grid", f"{t1.size} x {t2.size} over [{t1[0]:g}, {t1[-1]:g}] x [{t2[0]:g}, {t2[-1]:g}] s"),
        ("fraction with Re < 0", f"{summary['stable_fraction']:.3f}"),
        ("most negative Re on the grid", f"{re[best]:.4g} at ({t1[best[0]]:g}, {t2[best[1]]:g})"),
    )
    return Section(
        key="map",
        title="Dominant root over the delay plane",
        text=(
            "The real part of the dominant root at every grid point. Where it crosses zero lies the "
            "CTCR stability boundary; its deepest valleys are the fastest delays (delay scheduling)."
        ),
        figures=(
            Figure("dominant_surface", "Dominant-root surface",
                   "Re of the dominant root as a surface over (tau1, tau2), with the plane Re = 0."),
            Figure("dominant_contour", "Dominant-root contour",
                   "Contour map of the same surface; the zero level is the stability boundary."),
        ),  # fmt: skip
        table=table,
        summary=summary,
        files=tuple(files),
    )


def schedule_section(
    scenario: Scenario,
    out: Path,
    *,
    tau_min: tuple[float, float] | None = None,
    tau_max: tuple[float, float] | None = None,
    label: str = "",
    report_failure: bool = False,
) -> Section:
    """Delay scheduling: the fastest stable delays reachable by increasing the hardware delays.

    ``tau_min`` and ``tau_max`` default to the scenario's ``[schedule]``;
    ``label`` names the hardware point (e.g. ``"c"``) in titles and file names.
    With ``report_failure``, a box without stable delays becomes a section
    saying so instead of :class:`~delayform.errors.NoStableDelaysError`.
    """
    from delayform.design.scheduling import schedule_delays

    lo = scenario.schedule.tau_min if tau_min is None else tau_min
    hi = scenario.schedule.tau_max if tau_max is None else tau_max
    suffix = f"_{label}" if label else ""
    where = f"point {label} " if label else ""
    try:
        result = schedule_delays(scenario.topology, scenario.P, scenario.D, tau_min=lo, tau_max=hi)
    except NoStableDelaysError as exc:
        if not report_failure:
            raise
        # a finding, not a failure of the report: say so in the page
        return Section(
            key=f"schedule{suffix}",
            title=f"Delay scheduling from {where}({lo[0]:g}, {lo[1]:g}) s: no stable delays",
            text=f"Delays can only be increased from the hardware's, and none of them is stable: {exc}.",
            table=(("hardware delays (tau1, tau2)", f"({lo[0]:g}, {lo[1]:g}) s"), ("result", "no stable delays")),
            summary={"tau_min": list(lo), "tau_max": list(hi), "stable_delays_found": False},
        )
    root, hardware = complex(result.root), complex(result.hardware_root)
    summary = {
        "tau_min": list(lo),
        "tau_max": list(hi),
        "stable_delays_found": True,
        "tau1": float(result.tau1),
        "tau2": float(result.tau2),
        "root": root,
        "time_constant": float(result.time_constant),
        "settling_time": float(result.settling_time),
        "hardware_root": hardware,
    }
    settling_rows = [("predicted settling time ln(50)/|Re|", f"{_fmt(float(result.settling_time))} s")]
    if result.factor.is_centroid:
        # the slowest mode is the centroid's speed: say so, and give the shape's own settling time
        from delayform.analysis.spectrum import SETTLING_FACTOR, dominant_root

        shape = complex(dominant_root(scenario.topology, scenario.P, scenario.D, result.tau1, result.tau2).formation_root)
        summary |= {"dominant_is_centroid": True, "formation_root": shape,
                    "formation_settling_time": SETTLING_FACTOR / abs(shape.real)}  # fmt: skip
        settling_rows = [
            ("predicted settling of the centroid's speed", f"{_fmt(float(result.settling_time))} s"),
            ("predicted settling of the formation's shape", f"{_fmt(SETTLING_FACTOR / abs(shape.real))} s"),
        ]
    name = f"schedule{suffix}.json"
    (out / name).write_text(json.dumps(jsonable(summary), indent=2))
    verdict = "unstable" if hardware.real > 0 else "stable"
    return Section(
        key=f"schedule{suffix}",
        title=f"Delay scheduling from {where}({lo[0]:g}, {lo[1]:g}) s: the best delays",
        text=(
            "Delays can only be increased from what the hardware gives. Within "
            f"[{lo[0]:g}, {hi[0]:g}] x [{lo[1]:g}, {hi[1]:g}] s, the delays below give the most "
            f"negative dominant root, hence the fastest convergence. At the hardware delays the team is {verdict}."
        ),
        table=(
            ("hardware delays (tau1, tau2)", f"({lo[0]:g}, {lo[1]:g}) s"),
            ("dominant root at the hardware delays", f"{_fmt_complex(hardware)} ({verdict})"),
            ("best delays (tau1, tau2)", f"({result.tau1:.4g}, {result.tau2:.4g}) s"),
            ("dominant root there", _fmt_complex(root)),
            *settling_rows,
        ),
        summary=summary,
        files=(name,),
    )


#: the CSV of a run is written by default only below this estimated size (bytes); NPZ always
CSV_AUTO_LIMIT = 20 * 2**20


def simulation_section(
    scenario: Scenario,
    out: Path,
    *,
    label: str = "operating",
    tau1: float | None = None,
    tau2: float | None = None,
    traces: bool = True,
    gif: bool = False,
    csv: bool | None = None,
    progress: MapProgress | None = None,
) -> Section:
    """Simulate the team at one delay pair: paths, x/y versus time, commands, NPZ (and CSV), optional GIF.

    Files (``<stem> = sim_<label>``): ``<stem>_traces.png/.svg`` x(t) and
    y(t); ``<stem>_xy.png/.svg`` the paths in the x-y plane (with ``traces``);
    ``<stem>.npz`` the trajectory; for robots ``<stem>_commands.png/.svg``
    and ``<stem>_commands.npz`` (v, omega, wheel speeds); the CSV versions
    ``<stem>.csv`` and ``<stem>_commands.csv`` when ``csv`` says so.

    Parameters
    ----------
    scenario
        The validated scenario (topology, gains, delays, windows, robot limits).
    out
        Folder the section writes its files into.
    label
        Name of the delay pair, used in file names (``sim_<label>_*``) and titles.
    tau1, tau2
        Delays to simulate at; the scenario's operating delays by default.
    traces
        Also draw the paths figure (paper Fig. traces), ``<stem>_xy``.
    gif
        Also write an animated GIF (slower).
    csv
        Write the CSV files: True always, False never, None (default) when
        the trajectory's CSV would be below :data:`CSV_AUTO_LIMIT`.
    progress
        Optional callback ``(steps done, steps)`` while the run is integrated.
    """
    from delayform.simulation import simulate

    plt = _pyplot()
    tau1 = scenario.tau1 if tau1 is None else tau1
    tau2 = scenario.tau2 if tau2 is None else tau2
    sim = scenario.simulation
    limits = scenario.robot if sim.model == "unicycle" else None
    traj = simulate(
        scenario.topology, scenario.P, scenario.D, tau1, tau2, scenario.desired_positions(),
        model=sim.model, limits=limits, initial_positions=scenario.initial_positions(),
        initial_headings=scenario.initial_headings(), initial_speed=scenario.initial.speed,
        seed=scenario.initial.seed, duration=sim.duration, dt=sim.dt, progress=progress,
    )  # fmt: skip
    stem = f"sim_{label}"
    files: list[str] = []
    figures = []
    n = scenario.topology.n
    fig, axes = plt.subplots(2, 1, figsize=(8.0 if n <= 20 else 7.0, 6.0), sharex=True)
    traj.plot_xy(ax=axes)
    files += _save(fig, out, f"{stem}_traces")
    figures.append(Figure(f"{stem}_traces", f"x and y versus time at {label}",
                          f"Positions (m) of the {n} agents, numbered from 1, in x (top) and y (bottom) "
                          f"at (tau1, tau2) = ({tau1:g}, {tau2:g}) s."))  # fmt: skip
    if traces:
        fig, ax = plt.subplots(figsize=(8.0, 6.0))
        traj.plot_traces(ax=ax)
        files += _save(fig, out, f"{stem}_xy")
        figures.append(Figure(f"{stem}_xy", f"Paths at {label}",
                              "Paths of the agents in the plane (m) into the formation; dots mark positions at "
                              "snapshot times with a short line along each heading; open circles the final positions."))  # fmt: skip
    write_csv = traj.csv_bytes() <= CSV_AUTO_LIMIT if csv is None else csv
    if write_csv:
        traj.to_csv(out / f"{stem}.csv")
        files.append(f"{stem}.csv")
    traj.to_npz(out / f"{stem}.npz")
    files.append(f"{stem}.npz")
    commands = traj.commands
    if commands is not None:
        fig, axes = plt.subplots(3, 1, figsize=(8.0, 7.5), sharex=True)
        commands.plot(ax=axes)
        files += _save(fig, out, f"{stem}_commands")
        reference = "the robots' limits" if commands.limited else "the iRobot Create's limits, for reference"
        figures.append(Figure(f"{stem}_commands", f"Commands of the robots at {label}",
                              f"Speed v, turn rate omega and wheel speeds each robot executes; dashed: {reference}."))  # fmt: skip
        commands.to_npz(out / f"{stem}_commands.npz")
        files.append(f"{stem}_commands.npz")
        if write_csv:
            commands.to_csv(out / f"{stem}_commands.csv")
            files.append(f"{stem}_commands.csv")
    if gif:
        traj.save_gif(out / f"{stem}.gif")
        files.append(f"{stem}.gif")
        figures.append(Figure(f"{stem}", f"The robots moving into formation at {label}",
                              "Animation of the simulated positions and headings.", animated=True))  # fmt: skip
    settling = float(traj.settling_time)
    limits_text = commands.summary() if commands is not None else None
    summary = {
        "label": label, "tau1": tau1, "tau2": tau2, "model": sim.model,
        "duration": sim.duration, "dt": sim.dt,
        "status": traj.status, "warnings": list(traj.warnings),
        "settling_time": settling,
        "initial_error": float(traj.formation_error[0]),
        "final_error": float(traj.formation_error[-1]),
        "min_distance": float(traj.min_distance),
        "final_centroid": np.asarray(traj.final_centroid),
        "robot_limits": None if limits is None else limits.describe(),
        "limits_exceeded": limits_text,
        "csv_written": bool(write_csv),
    }  # fmt: skip
    if traj.status == "settled":
        settled_text = f"{_fmt(settling)} s"
    elif traj.status == "not settled":
        settled_text = f"not within {sim.duration:g} s"
    else:
        settled_text = f"no: {traj.status}"
    table = [
        ("delays (tau1, tau2)", f"({tau1:g}, {tau2:g}) s"),
        ("model", sim.model + ("" if commands is None else (", with limits" if commands.limited else ", ideal robots"))),
        ("settling time (2 %)", settled_text),
        ("final formation error", f"{_fmt(summary['final_error'])} m"),
        ("closest approach of two agents", f"{_fmt(summary['min_distance'])} m"),
    ]
    if commands is not None:
        table.append(("beyond the limits" if commands.limited else "beyond an iRobot Create's limits", limits_text))
    table += [("warning", w) for w in traj.warnings]
    if not write_csv:
        table.append(("CSV", "not written (large run): NPZ only; use --csv to force it"))
    robots = "double-integrator agents"
    if sim.model == "unicycle":
        robots = ("differential-drive robots with actuator limits (saturated unicycle)" if limits is not None
                  else "ideal differential-drive robots (unicycle, feedback linearization eq. transform2)")  # fmt: skip
    return Section(
        key=f"simulation_{label}",
        title=f"Simulation at {label}: (tau1, tau2) = ({tau1:g}, {tau2:g}) s",
        text=(
            f"{n} {robots} "
            f"start from {'random' if scenario.initial.positions is None else 'given'} positions "
            f"(seed {scenario.initial.seed}) with speed {scenario.initial.speed:g} m/s and move into the "
            f"{scenario.formation.describe()} formation over {sim.duration:g} s (step {sim.dt:g} s)."
        ),
        figures=tuple(figures),
        table=tuple(table),
        summary=summary,
        files=tuple(files),
    )


def settling_section(sims: Sequence[Section]) -> Section:
    """A table of the settling times of the simulations run for the report.

    Parameters
    ----------
    sims
        Sections returned by :func:`simulation_section`.
    """
    rows = tuple(
        (f"{s.summary['label']} ({s.summary['tau1']:g}, {s.summary['tau2']:g})",
         f"{_fmt(s.summary['settling_time'])} s" if np.isfinite(s.summary["settling_time"]) else "did not settle")
        for s in sims
    )  # fmt: skip
    return Section(
        key="settling",
        title="Settling times",
        text="First time after which the formation error stays below 2 % of its initial value.",
        table=rows,
        summary={s.summary["label"]: s.summary["settling_time"] for s in sims},
    )


# === section: the eigenvalue plane (issue 11) ===
def region_section(scenario: Scenario, out: Path, *, tau1: float | None = None, tau2: float | None = None) -> Section:
    """The stable region of the eigenvalue plane at the scenario's delays, with the team's eigenvalues.

    Parameters
    ----------
    scenario
        The validated scenario (topology, gains, delays).
    out
        Folder the section writes its files into.
    tau1, tau2
        Delays (s); default the scenario's.
    """
    from delayform.analysis.bounds import DENSE_BOUND_LIMIT, spectrum_bound
    from delayform.analysis.certificates import safe_delays
    from delayform.analysis.region import lambda_region

    plt = _pyplot()
    t1 = scenario.tau1 if tau1 is None else tau1
    t2 = scenario.tau2 if tau2 is None else tau2
    topo = scenario.topology
    region = lambda_region(scenario.P, scenario.D, t1, t2)
    window = (max(t1, 1e-3), max(t2, 1e-3))
    certs = {name: bool(safe_delays(scenario.P, scenario.D, *window, spectrum=name).is_safe(t1, t2))
             for name in ("undirected", "any")}  # fmt: skip
    fig, ax = plt.subplots(figsize=(6.0, 6.0))
    rows: list[tuple[Any, ...]] = []
    if topo.n <= DENSE_BOUND_LIMIT:
        lam = topo.eigenvalues
        counts = region.unstable_count(lam)
        region.plot(ax=ax, topology=topo)
        rows = [(f"{z.real:.10g}", f"{z.imag:.10g}", int(n)) for z, n in zip(lam, counts, strict=True)]
        stable = bool(np.all(counts == 0))
        verdict = "stable (exact)" if stable else f"unstable, NU = {int(counts.sum())}"
        summary: dict[str, Any] = {"eigenvalues": [complex(z) for z in lam], "unstable_roots": [int(n) for n in counts]}
    else:
        bound = spectrum_bound(topo)
        region.plot(ax=ax)
        ok = bool(safe_delays(scenario.P, scenario.D, *window, spectrum=bound).is_safe(t1, t2))
        stable = ok
        verdict = "stable (sufficient test on the spectrum bound)" if ok else "not certified by the spectrum bound"
        summary = {"bound": bound.spectrum_set.label, "bound_method": bound.method}
    files = list(_save(fig, out, "lambda_region"))
    if rows:
        files.append(_write_csv(out / "eigenvalue_region.csv", ("re", "im", "unstable_roots"), rows))
    disc = region.stable_fraction_of_disc(resolution=121)
    summary.update({"tau1": t1, "tau2": t2, "team_stable": stable, "stable_fraction_of_unit_disc": disc,
                    "safe_for_every_undirected_team": certs["undirected"], "safe_for_every_team": certs["any"]})
    table = [("delays", f"({t1:g}, {t2:g}) s"), ("team", verdict),
             ("stable share of the unit disc", f"{disc:.3f}"),
             ("safe for every undirected team", "yes" if certs["undirected"] else "no"),
             ("safe for every team (unit disc)", "yes" if certs["any"] else "no")]  # fmt: skip
    return Section(
        key="region",
        title="Stable eigenvalues of C (the eigenvalue plane)",
        text=(
            "Every factor of the characteristic equation is the same quasi-polynomial with the eigenvalue lam "
            "of C as a parameter. The shaded set holds the eigenvalues whose factor is stable at these delays; "
            "its boundary is lam = L(j omega). The team is stable exactly when all its eigenvalues (the "
            "centroid 1 aside) lie in it, so a new graph can be checked by its eigenvalues alone."
        ),
        figures=(Figure("lambda_region", "Stable region of the eigenvalue plane",
                        "Shaded: stable eigenvalues; red: the boundary L(j omega); dashed: the unit disc; "
                        "dots: the team's eigenvalues (green stable, red not)."),),  # fmt: skip
        table=tuple(table),
        summary=summary,
        files=tuple(files),
    )


def safe_delays_section(
    out: Path, P: float, D: float, tau1_max: float, tau2_max: float, *, spectrum: object = "undirected",
    points: Sequence[tuple[str, float, float]] = (),
) -> Section:
    """The delays safe for every team whose spectrum lies in a set, drawn like the stability chart.

    Parameters
    ----------
    out
        Folder the section writes its files into.
    P, D
        Gains of eq. protocol.
    tau1_max, tau2_max
        The delay window.
    spectrum
        What :func:`delayform.analysis.certificates.safe_delays` accepts.
    points
        ``(label, tau1, tau2)`` delay pairs to mark and classify.
    """
    from delayform.analysis.certificates import safe_delays

    plt = _pyplot()
    m = safe_delays(P, D, tau1_max, tau2_max, spectrum=spectrum)
    fig, ax = plt.subplots(figsize=(6.4, 5.6))
    m.plot(ax=ax, points={label: (a, b) for label, a, b in points})
    files = list(_save(fig, out, "safe_delays"))
    t1, t2, safe = m.grid(200)
    np.savez_compressed(out / "safe_delays.npz", tau1=t1, tau2=t2, safe=safe)
    files.append("safe_delays.npz")
    fraction = float(safe.mean())
    marks = [(label, a, b, bool(m.is_safe(a, b))) for label, a, b in points]
    summary = {"spectrum": m.spectrum.label, "window": [tau1_max, tau2_max], "P": P, "D": D,
               "safe_fraction": fraction, "never_safe": m.never_safe,
               "points": [{"label": k, "tau1": a, "tau2": b, "safe": s} for k, a, b, s in marks]}  # fmt: skip
    table = [("spectrum set", m.spectrum.label), ("window", f"[0, {tau1_max:g}] x [0, {tau2_max:g}] s"),
             ("safe fraction of the window", f"{fraction:.3f}")]  # fmt: skip
    method = getattr(spectrum, "method", None)
    if method:  # a SpectrumBound of a team
        table.append(("how the set was bounded", str(method)))
        summary["bound_method"] = str(method)
    if m.never_safe:
        table.append(("why none", m.never_safe))
    table += [(f"point {k} ({a:g}, {b:g})", "safe" if s else "not certified") for k, a, b, s in marks]
    return Section(
        key="safe_delays",
        title="Delays safe for a whole class of teams",
        text=(
            "Shaded: delay pairs at which every team whose eigenvalues of C lie in the set is stable, whatever "
            "its size or graph (a certified test; a sufficient condition for any one team). Red/blue: the exact "
            "CTCR curves of the factors at the ends of the set; black: the envelope of the interior factors."
        ),
        figures=(Figure("safe_delays", "Safe delays", f"Safe for every team with spectrum in {m.spectrum.label}."),),
        table=tuple(table),
        summary=summary,
        files=tuple(files),
    )


# ------------------------------------------------------------ whole reports
def scenario_sections(
    scenario: Scenario, out: Path, *, progress: Progress | None = None, map_progress: MapProgress | None = None
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
    """
    steps: list[tuple[str, Callable[[], Section]]] = [
        ("factors", lambda: factors_section(scenario, out)),
        ("stability chart", lambda: chart_section(scenario, out)),
        ("eigenvalue plane", lambda: region_section(scenario, out)),
        ("roots", lambda: roots_section(scenario, out)),
        ("dominant-root map", lambda: map_section(scenario, out, progress=map_progress)),
        ("delay scheduling", lambda: schedule_section(scenario, out, report_failure=True)),
        ("simulation", lambda: simulation_section(scenario, out)),
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
    if "region" in by_key:
        reg = by_key["region"]
        rows.append((f"safe at ({reg['tau1']:g}, {reg['tau2']:g}) for every undirected team",
                     "yes" if reg["safe_for_every_undirected_team"] else "no"))  # fmt: skip
    if "roots" in by_key:
        roots = by_key["roots"]
        rows.append((f"dominant root at ({roots['tau1']:g}, {roots['tau2']:g})", _fmt_complex(roots["dominant_root"])))
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
    index.write_text("\n".join(parts), encoding="utf-8")
    summary = {
        "title": title,
        "scenario": scenario.summary(),
        "seconds": seconds,
        "sections": {s.key: s.summary for s in sections},
        "files": sorted({f for s in sections for f in s.files} | {"index.html", "summary.json"}),
    }
    (out / "summary.json").write_text(json.dumps(jsonable(summary), indent=2), encoding="utf-8")
    return index
