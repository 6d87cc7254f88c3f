"""Report sections of the analyses: factors, stability chart, roots, dominant-root map, eigenvalue plane, safe delays."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from delayform._files import save_npz
from delayform.scenario import Scenario
from delayform.report._common import (
    Figure,
    MapProgress,
    Section,
    _fmt,
    _fmt_complex,
    _pyplot,
    _save,
    _write_csv,
)


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
            f"(paper, eq. 3). The factor of lam = 1 is the centroid factor with its root s = 0 at "
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


def chart_section(scenario: Scenario, out: Path, *, jitter_grid: int = 0) -> Section:
    """The exact CTCR stability map over the chart window, its figure, curves and the marked points.

    Parameters
    ----------
    scenario
        The validated scenario (topology, gains, delays, windows).
    out
        Folder the section writes its files into.
    jitter_grid
        Above 0: contour lines of the certified jitter margin on a grid of this
        many points per axis are drawn over the stable region
        (:mod:`delayform.report.jitter_overlay`); refused up front beyond the budget.
    """
    from delayform.analysis.ctcr.stability_map import stability_map
    from delayform.report.jitter_overlay import check_overlay, draw_overlay, jitter_overlay

    plt = _pyplot()
    points = _chart_points(scenario)
    # the window grows to hold the operating point, so it is always classified
    cs = replace(
        scenario.chart,
        tau1_max=max([scenario.chart.tau1_max] + [a for _, a, _ in points]),
        tau2_max=max([scenario.chart.tau2_max] + [b for _, _, b in points]),
    )
    if jitter_grid:
        check_overlay(scenario, cs.tau1_max, cs.tau2_max, jitter_grid)
    smap = stability_map(scenario.topology, scenario.P, scenario.D, cs.tau1_max, cs.tau2_max,
                         actuation_delay=scenario.actuation_delay)  # fmt: skip
    jmap = jitter_overlay(scenario, cs.tau1_max, cs.tau2_max, jitter_grid) if jitter_grid else None
    t1 = np.array([p[1] for p in points])
    t2 = np.array([p[2] for p in points])
    counts = np.asarray(smap.unstable_count(t1, t2))
    stable = np.asarray(smap.is_stable(t1, t2))
    fig, ax = plt.subplots(figsize=(6.4, 5.6))
    smap.plot(ax=ax, points={label: (a, b) for label, a, b in points})
    jitter_summary, jitter_rows = draw_overlay(jmap, ax) if jmap is not None else (None, [])
    ax.set_title(f"Stability chart: {scenario.name}, P = {scenario.P:g}, D = {scenario.D:g}")
    out.mkdir(parents=True, exist_ok=True)  # the command line leaves the folder to the first write
    files = list(_save(fig, out, "stability_chart"))
    curve_rows, arrays = _curve_rows(smap)
    files.append(_write_csv(out / "ctcr_curves.csv", ("curve", "source", "kind", "tau1", "tau2", "omega"), curve_rows))
    save_npz(out / "ctcr_curves.npz", **arrays)
    files.append("ctcr_curves.npz")
    fraction = float(smap.stable_fraction())
    summary = {
        "window": [cs.tau1_max, cs.tau2_max],
        "actuation_delay": scenario.actuation_delay,
        "curves": len(smap.curves),
        "kernel_curves": len(smap.kernel_curves),
        "delay_free_unstable_roots": int(smap.delay_free_count),
        "stable_fraction": fraction,
        "points": [
            {"label": label, "tau1": a, "tau2": b, "unstable_roots": int(n), "stable": bool(s)}
            for (label, a, b), n, s in zip(points, counts, stable, strict=True)
        ],
    }
    if jmap is not None:
        summary["jitter_margin"] = jitter_summary
        save_npz(out / "jitter_margin_map.npz", tau1=jmap.tau1_values, tau2=jmap.tau2_values, delta=jmap.delta)
        files.append("jitter_margin_map.npz")
    table = [("window", f"[0, {cs.tau1_max:g}] x [0, {cs.tau2_max:g}] s"),
             ("crossing curves", str(len(smap.curves))),
             ("stable fraction of the window", f"{fraction:.3f}")]  # fmt: skip
    table += [
        (f"point {label} ({a:g}, {b:g})", f"{'stable' if s else 'unstable'}, NU = {int(n)}")
        for (label, a, b), n, s in zip(points, counts, stable, strict=True)
    ] + jitter_rows
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
                   f"in [0, {cs.tau1_max:g}] x [0, {cs.tau2_max:g}] s, with the marked delay points"
                   + ("; contour lines: the certified jitter margin delta (s), the time-varying delays "
                      "within +-delta that keep the team stable however fast they vary." if jmap is not None else ".")),
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
    scenario: Scenario, out: Path, *, region: tuple[float, float, float, float] | None = None,
    progress: MapProgress | None = None,
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
    progress
        Optional callback ``progress(done, total)`` over the factors whose roots are
        listed (:func:`~delayform.analysis.roots.team_roots.factor_roots_in`; for a progress bar).
    """
    from delayform.analysis.roots.team_roots import factor_roots_in
    from delayform.analysis.roots.dominant import dominant_root

    team, P, D = scenario.topology, scenario.P, scenario.D
    ta = scenario.actuation_delay  # [robot] actuation_delay: every factor with its delayed own-state terms
    dom = dominant_root(team, P, D, scenario.tau1, scenario.tau2, actuation_delay=ta)
    s_dom = complex(dom.root)
    # Im from just below 0, so real roots lie inside and not on the boundary
    region = region or (min(-2.0, 2.0 * s_dom.real), 1.0, -0.01, 10.0)
    # one batched solve for all factors (a rectangle too far out is refused before it starts)
    per_factor = factor_roots_in(team, P, D, scenario.tau1, scenario.tau2, region, progress=progress,
                                 actuation_delay=ta)  # fmt: skip
    rows = [(i, complex(f.lam).real, complex(f.lam).imag, float(s.real), float(s.imag))
            for i, (f, roots) in enumerate(per_factor, start=1) for s in roots]  # fmt: skip
    files = [_write_csv(out / "roots.csv", ("factor", "lam_re", "lam_im", "re", "im"), rows)]
    at_points = []
    for label, a, b in _chart_points(scenario):
        d = dominant_root(team, P, D, a, b, actuation_delay=ta)
        at_points.append({"label": label, "tau1": a, "tau2": b, "root": complex(d.root),
                          "time_constant": _time_constant(complex(d.root))})  # fmt: skip
    formation_root = complex(dom.formation_root if dom.formation_root is not None else s_dom)
    summary = {
        "tau1": scenario.tau1,
        "tau2": scenario.tau2,
        "actuation_delay": ta,
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


# === section: the eigenvalue plane ===
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
    from delayform.analysis.plane.spectrum_bounds import DENSE_BOUND_LIMIT, spectrum_bound
    from delayform.analysis.plane.spectrum_sets import safe_delays
    from delayform.analysis.plane.region import lambda_region

    t1 = scenario.tau1 if tau1 is None else tau1
    t2 = scenario.tau2 if tau2 is None else tau2
    if scenario.actuation_delay > 0.0:  # no number for another system: the page says why there is none
        return Section(
            key="region", title="Eigenvalue plane: not computed with an actuation delay",
            text=("The stable region of the eigenvalue plane is computed for the paper's factors; with an "
                  f"actuation delay of {scenario.actuation_delay:g} s every factor has delayed own-state terms "
                  "that it does not model. The chart, the roots and the map above take the actuation delay."),
            table=(("actuation delay tau_a", f"{scenario.actuation_delay:g} s"), ("result", "not computed")),
            summary={"actuation_delay": scenario.actuation_delay, "computed": False},
        )  # fmt: skip
    plt = _pyplot()
    topo = scenario.topology
    region = lambda_region(scenario.P, scenario.D, t1, t2)
    window = (max(t1, 1e-3), max(t2, 1e-3))
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
    # after the team's own test: its guards are cheap, the certificates' CTCR maps are not
    certs = {name: bool(safe_delays(scenario.P, scenario.D, *window, spectrum=name).is_safe(t1, t2))
             for name in ("undirected", "any")}  # fmt: skip
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
        Gains of the paper's eq. 1.
    tau1_max, tau2_max
        The delay window.
    spectrum
        What :func:`delayform.analysis.plane.spectrum_sets.safe_delays` accepts.
    points
        ``(label, tau1, tau2)`` delay pairs to mark and classify.
    """
    from delayform.analysis.plane.spectrum_sets import safe_delays

    plt = _pyplot()
    m = safe_delays(P, D, tau1_max, tau2_max, spectrum=spectrum)
    fig, ax = plt.subplots(figsize=(6.4, 5.6))
    m.plot(ax=ax, points={label: (a, b) for label, a, b in points})
    files = list(_save(fig, out, "safe_delays"))
    t1, t2, safe = m.grid(200)
    save_npz(out / "safe_delays.npz", tau1=t1, tau2=t2, safe=safe)
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
        :func:`~delayform.analysis.roots.dominant.dominant_root_map` (for a progress bar).
    """
    from delayform.analysis.roots.dominant import dominant_root_map

    plt = _pyplot()
    grid = scenario.map
    t1, t2 = grid.tau1_values(), grid.tau2_values()
    ta = scenario.actuation_delay  # [robot] actuation_delay: every factor in three delays
    dmap = dominant_root_map(scenario.topology, scenario.P, scenario.D, t1, t2, progress=progress or False,
                             actuation_delay=ta)  # fmt: skip
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
    save_npz(out / "dominant_map.npz", tau1=t1, tau2=t2, real_part=re, roots=roots)
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
        "actuation_delay": ta,
        # DominantRootMap.stable, the one meaning of stable: on tau1 = 0 the centroid's drift (Re = 0
        # exactly) is not instability, as in the chart and roots (Re < 0 alone would call that row unstable)
        "stable_fraction": float(np.mean(dmap.stable)),
        "min_real_part": float(re[best]),
        "argmin": [float(t1[best[0]]), float(t2[best[1]])],
    }
    table = (
        ("grid", f"{t1.size} x {t2.size} over [{t1[0]:g}, {t1[-1]:g}] x [{t2[0]:g}, {t2[-1]:g}] s"),
        ("stable fraction (the centroid's drift on tau1 = 0 excepted)", f"{summary['stable_fraction']:.3f}"),
        ("most negative Re on the grid", f"{re[best]:.4g} at ({t1[best[0]]:g}, {t2[best[1]]:g})"),
    ) + ((("actuation delay tau_a", f"{ta:g} s (every factor with its delayed own-state terms)"),) if ta else ())
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
