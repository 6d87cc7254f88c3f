"""The simulate command."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import click

from delayform.cli._common import (
    POSITIVE,
    _emit,
    _inner_progress,
    _limits_given,
    _robot,
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

@cli.command("simulate")
@scenario_options
@click.option("--model", type=click.Choice(("unicycle", "double_integrator")),
              help="Agent model [default: simulation.model].")
@click.option("--duration", type=POSITIVE, help="Simulated time in seconds [default: simulation.duration].")
@click.option("--dt", type=POSITIVE, help="Time step in seconds [default: simulation.dt].")
@limit_options
@radius_option
@actuation_option
@click.option("--csv/--no-csv", "csv", default=None,
              help="Also write the trajectory and commands as CSV [default: only when under 20 MiB; NPZ always].")
@click.option("--gif/--no-gif", default=False, show_default=True, help="Also write an animated GIF.")
def simulate_command(scenario: Path | None, model: str | None, duration: float | None, dt: float | None,
                     seed: int | None, use_limits: bool | None, radius: float | None, assignment: str | None,
                     safety: str | None, actuation_delay: float | None,
                     csv: bool | None, gif: bool,
                     out: Path | None, as_json: bool, **overrides: Any) -> None:  # fmt: skip
    """Simulate the team at the scenario's delays into its formation.

    Writes x and y versus time (sim_operating_traces.png/.svg), the paths in
    the plane (sim_operating_xy.png/.svg), the robots' commands with their
    limits (sim_operating_commands.png/.svg, .npz), the trajectory as NPZ,
    CSV files when small or with --csv, and with --gif an animation;
    reports settling time, final formation error, closest approach (exact
    between saved steps), contacts between the robots' bodies (--radius) and
    any command beyond a limit. A run that diverges or whose robots collide
    is noted on stderr.
    """
    from delayform.report import simulation_section

    given = _limits_given(overrides)
    sc = with_actuation(_scenario(scenario, seed=seed, **overrides), actuation_delay)
    sim = _simulation_spec(sc, model=model, duration=duration, dt=dt, assignment=assignment)
    robot = _robot(sc.robot, use_limits, given, sim.model)
    sc = replace(sc, simulation=sim, robot=robot, radius=sc.radius if radius is None else radius,
                 safety=sc.safety if safety is None else (None if safety == "none" else safety),
                 initial=replace(sc.initial, seed=sc.initial.seed if seed is None else seed))  # fmt: skip
    sc.robot_spec.check_slots(sc.desired_positions())  # bodies that overlap in formation: before writing
    from delayform.simulation.runner import check_actuation

    check_actuation(sc.robot_spec, sc.network, sim.dt)  # an actuation delay this run cannot model: before writing
    directory = _out_dir(out, sc)
    with _inner_progress(f"simulate {sim.model}, {sim.duration:g} s (steps)") as callback:
        section = simulation_section(sc, directory, gif=gif, csv=csv, progress=callback)
    _emit(section, directory, as_json=as_json)
    for warning in section.summary["warnings"]:
        # a run that diverged, or whose robots collided, is said plainly
        if section.summary["status"] in ("diverging", "stopped") or warning.startswith("the robots collided"):
            click.echo(f"delayform: note: {warning}", err=True)
