"""The check command: does a design fit a real robot?"""

from __future__ import annotations

import json
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

import click

from delayform.cli._common import POSITIVE, ROBOT_NAMES, _scenario, _simulation_spec, cli, team_options, without_actuation


@cli.command("check")
@team_options
@click.option("--robot", "robot_name", metavar="NAME",
              help=f"The robot ({', '.join(ROBOT_NAMES)}) [default: the scenario's [robot] profile].")
@click.option("--tau1", type=click.FloatRange(min=0.0), help="Position delay tau1 in seconds (overrides the scenario).")
@click.option("--tau2", type=click.FloatRange(min=0.0), help="Velocity delay tau2 in seconds (overrides the scenario).")
@click.option("--duration", type=POSITIVE, help="Simulated time in seconds [default: simulation.duration].")
@click.option("--dt", type=POSITIVE, help="Time step in seconds [default: simulation.dt].")
def check_command(scenario: Path | None, robot_name: str | None, duration: float | None, dt: float | None,
                  as_json: bool, **overrides: Any) -> None:  # fmt: skip
    """Say on one page whether the scenario's design fits a real robot.

    Five verdicts, each with its number: the actuator limits (the run with
    the robot's limits settles), the body radius (no overlap in the
    formation or during the run), the arena (where the robot has one), the
    control rate (the delays a robot ticking at its period applies are
    proven stable) and the jitter margin (constant extra delay proven
    stable). Exit code 0 when the design fits, 1 when a verdict says it
    does not, 2 for bad input.
    """
    from delayform.deploy import robot_profile
    from delayform.report.check import robot_check

    sc = without_actuation(_scenario(scenario, **overrides), "the design check (its certificates and margins)")
    name = robot_name if robot_name is not None else sc.robot_profile
    if name is None:
        raise click.UsageError("which robot? give --robot NAME or [robot] profile = \"NAME\" in the scenario")
    profile = robot_profile(name)
    sim = _simulation_spec(sc, model="unicycle", duration=duration, dt=dt)
    result = robot_check(replace(sc, simulation=sim), profile)
    if as_json:
        from delayform.report import jsonable

        click.echo(json.dumps(jsonable(result.summary()), indent=2))
    else:
        click.echo(result.page())
    if not result.fits:
        sys.exit(1)
