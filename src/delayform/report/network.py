"""Report sections of imperfect networks: a Monte Carlo of the scenario, and what the analysis still promises.

Split from :mod:`delayform.report` (same stage of the data flow, its
helpers). :func:`montecarlo_section` runs
:func:`~delayform.simulation.experiments.montecarlo.monte_carlo` on a scenario and its
``[network]`` table; :func:`promises_section` sets the constant-delay
prediction (dominant root, stable or not, predicted settling ``ln(50)/|Re s|``)
beside Monte Carlo runs with growing jitter and packet loss at labelled delay
pairs (the paper's points a and b by default): docs/theory.md, section
"What the analysis still promises".
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from delayform._files import save_npz
from delayform.errors import ScenarioError
from delayform.report._common import Figure, Section, _fmt, _fmt_complex, _pyplot, _save, _write_csv
from delayform.scenario import Scenario

__all__ = ["montecarlo_section", "sweep_section", "scenario_setup", "promises_section", "JITTER_FRACTIONS", "LOSS_PROBABILITIES"]

#: jitter bounds of :func:`promises_section`, as fractions of each delay
JITTER_FRACTIONS = (0.0, 0.25, 0.5, 0.75)

#: loss probabilities of :func:`promises_section`
LOSS_PROBABILITIES = (0.0, 0.3, 0.6)

#: the 2 % settling of a mode exp(Re s t) (delayform.simulation.SETTLING_FRACTION)
_LN50 = math.log(50.0)


def _setup(scenario: Scenario, *, tau1: float, tau2: float, duration: float, dt: float) -> Any:
    from delayform.simulation.experiments.montecarlo import make_setup

    # double integrators: every level, the ideal one included, then runs the same agent model
    return make_setup(
        scenario.topology, scenario.P, scenario.D, tau1, tau2, scenario.desired_positions(),
        model="double_integrator", duration=duration, dt=dt,
        initial_positions=scenario.initial_positions(), initial_headings=scenario.initial_headings(),
        initial_speed=scenario.initial.speed,
    )  # fmt: skip


def _predicted(scenario: Scenario, tau1: float, tau2: float) -> float:
    """``ln(50) / |Re s|`` of the dominant root at (tau1, tau2); inf where it does not decay."""
    from delayform.analysis.roots.dominant import dominant_root

    re = complex(dominant_root(scenario.topology, scenario.P, scenario.D, tau1, tau2).root).real
    return _LN50 / abs(re) if re < 0 else math.inf


def _delays_phrase(scenario: Scenario, net: Any) -> str:
    """The delays the runs use: the scenario's two, or the per-link ones (a matrix's range over the links, a spread)."""
    delays = None if net is None else net.delays
    if delays is None or delays.is_uniform:
        return f"at (tau1, tau2) = ({scenario.tau1:g}, {scenario.tau2:g}) s"
    links = np.asarray(scenario.topology.adjacency) != 0
    parts = []
    for name, matrix, scalar in (("tau1", delays.tau1, scenario.tau1), ("tau2", delays.tau2, scenario.tau2)):
        if matrix is None:
            around = f" (1 +- {delays.spread:g})" if delays.spread else ""
            parts.append(f"{name} = {scalar:g} s{around}")
        else:
            on = np.asarray(matrix)[links]
            parts.append(f"{name} from {on.min():g} to {on.max():g} s")
    return "with per-link delays: " + ", ".join(parts)


def montecarlo_section(
    scenario: Scenario,
    out: Path,
    *,
    runs: int = 40,
    seed: int = 0,
    network: Any = None,
    executor: Any = None,
    progress: Callable[[int, int], None] | None = None,
) -> Section:
    """Monte Carlo of the scenario over its network: quantile bands, histograms, per-run CSV.

    Parameters
    ----------
    scenario
        The validated scenario; its ``[simulation]`` table gives model, duration and step.
    out
        Folder the section writes its files into.
    runs
        Number of runs.
    seed
        Seed of the runs (initial states drawn per run unless the scenario fixes them).
    network
        The network; default the scenario's ``[network]`` table (None: ideal).
    executor
        Where the runs go (:func:`delayform.simulation.experiments.sweeps.executor`); default this process.
    progress
        Optional callback ``(runs done, runs)``.
    """
    from delayform.simulation.experiments.montecarlo import monte_carlo

    plt = _pyplot()
    net = scenario.network if network is None else network
    sim = scenario.simulation
    mc = monte_carlo(
        scenario.topology, scenario.P, scenario.D, scenario.tau1, scenario.tau2, scenario.desired_positions(),
        model=sim.model, network=net, runs=runs, seed=seed, duration=sim.duration, dt=sim.dt,
        initial_positions=scenario.initial_positions(), initial_headings=scenario.initial_headings(),
        initial_speed=scenario.initial.speed, limits=scenario.robot, radius=scenario.radius, assignment=sim.assignment, safety=scenario.safety, executor=executor, progress=progress,
    )  # fmt: skip
    files: list[str] = []
    fig, ax = plt.subplots(figsize=(7.0, 4.2))
    mc.plot(ax=ax)
    files += _save(fig, out, "montecarlo_bands")
    fig, axes = plt.subplots(1, 4, figsize=(16.0, 3.4))
    mc.plot_histograms(axes)
    fig.tight_layout()
    files += _save(fig, out, "montecarlo_histograms")
    rows = [(r, mc.settling_times[r], mc.final_errors[r], *mc.peak_commands[r], mc.min_distances[r],
             mc.contact_counts[r]) for r in range(mc.runs)]  # fmt: skip
    names = [n.strip("|").replace("/", "_") or "unused" for n in mc.command_names]
    files.append(_write_csv(out / "montecarlo_runs.csv",
                            ("run", "settling_time", "final_error", f"peak_{names[0]}", f"peak_{names[1]}",
                             "min_distance", "contacts"), rows))  # fmt: skip
    save_npz(out / "montecarlo.npz", times=mc.times, errors=mc.errors, settling_times=mc.settling_times)
    files.append("montecarlo.npz")
    where = "given" if scenario.initial.positions is not None else "random (one draw per run)"
    table, summary, bugs = _beside_guarantees(scenario, net, mc)
    return Section(
        key="montecarlo",
        title=f"Monte Carlo over the network: {runs} runs {_delays_phrase(scenario, net)}",
        text=(
            f"{runs} runs of the {scenario.topology.n} agents ({sim.model}, {sim.duration:g} s, step {sim.dt:g} s) "
            f"from {where} initial positions, each with its own draw of the network "
            f"({'ideal' if net is None else net.describe(scenario.topology.adjacency)}); seeds from SeedSequence({seed}).spawn({runs}), "
            "so the numbers are the same whichever way the runs are spread over workers. "
            "The certificates that apply to this network are listed beside what the runs observed"
            + (f"; BUG: {'; '.join(bugs)}" if bugs else ".")
        ),
        figures=(
            Figure("montecarlo_bands", "Formation error over time",
                   "Median and 5-95 %, 25-75 % quantile bands of the formation error (log scale) over the runs."),
            Figure("montecarlo_histograms", "Distributions",
                   "Histograms over the runs of the settling time, the final formation error, the peak command "
                   "and the closest approach of two robots (exact between saved steps)."),
        ),  # fmt: skip
        table=table,
        summary=summary,
        files=tuple(files),
    )


#: the certificates beside a Monte Carlo are computed for teams up to this size (their cost grows as N^4)
GUARANTEE_AGENTS = 30


def _beside_guarantees(scenario: Scenario, net: Any, mc: Any) -> tuple[tuple[tuple[str, str], ...], dict[str, Any], list[str]]:
    """The Monte Carlo table and summary with the applicable certificates and any contradiction."""
    from delayform.report.guarantees import (
        bug_rows, contradictions, guarantee_rows, network_guarantees, summary_of, with_actuation_delay,
        with_actuator_limits,
    )  # fmt: skip

    summary = dict(mc.summary())
    if scenario.topology.n > GUARANTEE_AGENTS:
        summary["guarantees"] = []
        summary["contradictions"] = []
        return mc.table() + (("certificates", f"not computed above {GUARANTEE_AGENTS} agents"),), summary, []
    gs = network_guarantees(scenario.topology, scenario.P, scenario.D, scenario.tau1, scenario.tau2, net,
                            dt=scenario.simulation.dt)  # fmt: skip
    if scenario.robot is not None or scenario.safety:  # saturating or filtered commands: outside every certificate
        gs = with_actuator_limits(gs)
    gs = with_actuation_delay(gs, scenario.actuation_delay)
    bugs = contradictions(gs, mc.statuses)
    summary["guarantees"] = summary_of(gs)
    summary["contradictions"] = bugs
    return bug_rows(bugs) + mc.table() + guarantee_rows(gs), summary, bugs


def scenario_setup(scenario: Scenario) -> Any:
    """What one Monte Carlo run of the scenario simulates (:func:`~delayform.simulation.experiments.montecarlo.make_setup`).

    Parameters
    ----------
    scenario
        Team, gains, delays, formation, ``[simulation]``, ``[network]``, ``[robot]`` and initial state.
    """
    from delayform.simulation.experiments.montecarlo import make_setup

    sim = scenario.simulation
    return make_setup(
        scenario.topology, scenario.P, scenario.D, scenario.tau1, scenario.tau2, scenario.desired_positions(),
        model=sim.model, network=scenario.network, duration=sim.duration, dt=sim.dt,
        initial_positions=scenario.initial_positions(), initial_headings=scenario.initial_headings(),
        initial_speed=scenario.initial.speed, limits=scenario.robot, radius=scenario.radius, assignment=sim.assignment, safety=scenario.safety,
        actuation_delay=scenario.actuation_delay, chassis=scenario.robot_spec.chassis,
    )  # fmt: skip


def sweep_section(
    scenario: Scenario,
    out: Path,
    *,
    tau1_values: Sequence[float],
    tau2_values: Sequence[float],
    runs: int = 10,
    seed: int = 0,
    workers: int | None = None,
    scheduler: str | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> Section:
    """Monte Carlo of the scenario on a grid of delays: settling time over ``tau1_values x tau2_values``.

    Parameters
    ----------
    scenario
        The validated scenario: team, gains, formation, ``[simulation]``,
        ``[network]`` (None: ideal) and ``[robot]`` (None: ideal robots).
    out
        Folder the section writes its files into.
    tau1_values, tau2_values
        Delays (s) to combine.
    runs
        Runs per grid point.
    seed
        Seed of every point (common random numbers, :mod:`delayform.simulation.experiments.sweeps`).
    workers, scheduler
        Where the runs go (:func:`delayform.simulation.experiments.sweeps.executor_for`).
    progress
        Optional callback ``(runs done, runs)``.
    """
    from delayform.plots import plot_metric_grid
    from delayform.simulation.experiments.sweeps import delay_sweep

    plt = _pyplot()
    sim, net = scenario.simulation, scenario.network
    setup = scenario_setup(scenario)
    result = delay_sweep(setup, tau1_values, tau2_values, runs=runs, seed=seed, workers=workers,
                         scheduler=scheduler, progress=progress or False)  # fmt: skip
    shape = (len(tau1_values), len(tau2_values))
    stats = {name: result.statistic("settling_time", q).reshape(shape) for name, q in
             (("median", 0.5), ("q05", 0.05), ("q95", 0.95))}  # fmt: skip
    settled = np.array([r.settled_fraction for r in result.results]).reshape(shape)
    final = result.statistic("final_error", 0.5).reshape(shape)
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    robots = "ideal robots" if scenario.robot is None else "robots with limits"
    plot_metric_grid(tau1_values, tau2_values, stats["median"], ax=ax, label="median settling time (s)",
                     title=f"{runs} runs per point, {'ideal network' if net is None else net.describe(scenario.topology.adjacency)}, {robots}")  # fmt: skip
    files = list(_save(fig, out, "sweep_settling"))
    rows = [
        (t1, t2, settled[i, j], stats["median"][i, j], stats["q05"][i, j], stats["q95"][i, j], final[i, j])
        for i, t1 in enumerate(tau1_values) for j, t2 in enumerate(tau2_values)
    ]  # fmt: skip
    files.append(_write_csv(out / "sweep.csv", ("tau1", "tau2", "settled_fraction", "settling_median",
                                                "settling_q05", "settling_q95", "final_error_median"), rows))  # fmt: skip
    save_npz(out / "sweep.npz", tau1=np.asarray(tau1_values, dtype=float),
                        tau2=np.asarray(tau2_values, dtype=float), settled_fraction=settled,
                        final_error_median=final, **{f"settling_{k}": v for k, v in stats.items()})  # fmt: skip
    files.append("sweep.npz")
    return Section(
        key="sweep",
        title=f"Delay sweep: {shape[0]} x {shape[1]} delay pairs, {runs} runs each",
        text=(
            f"Monte Carlo of the {scenario.topology.n} agents ({sim.model}, {sim.duration:g} s, step {sim.dt:g} s, "
            f"{robots}) at every (tau1, tau2) of the grid, over the "
            f"{'ideal network' if net is None else 'network ' + net.describe(scenario.topology.adjacency)}; every point uses the seeds of "
            f"SeedSequence({seed}).spawn({runs}), so the points differ by their delays, not by their draws."
        ),
        figures=(Figure("sweep_settling", "Settling time over the delay grid",
                        "Median settling time of the runs at each delay pair; grey: the median run did not settle."),),
        table=result.table(),
        summary={"runs": runs, "seed": seed, "setup": setup.describe(), "tau1": list(map(float, tau1_values)),
                 "tau2": list(map(float, tau2_values)), "points": result.summary()["points"]},  # fmt: skip
        files=tuple(files),
    )


def promises_section(
    scenario: Scenario,
    out: Path,
    *,
    points: Sequence[tuple[str, float, float]] | None = None,
    jitter_fractions: Sequence[float] = JITTER_FRACTIONS,
    loss_probabilities: Sequence[float] = LOSS_PROBABILITIES,
    runs: int = 6,
    seed: int = 0,
    dt: float | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> Section:
    """What the analysis still promises: the constant-delay prediction against Monte Carlo with jitter and loss.

    At each point the dominant root (paper, eq. 3) says stable or not and
    predicts the settling ``ln(50)/|Re s|``; Monte Carlo runs then grow the
    jitter bound (a fraction of each delay, symmetric, so the mean delay stays
    the analysed one) and, separately, the loss probability.

    Parameters
    ----------
    scenario
        The validated scenario (topology, gains, formation, model).
    out
        Folder the section writes its files into.
    points
        ``(label, tau1, tau2)``; default the chart points a and b (the paper's).
    jitter_fractions
        Jitter bounds as fractions of each delay, each in [0, 1).
    loss_probabilities
        Independent loss probabilities.
    runs
        Runs per level (initial states and network draws shared by the levels).
    seed
        Seed of the runs.
    dt
        Integration step (s); a jitter level must leave every delay at least ``dt``.
        Default per point: ``min(0.1, (1 - largest fraction) min(tau1, tau2))``,
        0.05 s at a and 0.1 s at b.
    progress
        Optional callback ``(levels done, levels)``.
    """
    from delayform.analysis.roots.dominant import dominant_root
    from delayform.model.network import BernoulliLoss, Jitter, Network
    from delayform.simulation.experiments.sweeps import network_sweep

    plt = _pyplot()
    if points is None:
        chart = {label: (a, b) for label, a, b in scenario.chart.points}
        missing = [k for k in "ab" if k not in chart]
        if missing:
            raise ScenarioError(f"{scenario.source}: chart.points: the network section needs points a and b; missing {missing}")
        points = [(k, *chart[k]) for k in "ab"]
    jitters = [float(f) for f in jitter_fractions]
    losses = [float(p) for p in loss_probabilities]
    total = len(points) * (len(jitters) + len(losses))
    done = 0
    rows: list[tuple[Any, ...]] = []
    per_point = []
    for label, t1, t2 in points:
        dom = dominant_root(scenario.topology, scenario.P, scenario.D, t1, t2)
        s = complex(dom.root)
        predicted = _LN50 / abs(s.real) if s.real < 0 else math.inf
        # long enough to see the predicted settling twice over, at least 60 s
        duration = max(60.0, min(2.0 * predicted, 300.0)) if math.isfinite(predicted) else 60.0
        # hold-newest under jitter hears, of many packets, nearly the quickest: the shortest delays
        shortest = [_predicted(scenario, t1 * (1 - f), t2 * (1 - f)) for f in jitters]
        step = dt if dt is not None else min(0.1, (1.0 - max(jitters)) * min(t for t in (t1, t2) if t > 0))
        setup = _setup(scenario, tau1=t1, tau2=t2, duration=duration, dt=step)
        nets_j = [Network(jitter=Jitter(f * t1, f * t2)) for f in jitters]
        nets_l = [Network(loss=BernoulliLoss(p)) for p in losses]
        sweeps = {}
        for kind, nets, levels in (("jitter", nets_j, jitters), ("loss", nets_l, losses)):
            labels = [f"{kind} {v:g}" for v in levels]
            sweeps[kind] = network_sweep(setup, nets, labels, runs=runs, seed=seed)
            done += len(levels)
            if progress is not None:
                progress(done, total)
            for v, r in zip(levels, sweeps[kind].results, strict=True):
                q = r.summary()["settling_time"]
                rows.append((label, t1, t2, kind, v, r.settled_fraction, q["median"], q["q05"], q["q95"],
                             float(np.median(r.final_errors))))  # fmt: skip
        per_point.append({"label": label, "tau1": t1, "tau2": t2, "root": s, "stable": dom.is_stable,
                          "predicted_settling": predicted, "predicted_at_shortest": shortest,
                          "duration": duration, "dt": step, "sweeps": sweeps})  # fmt: skip

    fig, axes = plt.subplots(1, 2, figsize=(11.0, 4.2))
    for p in per_point:
        for ax, kind, levels in ((axes[0], "jitter", jitters), (axes[1], "loss", losses)):
            result = p["sweeps"][kind]
            shown = [np.minimum(result.statistic("settling_time", q), p["duration"]) for q in (0.5, 0.05, 0.95)]
            line = ax.plot(levels, shown[0], "o-", label=f"{p['label']} ({p['tau1']:g}, {p['tau2']:g})")[0]
            ax.fill_between(levels, shown[1], shown[2], color=line.get_color(), alpha=0.2, lw=0)
            if math.isfinite(p["predicted_settling"]):
                ax.axhline(p["predicted_settling"], color=line.get_color(), ls=":", lw=1)
        axes[0].plot(jitters, np.minimum(p["predicted_at_shortest"], p["duration"]), "--", color=line.get_color(), lw=1)
    axes[0].set_xlabel("jitter bound / delay")
    axes[1].set_xlabel("loss probability")
    for ax in axes:
        ax.set_ylabel("settling time (s), capped at the run length")
        ax.set_yscale("log")
        ax.legend(fontsize="small")
    fig.tight_layout()
    files = list(_save(fig, out, "promises_settling"))
    files.append(_write_csv(out / "promises.csv", ("point", "tau1", "tau2", "kind", "level", "settled_fraction",
                                                   "settling_median", "settling_q05", "settling_q95", "final_error_median"),
                            rows))  # fmt: skip

    table = []
    for p in per_point:
        verdict = "stable" if p["stable"] else "unstable"
        table.append((f"{p['label']} ({p['tau1']:g}, {p['tau2']:g}): dominant root", f"{_fmt_complex(p['root'])} ({verdict})"))
        table.append((f"{p['label']}: predicted settling ln(50)/|Re s|", f"{_fmt(p['predicted_settling'])} s"))
        table.append((f"{p['label']}: predicted at the shortest delays tau (1 - f)",
                       "; ".join(f"{f:g}: {_fmt(v)} s" for f, v in zip(jitters, p["predicted_at_shortest"], strict=True))))  # fmt: skip
        for kind, levels in (("jitter", jitters), ("loss", losses)):
            cells = []
            for v, r in zip(levels, p["sweeps"][kind].results, strict=True):
                med = r.summary()["settling_time"]["median"]
                cells.append(f"{v:g}: {_fmt(med)} s ({100 * r.settled_fraction:.0f} %)")
            table.append((f"{p['label']}: median settling vs {kind}", "; ".join(cells)))
    summary = {
        "runs": runs, "seed": seed, "jitter_fractions": jitters, "loss_probabilities": losses,
        "points": [{k: v for k, v in p.items() if k != "sweeps"} | {
            kind: [{"level": v, "settled_fraction": r.settled_fraction, **{
                k: r.summary()["settling_time"][k] for k in ("median", "q05", "q95")}}
                for v, r in zip(levels, p["sweeps"][kind].results, strict=True)]
            for kind, levels in (("jitter", jitters), ("loss", losses))} for p in per_point],
    }  # fmt: skip
    return Section(
        key="promises",
        title="What the analysis still promises on a real network",
        text=(
            "The stability chart and the dominant root assume two constant delays on every link. Here the same "
            f"team runs {runs} times per level (double-integrator motion, the same seeds at every "
            "level) with jitter around each delay (each packet's delay uniform in tau (1 +- f)) and, separately, "
            "with independent packet loss (hold-last-value), a packet every step. Dotted: the settling the dominant "
            "root predicts at the nominal delays; dashed: at the shortest delays tau (1 - f). An agent keeps the "
            "newest sample it has received, and of many packets in flight the newest to arrive is nearly the "
            "quickest: jitter makes the information younger, not older, and the analysis at the shortest delay "
            "is the better yardstick. Loss makes it older by about p / (1 - p) packet periods on average."
        ),
        figures=(Figure("promises_settling", "Settling time against jitter and loss",
                        "Median settling time over the runs with 5-95 % band (capped at the run length when runs "
                        "do not settle), against the jitter bound as a fraction of the delays (left) and the "
                        "loss probability (right); dotted: ln(50)/|Re s| of the dominant root at the nominal delays, "
                        "dashed: at the shortest delays of each jitter level."),),  # fmt: skip
        table=tuple(table),
        summary=summary,
        files=tuple(files),
    )
