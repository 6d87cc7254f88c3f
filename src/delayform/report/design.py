"""Report sections of design: delay scheduling, gain design, and gains versus scheduling side by side."""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from delayform._files import save_npz, write_text
from delayform.errors import NoStableDelaysError, NoStableGainsError
from delayform.scenario import Scenario
from delayform.report._common import (
    Figure,
    Section,
    _fmt,
    _fmt_complex,
    _pyplot,
    _save,
    jsonable,
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
        result = schedule_delays(scenario.topology, scenario.P, scenario.D, tau_min=lo, tau_max=hi,
                                 actuation_delay=scenario.actuation_delay)  # fmt: skip
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
        "actuation_delay": scenario.actuation_delay,
    }
    settling_rows = [("predicted settling time ln(50)/|Re|", f"{_fmt(float(result.settling_time))} s")]
    if result.factor.is_centroid:
        # the slowest mode is the centroid's speed: say so, and give the shape's own settling time
        from delayform.analysis.roots.dominant import SETTLING_FACTOR, dominant_root

        shape = complex(dominant_root(scenario.topology, scenario.P, scenario.D, result.tau1, result.tau2,
                                      actuation_delay=scenario.actuation_delay).formation_root)  # fmt: skip
        summary |= {"dominant_is_centroid": True, "formation_root": shape,
                    "formation_settling_time": SETTLING_FACTOR / abs(shape.real)}  # fmt: skip
        settling_rows = [
            ("predicted settling of the centroid's speed", f"{_fmt(float(result.settling_time))} s"),
            ("predicted settling of the formation's shape", f"{_fmt(SETTLING_FACTOR / abs(shape.real))} s"),
        ]
    name = f"schedule{suffix}.json"
    write_text(out / name, json.dumps(jsonable(summary), indent=2))
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




#: Bounds of P and D searched when none are given (the paper's scale and a margin around it).
DEFAULT_GAIN_BOUNDS = (0.05, 3.0)


def _design(scenario: Scenario, tau1: Any, tau2: Any, P_bounds: tuple[float, float],
            D_bounds: tuple[float, float], grid: int) -> Any:  # fmt: skip
    from delayform.design.gains import design_gains

    return design_gains(scenario.topology, tau1, tau2, P_bounds=P_bounds, D_bounds=D_bounds, grid=grid)


