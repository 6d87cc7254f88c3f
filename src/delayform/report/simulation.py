"""Report sections of simulations: trajectories, the robots' commands, settling times."""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import replace
from datetime import datetime
from pathlib import Path

import numpy as np

from delayform.scenario import Scenario
from delayform.report._common import (
    Figure,
    MapProgress,
    Section,
    _fmt,
    _pyplot,
    _save,
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
    mcap: Path | None = None,
    mcap_start: datetime | float | str | None = None,
    progress: MapProgress | None = None,
    network: bool = False,
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
        Also draw the paths figure (paper, Fig. 6), ``<stem>_xy``.
    gif
        Also write an animated GIF (slower).
    csv
        Write the CSV files: True always, False never, None (default) when
        the trajectory's CSV would be below :data:`CSV_AUTO_LIMIT`.
    mcap
        Also write the run as a ROS 2 recording there
        (:func:`delayform.deploy.recording.write_mcap`; robots only), with
        the scenario and the analysis verdict as metadata (:func:`mcap_records`).
    mcap_start
        The recording's start time (:func:`delayform.deploy.recording.recording_start`;
        default 1970-01-01, stamps = simulated time).
    progress
        Optional callback ``(steps done, steps)`` while the run is integrated.
    network
        Run over the scenario's ``[network]`` (per-link delays, jitter, loss,
        ...) instead of the ideal one, at the scenario's own delays (no
        ``tau1`` / ``tau2``: a matrix would override them): what ``delayform
        simulate`` and ``report`` ask.
    """
    from delayform.simulation import simulate

    plt = _pyplot()
    if network and (tau1 is not None or tau2 is not None):
        from delayform.errors import InputError

        raise InputError("simulation_section: network=True runs at the scenario's own delays, give no tau1 / tau2")
    per_link = None
    if network:  # a delay matrix equal on every link is that delay; one that differs is said in the table
        scenario = scenario.with_uniform_links_folded()
        per_link = scenario.per_link_description(spread=False)
    tau1 = scenario.tau1 if tau1 is None else tau1
    tau2 = scenario.tau2 if tau2 is None else tau2
    sim = scenario.simulation
    robot = scenario.robot_spec
    limits = robot.limits
    traj = simulate(
        scenario.topology, scenario.P, scenario.D, tau1, tau2, scenario.desired_positions(),
        robot=robot, initial_positions=scenario.initial_positions(),
        initial_headings=scenario.initial_headings(), initial_speed=scenario.initial.speed,
        seed=scenario.initial.seed, duration=sim.duration, dt=sim.dt, progress=progress,
        assignment=sim.assignment, network=scenario.network if network else None,
    )  # fmt: skip
    out.mkdir(parents=True, exist_ok=True)  # the command line leaves the folder to the first write
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
    if mcap is not None:
        from delayform.deploy.recording import write_mcap

        mcap.parent.mkdir(parents=True, exist_ok=True)
        net = scenario.network if network and scenario.network is not None and not scenario.network.is_ideal else None
        files.append(str(write_mcap(traj, mcap, topology=scenario.topology, start_time=mcap_start,
                                    metadata=mcap_records(scenario, tau1, tau2), network=net).resolve()))
    if gif:
        traj.save_gif(out / f"{stem}.gif")
        files.append(f"{stem}.gif")
        figures.append(Figure(f"{stem}", f"The robots moving into formation at {label}",
                              "Animation of the simulated positions and headings.", animated=True))  # fmt: skip
    settling = float(traj.settling_time)
    limits_text = commands.summary() if commands is not None else None
    summary = {
        "label": label, "tau1": tau1, "tau2": tau2, "per_link_delays": per_link, "model": sim.model,
        "duration": sim.duration, "dt": sim.dt,
        "status": traj.status, "warnings": list(traj.warnings),
        "settling_time": settling,
        "initial_error": float(traj.formation_error[0]),
        "final_error": float(traj.formation_error[-1]),
        "min_distance": float(traj.min_distance),
        "closest_at": float(traj.closest_at) if np.isfinite(traj.closest_at) else None,
        "radius": float(traj.radius),
        "assignment": sim.assignment,
        "safety": None if traj.safety is None else {
            "safe_distance": traj.safety.safe_distance, "active_fraction": traj.safety.active_fraction,
            "first_active": traj.safety.first_active if traj.safety.was_active else None,
            "last_active": traj.safety.last_active if traj.safety.was_active else None,
        },
        "slots": [int(k) + 1 for k in traj.slots] if traj.slots is not None else None,
        "contacts": [
            {"agents": [c.agents[0] + 1, c.agents[1] + 1], "start": c.start, "end": c.end,
             "closest": c.closest, "closest_at": c.closest_at}
            for c in traj.contacts
        ],
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
        ("delays (tau1, tau2)", f"({tau1:g}, {tau2:g}) s" + ("" if per_link is None else f"; per link: {per_link}")),
        *([("network", scenario.network.describe(scenario.topology.adjacency))]
          if network and scenario.network is not None else []),
        ("model", sim.model + ("" if commands is None else (", with limits" if commands.limited else ", ideal robots"))),
        ("settling time (2 %)", settled_text),
        ("final formation error", f"{_fmt(summary['final_error'])} m"),
        ("closest approach of two agents", f"{_fmt(summary['min_distance'])} m at t = {_fmt(traj.closest_at)} s"),
    ]
    if sim.model == "physics":  # what the dynamics cost: the kinematic robots with the same limits, same start
        from delayform.simulation.physics.compare import KinematicComparison, kinematic_twin

        kin = simulate(
            scenario.topology, scenario.P, scenario.D, tau1, tau2, scenario.desired_positions(),
            robot=kinematic_twin(robot), initial_positions=scenario.initial_positions(),
            initial_headings=scenario.initial_headings(), initial_speed=scenario.initial.speed,
            seed=scenario.initial.seed, duration=sim.duration, dt=sim.dt, assignment=sim.assignment,
            network=scenario.network if network else None,
        )  # fmt: skip
        cmp = KinematicComparison.of(traj, kin)
        summary["kinematic"] = {
            "max_deviation": cmp.max_deviation, "final_deviation": cmp.final_deviation,
            "settling_time": float(kin.settling_time) if np.isfinite(kin.settling_time) else None,
            "status": kin.status,
        }  # fmt: skip
        table.append(("beside the kinematic model", cmp.describe()))
    if sim.assignment != "given" and traj.slots is not None:
        table.append(("slots (robot: slot)", f"{sim.assignment}: " + ", ".join(
            f"{i + 1}: {k + 1}" for i, k in enumerate(traj.slots))))  # fmt: skip
    if traj.safety is not None:
        table.append(("safety filter", traj.safety.sentence()))
        # the settling time it costs: the same run without the filter
        bare = simulate(
            scenario.topology, scenario.P, scenario.D, tau1, tau2, scenario.desired_positions(),
            robot=replace(robot, safety=None), initial_positions=scenario.initial_positions(),
            initial_headings=scenario.initial_headings(), initial_speed=scenario.initial.speed,
            seed=scenario.initial.seed, duration=sim.duration, dt=sim.dt, assignment=sim.assignment,
        )  # fmt: skip
        summary["settling_time_without_filter"] = float(bare.settling_time)
        summary["contacts_without_filter"] = len(bare.contacts)
        table.append(("without the filter", f"settling {_fmt(float(bare.settling_time))} s, "
                                            f"{len(bare.contacts)} contact(s), closest {_fmt(bare.min_distance)} m"))  # fmt: skip
    if traj.radius > 0:
        table.append(("contacts (bodies " + f"{2 * traj.radius:g} m across)",
                      f"{len(traj.contacts)}: collided" if traj.collided else "none"))  # fmt: skip
    if commands is not None:
        table.append(("beyond the limits" if commands.limited else "beyond an iRobot Create's limits", limits_text))
    table += [("warning", w) for w in traj.warnings]
    if not write_csv:
        table.append(("CSV", "not written (large run): NPZ only; use --csv to force it"))
    robots = "double-integrator agents"
    if sim.model == "unicycle":
        robots = ("differential-drive robots with actuator limits (saturated unicycle)" if limits is not None
                  else "ideal differential-drive robots (unicycle, feedback linearization (paper, eq. 19))")  # fmt: skip
    elif sim.model == "physics":
        robots = ("differential-drive robots with mass, wheel servos and contacts in a physics engine "
                  f"(controller ticks every {robot.chassis.control_period:g} s)")  # fmt: skip
    return Section(
        key=f"simulation_{label}",
        title=f"Simulation at {label}: (tau1, tau2) = ({tau1:g}, {tau2:g}) s" + ("" if per_link is None else ", per-link delays over [network]"),
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


def mcap_records(scenario: Scenario, tau1: float, tau2: float) -> dict[str, dict[str, str]]:
    """The metadata a recording of the scenario's run carries: the scenario and the analysis verdict.

    ``delayform/scenario``: the run's parameters as JSON (command-line
    overrides applied) and, for a scenario file, its TOML text as written.
    ``delayform/analysis``: the dominant root of the team at (tau1, tau2)
    (:func:`~delayform.analysis.roots.dominant.dominant_root`, milliseconds
    for small teams) and the verdict, for constant delays on every link.
    """
    from delayform.analysis.roots.dominant import dominant_root
    from delayform.errors import DelayformError

    scene = {"name": scenario.name, "source": scenario.source,
             "parameters": json.dumps(scenario.summary(), default=str)}  # fmt: skip
    source = Path(scenario.source)
    if source.suffix == ".toml" and source.is_file():
        scene["toml"] = source.read_text(encoding="utf-8")
    covers = f"constant delays ({tau1:g}, {tau2:g}) s on every link"
    if scenario.actuation_delay > 0:
        covers += f", actuation delay {scenario.actuation_delay:g} s"
    if scenario.network is not None and not scenario.network.is_ideal:
        covers += "; the run's [network] is not covered (delayform links, box, montecarlo)"
    try:
        dom = dominant_root(scenario.topology, scenario.P, scenario.D, tau1, tau2, actuation_delay=scenario.actuation_delay)
    except DelayformError as exc:  # the recording still holds the run; the verdict says why it is missing
        return {"delayform/scenario": scene, "delayform/analysis": {"verdict": "not computed", "reason": str(exc), "covers": covers}}
    root = complex(dom.root)
    analysis = {"verdict": "stable" if dom.is_stable else "unstable", "dominant_root": repr(root),
                "dominant_root_re": repr(root.real), "dominant_root_im": repr(root.imag), "covers": covers}  # fmt: skip
    return {"delayform/scenario": scene, "delayform/analysis": analysis}


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


