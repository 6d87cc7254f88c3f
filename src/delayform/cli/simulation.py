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
    _out_dir,
    _scenario,
    cli,
    scenario_options,
)

#: command-line option -> field of delayform.simulation.RobotLimits
_LIMIT_OPTIONS = (
    ("max_speed", "--max-speed", "Largest linear speed |v| (m/s)."),
    ("max_turn_rate", "--max-turn-rate", "Largest turn rate |omega| (rad/s)."),
    ("max_acceleration", "--max-acceleration", "Largest linear acceleration |dv/dt| (m/s^2)."),
    ("max_wheel_speed", "--max-wheel-speed", "Largest wheel speed (rad/s)."),
    ("wheel_radius", "--wheel-radius", "Wheel radius (m)."),
    ("axle_length", "--axle-length", "Distance between the wheels (m)."),
)


def _limit_options(func: Any) -> Any:
    for field, flag, text in reversed(_LIMIT_OPTIONS):
        func = click.option(flag, field, type=POSITIVE,
                            help=f"{text} Implies --limits [default: robot.{field} or the iRobot Create's].")(func)  # fmt: skip
    return func


@cli.command("simulate")
@scenario_options
@click.option("--model", type=click.Choice(("unicycle", "double_integrator")),
              help="Agent model [default: simulation.model].")
@click.option("--duration", type=POSITIVE, help="Simulated time in seconds [default: simulation.duration].")
@click.option("--dt", type=POSITIVE, help="Time step in seconds [default: simulation.dt].")
@click.option("--limits/--no-limits", "use_limits", default=None,
              help="Robots with actuator limits (the scenario's [robot] table, else the iRobot Create's) "
                   "or ideal robots [default: limits when the scenario has a [robot] table].")
@_limit_options
@click.option("--csv/--no-csv", "csv", default=None,
              help="Also write the trajectory and commands as CSV [default: only when under 20 MiB; NPZ always].")
@click.option("--gif/--no-gif", default=False, show_default=True, help="Also write an animated GIF.")
def simulate_command(scenario: Path | None, model: str | None, duration: float | None, dt: float | None,
                     seed: int | None, use_limits: bool | None, csv: bool | None, gif: bool, out: Path | None,
                     as_json: bool, **overrides: Any) -> None:  # fmt: skip
    """Simulate the team at the scenario's delays into its formation.

    Writes x and y versus time (sim_operating_traces.png/.svg), the paths in
    the plane (sim_operating_xy.png/.svg), the robots' commands with their
    limits (sim_operating_commands.png/.svg, .npz), the trajectory as NPZ,
    CSV files when small or with --csv, and with --gif an animation;
    reports settling time, final formation error, closest approach and any
    command beyond a limit. A run that diverges is noted on stderr.
    """
    from delayform.report import simulation_section
    from delayform.scenario import SimulationSpec
    from delayform.simulation import IROBOT_CREATE

    given = {field: overrides.pop(field) for field, _, _ in _LIMIT_OPTIONS}
    given = {k: v for k, v in given.items() if v is not None}
    sc = _scenario(scenario, seed=seed, **overrides)
    sim = SimulationSpec(
        model=model or sc.simulation.model,
        duration=sc.simulation.duration if duration is None else duration,
        dt=sc.simulation.dt if dt is None else dt,
    )
    if sim.dt >= sim.duration:
        raise click.BadParameter(f"the step must be smaller than the duration {sim.duration:g}", param_hint="--dt")
    robot = sc.robot
    if use_limits is False:
        if given:
            raise click.UsageError("--no-limits cannot be combined with " + ", ".join(
                flag for field, flag, _ in _LIMIT_OPTIONS if field in given))  # fmt: skip
        robot = None
    elif use_limits or given:
        robot = replace(robot or IROBOT_CREATE, **given)
    if robot is not None and sim.model != "unicycle":
        raise click.UsageError("actuator limits apply to robots: use --model unicycle or --no-limits")
    sc = replace(sc, simulation=sim, robot=robot,
                 initial=replace(sc.initial, seed=sc.initial.seed if seed is None else seed))  # fmt: skip
    directory = _out_dir(out, sc)
    with _inner_progress(f"simulate {sim.model}, {sim.duration:g} s (steps)") as callback:
        section = simulation_section(sc, directory, gif=gif, csv=csv, progress=callback)
    _emit(section, directory, as_json=as_json)
    if section.summary["status"] in ("diverging", "stopped"):
        for warning in section.summary["warnings"]:
            click.echo(f"delayform: note: {warning}", err=True)