def gains_section(
    scenario: Scenario,
    out: Path,
    *,
    tau1: float | tuple[float, float] | None = None,
    tau2: float | tuple[float, float] | None = None,
    P_bounds: tuple[float, float] = DEFAULT_GAIN_BOUNDS,
    D_bounds: tuple[float, float] = DEFAULT_GAIN_BOUNDS,
    grid: int = 21,
    label: str = "",
) -> Section:
    """Gain design at the scenario's delays (or a box of them): gains, root, settling, the gain plane.

    Parameters
    ----------
    scenario
        The validated scenario (topology, gains, delays).
    out
        Folder the section writes its files into.
    tau1, tau2
        Delays or intervals (lo, hi); the scenario's operating delays by default.
    P_bounds, D_bounds
        Intervals searched for P and D.
    grid
        Points per axis of the coarse gain-plane map.
    label
        Names the delays in titles and file names (e.g. ``"c"``).
    """
    from delayform.analysis.roots.dominant import dominant_root

    plt = _pyplot()
    tau1 = scenario.tau1 if tau1 is None else tau1
    tau2 = scenario.tau2 if tau2 is None else tau2
    suffix = f"_{label}" if label else ""
    result = _design(scenario, tau1, tau2, P_bounds, D_bounds, grid)
    robust = result.is_robust
    where = (f"tau1 in [{result.tau1_box[0]:g}, {result.tau1_box[1]:g}], "
             f"tau2 in [{result.tau2_box[0]:g}, {result.tau2_box[1]:g}] s") if robust else (
             f"(tau1, tau2) = ({result.tau1:g}, {result.tau2:g}) s")  # fmt: skip
    current = dominant_root(scenario.topology, scenario.P, scenario.D, result.tau1, result.tau2)
    fig, ax = plt.subplots(figsize=(6.6, 5.6))
    result.plot(ax=ax, points={"scenario": (scenario.P, scenario.D)})
    files = list(_save(fig, out, f"gain_plane{suffix}"))
    gm = result.gain_map
    save_npz(out / f"gain_plane{suffix}.npz", P=gm.P_values, D=gm.D_values,
                        abscissa=gm.abscissa, roots=gm.roots, delays=gm.delays)  # fmt: skip
    files.append(f"gain_plane{suffix}.npz")
    summary = {
        "robust": robust,
        "tau1": list(result.tau1_box) if robust else result.tau1,
        "tau2": list(result.tau2_box) if robust else result.tau2,
        "P_bounds": list(result.P_bounds),
        "D_bounds": list(result.D_bounds),
        "P": result.P,
        "D": result.D,
        "abscissa": result.abscissa,
        "root": complex(result.root),
        "root_delays": [result.tau1, result.tau2],
        "decay_rate": result.decay_rate,
        "settling_time": result.settling_time,
        "certificate": result.certificate,
        "scenario_gains": [scenario.P, scenario.D],
        "scenario_root": complex(current.root),
        "stable_fraction_of_gain_grid": float(np.mean(gm.stable)),
    }
    name = f"gains{suffix}.json"
    write_text(out / name, json.dumps(jsonable(summary), indent=2))
    files.append(name)
    worst = "worst case over the box" if robust else "dominant root"
    table = (
        ("delays", where),
        ("bounds", f"P in [{result.P_bounds[0]:g}, {result.P_bounds[1]:g}], D in [{result.D_bounds[0]:g}, {result.D_bounds[1]:g}]"),
        ("designed gains (P, D)", f"({result.P:.4g}, {result.D:.4g})"),
        (worst, f"{_fmt_complex(complex(result.root))}" + (f" at ({result.tau1:.3g}, {result.tau2:.3g}) s" if robust else "")),
        ("decay rate -Re", f"{_fmt(result.decay_rate)} 1/s"),
        ("predicted settling time ln(50)/|Re|", _predicted(result.settling_time)),
        (f"scenario gains ({scenario.P:g}, {scenario.D:g}): dominant root at ({result.tau1:.3g}, {result.tau2:.3g})",
         f"{_fmt_complex(complex(current.root))} ({'stable' if current.is_stable else 'unstable'})"),
        ("certificate", result.certificate),
    )  # fmt: skip
    return Section(
        key=f"gains{suffix}",
        title=f"Gain design {'over the delay box ' if robust else 'at '}{where}",
        text=(
            "The gains inside the bounds that minimise the spectral abscissa (the real part of the dominant root, "
            "the centroid's persistent zero excluded)"
            + (", in the worst case over the delay box" if robust else "")
            + ": a certified map of the gain plane, gradient sampling from its best local minima, and a "
            "certified final root."
        ),
        figures=(
            Figure(f"gain_plane{suffix}", "The gain plane",
                   "Re of the dominant root over (P, D)" + (" (worst of the sampled delay pairs)" if robust else "")
                   + "; black: Re = 0, the edge of the stable region; star: the designed gains; "
                   "dot: the scenario's gains."),
        ),  # fmt: skip
        table=table,
        summary=summary,
        files=tuple(files),
    )


def _settling(scenario: Scenario, P: float, D: float, tau1: float, tau2: float, duration: float) -> float:
    """Simulated 2 % settling time of double-integrator agents (inf when not settled in ``duration``)."""
    from delayform.simulation import simulate

    sim = scenario.simulation
    traj = simulate(
        scenario.topology, P, D, tau1, tau2, scenario.desired_positions(), model="double_integrator",
        initial_positions=scenario.initial_positions(), initial_headings=scenario.initial_headings(),
        initial_speed=scenario.initial.speed, seed=scenario.initial.seed, duration=duration, dt=sim.dt,
    )  # fmt: skip
    return float(traj.settling_time)


def _predicted(t: float) -> str:
    return f"{_fmt(t)} s" if np.isfinite(t) else "none (unstable)"


