"""The simulate command."""

from __future__ import annotations

from dataclasses import replace
from datetime import datetime, timedelta, timezone
from pathlib import Path
from typing import Any

import click

from delayform.cli._common import (
    refuse_file_in_the_way,
    writable_folder,
    POSITIVE,
    _emit,
    _inner_progress,
    _limits_given,
    _with_robot,
    _out_dir,
    _scenario,
    _simulation_spec,
    cli,
    limit_options,
    radius_option,
    actuation_option,
    with_actuation,
    scenario_options,
)

_MCAP_FOLDER = "the folder of the MCAP file"


@cli.command("simulate")
@scenario_options
@click.option("--model", type=click.Choice(("unicycle", "double_integrator", "physics")),
              help="Agent model [default: simulation.model].")
@click.option("--duration", type=POSITIVE, help="Simulated time in seconds [default: simulation.duration].")
@click.option("--dt", type=POSITIVE, help="Time step in seconds [default: simulation.dt].")
@limit_options
@radius_option
@actuation_option
@click.option("--csv/--no-csv", "csv", default=None,
              help="Also write the trajectory and commands as CSV [default: only when under 20 MiB; NPZ always].")
@click.option("--gif/--no-gif", default=False, show_default=True, help="Also write an animated GIF.")
@click.option("--mcap", type=click.Path(dir_okay=False, path_type=Path),
              help="Also write the run as a ROS 2 recording (MCAP: Odometry, Twist, /tf, /tf_static, markers, "
                   "the scenario as metadata; docs/deploy.md).")
@click.option("--mcap-start", metavar="TIME",
              help="When t = 0 is in the recording: 'now', ISO 8601 with a zone (2026-12-03T10:00:00Z) or "
                   "seconds since 1970 [default: 1970-01-01, stamps = simulated time].")
def simulate_command(scenario: Path | None, model: str | None, duration: float | None, dt: float | None,
                     seed: int | None, use_limits: bool | None, radius: float | None, assignment: str | None,
                     safety: str | None, actuation_delay: float | None,
                     csv: bool | None, gif: bool, mcap: Path | None, mcap_start: str | None,
                     out: Path | None, as_json: bool, **overrides: Any) -> None:  # fmt: skip
    """Simulate the team at the scenario's delays into its formation.

    Writes x and y versus time (sim_operating_traces.png/.svg), the paths in
    the plane (sim_operating_xy.png/.svg), the robots' commands with their
    limits (sim_operating_commands.png/.svg, .npz), the trajectory as NPZ,
    CSV files when small or with --csv, and with --gif an animation;
    reports settling time, final formation error, closest approach (exact
    between saved steps), contacts between the robots' bodies (--radius) and
    any command beyond a limit. With --robot (or the scenario's [robot]
    profile) a formation the robots cannot hold (bodies overlapping, wider
    than the arena) is refused before anything runs; --mcap FILE writes the
    run as a ROS 2 recording. A run that diverges or whose robots collide is
    noted on stderr.
    """
    from delayform.report import simulation_section

    start = _mcap_start(mcap, mcap_start)  # a bad time is refused before the run
    given = _limits_given(overrides)
    sc = with_actuation(_scenario(scenario, seed=seed, **overrides), actuation_delay)
    sim = _simulation_spec(sc, model=model, duration=duration, dt=dt, assignment=assignment)
    if mcap is not None:
        from delayform._extras import require_extra
        from delayform.deploy.recording import check_mcap_path

        require_extra("ros")  # a core install writes no recordings: say which extra, before any work
        if sim.model == "double_integrator":
            raise click.UsageError("--mcap records robots: use --model unicycle or physics")
        # its folder is made when the recording is written; what can be refused without it is refused now
        refuse_file_in_the_way(mcap.parent, _MCAP_FOLDER, "--mcap")
        if mcap.parent.is_dir():
            check_mcap_path(mcap)
    sc = replace(_with_robot(sc, use_limits, given, sim.model), simulation=sim,
                 radius=sc.radius if radius is None else radius,
                 safety=sc.safety if safety is None else (None if safety == "none" else safety),
                 initial=replace(sc.initial, seed=sc.initial.seed if seed is None else seed))  # fmt: skip
    # both folders are made when the run writes: what simulate refuses (bodies that overlap in formation,
    # an actuation delay it cannot model) leaves no folder behind
    directory = _out_dir(out, sc, create=False)
    if mcap is not None:
        writable_folder(mcap.parent, _MCAP_FOLDER, "--mcap", create=False)
    with _inner_progress(f"simulate {sim.model}, {sim.duration:g} s (steps)") as callback:
        section = simulation_section(sc, directory, gif=gif, csv=csv, mcap=mcap, mcap_start=start,
                                     progress=callback, network=True)  # fmt: skip
    _emit(section, directory, as_json=as_json)
    for warning in section.summary["warnings"]:
        # a run that diverged, or whose robots collided, is said plainly
        if section.summary["status"] in ("diverging", "stopped") or warning.startswith("the robots collided"):
            click.echo(f"delayform: note: {warning}", err=True)


def _mcap_start(mcap: Path | None, text: str | None) -> datetime | None:
    """``--mcap-start`` as the instant it names (fixed now, so 'now' is when the command started)."""
    if text is None:
        return None
    if mcap is None:
        raise click.UsageError("--mcap-start sets the start of the recording: give --mcap FILE too")
    from delayform.deploy.recording import recording_start
    from delayform.errors import RecordingError

    try:
        ns = recording_start(text)
    except RecordingError as exc:
        raise click.BadParameter(str(exc), param_hint="--mcap-start") from None
    return datetime.fromtimestamp(ns // 10**9, tz=timezone.utc) + timedelta(microseconds=(ns % 10**9) // 1000)