def gain_comparison_section(
    scenario: Scenario,
    out: Path,
    points: Mapping[str, tuple[float, float]],
    *,
    P_bounds: tuple[float, float] = DEFAULT_GAIN_BOUNDS,
    D_bounds: tuple[float, float] = DEFAULT_GAIN_BOUNDS,
    grid: int = 21,
    duration: float | None = None,
) -> Section:
    """The scenario's gains, delay scheduling and gain design side by side at labelled delay pairs.

    For each pair: the dominant root with the scenario's gains; the delays
    delay scheduling picks from there (up to the chart window) with those
    gains; the gains gain design picks at the pair itself. Each with its
    certified dominant root, predicted settling time and the settling time of
    a simulation of double-integrator agents (fast; the formation forcing and
    initial state of the scenario).

    Parameters
    ----------
    scenario
        The validated scenario.
    out
        Folder the section writes its files into.
    points
        Label -> (tau1, tau2), e.g. the paper's points a, b, c.
    P_bounds, D_bounds
        Intervals searched by gain design.
    grid
        Points per axis of gain design's coarse map.
    duration
        Simulated time (s); the scenario's by default.
    """
    from delayform.analysis.roots.dominant import SETTLING_FACTOR, dominant_root
    from delayform.design.scheduling import schedule_delays

    plt = _pyplot()
    duration = scenario.simulation.duration if duration is None else duration
    window = (scenario.chart.tau1_max, scenario.chart.tau2_max)
    rows: list[dict[str, Any]] = []

    def entry(method: str, label: str, P: float, D: float, t1: float, t2: float, root: complex) -> dict[str, Any]:
        predicted = SETTLING_FACTOR / -root.real if root.real < 0 else math.inf
        return {"point": label, "method": method, "P": P, "D": D, "tau1": t1, "tau2": t2, "root": root,
                "predicted_settling": predicted,
                "simulated_settling": _settling(scenario, P, D, t1, t2, duration)}  # fmt: skip

    for label, (t1, t2) in points.items():
        dom = dominant_root(scenario.topology, scenario.P, scenario.D, t1, t2)
        rows.append(entry("scenario gains", label, scenario.P, scenario.D, t1, t2, complex(dom.root)))
        try:
            s = schedule_delays(scenario.topology, scenario.P, scenario.D, tau_min=(t1, t2), tau_max=window)
            rows.append(entry("delay scheduling", label, scenario.P, scenario.D, s.tau1, s.tau2, complex(s.root)))
        except NoStableDelaysError:
            rows.append({"point": label, "method": "delay scheduling", "found": False})
        try:
            g = _design(scenario, t1, t2, P_bounds, D_bounds, grid)
            rows.append(entry("gain design", label, g.P, g.D, t1, t2, complex(g.root)))
        except NoStableGainsError:
            rows.append({"point": label, "method": "gain design", "found": False})
    name = "gain_comparison.json"
    write_text(out / name, json.dumps(jsonable(rows), indent=2))
    files = [name]
    fig, ax = plt.subplots(figsize=(7.0, 4.4))
    methods = ("scenario gains", "delay scheduling", "gain design")
    labels = list(points)
    width = 0.26
    for k, method in enumerate(methods):
        vals = [next((r.get("simulated_settling", math.inf) for r in rows
                      if r["point"] == lab and r["method"] == method), math.inf) for lab in labels]  # fmt: skip
        shown = [v if np.isfinite(v) else 0.0 for v in vals]
        bars = ax.bar(np.arange(len(labels)) + (k - 1) * width, shown, width, label=method)
        for bar, v in zip(bars, vals, strict=True):
            if not np.isfinite(v):
                ax.annotate("no settling", (bar.get_x() + bar.get_width() / 2, 0), ha="center", va="bottom",
                            rotation=90, fontsize="small")
    ax.set_xticks(np.arange(len(labels)), [f"{lab} {points[lab]}" for lab in labels])
    ax.set_ylabel("simulated 2 % settling time (s)")
    ax.set_title(f"Settling times, {scenario.topology.n} double integrators")
    ax.legend(fontsize="small")
    files += _save(fig, out, "gain_comparison")
    table = []
    for r in rows:
        key = f"{r['point']}: {r['method']}"
        if not r.get("found", True):
            table.append((key, "nothing stable found"))
            continue
        sim = r["simulated_settling"]
        table.append((key, f"P = {r['P']:.3g}, D = {r['D']:.3g}, (tau1, tau2) = ({r['tau1']:.3g}, {r['tau2']:.3g}) s; "
                           f"root {_fmt_complex(r['root'])}; predicted settling {_predicted(r['predicted_settling'])}; "
                           f"simulated {_fmt(sim) + ' s' if np.isfinite(sim) else f'not within {duration:g} s'}"))  # fmt: skip
    return Section(
        key="gain_comparison",
        title="Which knob: the given gains, delay scheduling or gain design",
        text=(
            "At each delay pair: the team with the scenario's gains; delay scheduling (the same gains, delays "
            "increased up to the chart window, which is all the paper's method may do); and gain design (new gains "
            "within the bounds, no added delay). Roots are certified; settling times are from simulations of "
            "double-integrator agents with the scenario's formation and initial state."
        ),
        figures=(Figure("gain_comparison", "Settling times by method",
                        "Simulated 2 % settling time at each delay pair for each method; "
                        "'no settling' marks runs that did not settle."),),  # fmt: skip
        table=tuple(table),
        summary={"rows": rows, "P_bounds": list(P_bounds), "D_bounds": list(D_bounds), "duration": duration},
        files=tuple(files),
    )
