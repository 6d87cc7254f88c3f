"""The fleet command: the team as one process per robot over Zenoh, measured against the analysis."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import click

from delayform.cli._common import (
    POSITIVE,
    _emit,
    _limits_given,
    _out_dir,
    _scenario,
    _with_robot,
    cli,
    limit_options,
    scenario_options,
)

#: the world models (kept literal: the CLI starts fast; tests/test_fleet.py checks them against delayform.fleet.world.WORLDS)
WORLD_NAMES = ("kinematic",)

#: the control period of a robot whose profile states none: the Create Open Interface's 15 ms
DEFAULT_PERIOD = 0.015


@cli.command("fleet")
@scenario_options
@limit_options
@click.option("--duration", type=POSITIVE, default=30.0, show_default=True, help="Seconds of wall clock from t = 0.")
@click.option("--period", type=POSITIVE,
              help=f"Control period of every robot (s) [default: the robot profile's, else {DEFAULT_PERIOD:g}].")
@click.option("--endpoint", default="tcp/127.0.0.1:7447", show_default=True,
              help="Zenoh endpoint on the loopback where the processes meet (peer mode, no router).")
@click.option("--world", type=click.Choice(WORLD_NAMES), default="kinematic", show_default=True,
              help="What moves the robots: the kinematic unicycle with the robots' limits.")
@click.option("--kill", "kills", multiple=True, metavar="ROBOT@T",
              help="Kill robot ROBOT's process by SIGKILL at T s of the run (repeatable).")
@click.option("--restart", "restarts", multiple=True, metavar="ROBOT@T",
              help="Start a killed robot's process again at T s: it rejoins from the world's odometry (repeatable).")
@click.option("--foxglove", type=int, metavar="PORT",
              help="Serve the running team to Foxglove (WebSocket) on 127.0.0.1:PORT.")
@click.option("--ros-domain", type=click.IntRange(0, 232), metavar="N",
              help="Also publish every topic as rmw_zenoh (ROS 2 Jazzy) does on ROS domain N (0..232), with "
                   "liveliness tokens, so that a ROS 2 node on rmw_zenoh connected to --endpoint hears the run.")
def fleet_command(scenario: Path | None, seed: int | None, use_limits: bool | None, duration: float,
                  period: float | None, endpoint: str, world: str, kills: tuple[str, ...], restarts: tuple[str, ...],
                  foxglove: int | None, ros_domain: int | None, out: Path | None, as_json: bool, **overrides: Any) -> None:  # fmt: skip
    """Run the team as processes: one per robot, a world, Zenoh messages.

    Each robot's process runs the on-robot controller (its playout buffer
    holding tau1, tau2) every control period on the wall clock; the world
    process moves the robots (the kinematic unicycle with their limits: the
    scenario's [robot], --robot, else the iRobot Create's; --no-limits for
    ideal robots) and publishes their odometry. Messages are CDR-encoded
    nav_msgs/Odometry (robot_<i>/odom, robot_<i>/state) and geometry_msgs/Twist
    (robot_<i>/cmd_vel) on Zenoh key expressions named as ROS 2 topics; the
    scenario's [network] (per-link delays, jitter, loss, sampling, noise) acts
    on the state messages at the receiving side with the simulator's draws. Writes fleet.mcap (every message), summary.json,
    summary.txt and fleet_error.png/.svg: per link the delays applied, ticks
    missed or late, messages lost, and beside them the chart's verdict, the
    dominant root's decay against the measured one, and the simulator's
    settling time and closest approach at the same delays.

    --kill ROBOT@T and --restart ROBOT@T are faults: the robot's process is
    killed by SIGKILL, its neighbours hold its last message, and the summary
    names it and how long it was silent; a restarted robot rejoins from the
    world's odometry. --foxglove PORT serves the robots, their bodies, the
    formation's slots and the communication graph to Foxglove while the team runs.
    --ros-domain N also publishes every message as rmw_zenoh does on ROS
    domain N (key, attachment, liveliness tokens): `ros2 topic echo
    /robot_1/odom` on rmw_zenoh_cpp with its router connected to --endpoint.
    """
    from delayform._extras import require_extra
    from delayform.deploy import robot_profile
    from delayform.fleet.faults import check_faults, parse_fault
    from delayform.fleet.live import check_live_port
    from delayform.fleet.run import check_network
    from delayform.fleet.wire import check_endpoint
    from delayform.simulation import IROBOT_CREATE

    require_extra("fleet")
    given = _limits_given(overrides)
    sc = _scenario(scenario, seed=seed, **overrides)
    if sc.actuation_delay:
        raise click.UsageError("the scenario has an actuation delay: a fleet run's robots act when their command "
                               "arrives; set [robot] actuation_delay = 0")  # fmt: skip
    sc = sc.with_uniform_links_folded()  # per-link delays stay in the network: the playout buffers hold them
    if use_limits is None and sc.robot is None and not given:  # the paper's robot, as the fleet's default
        sc = replace(sc, robot=IROBOT_CREATE)
    sc = _with_robot(sc, use_limits, given, "unicycle")
    desired = sc.desired_positions()
    if sc.robot is not None:
        sc.robot_spec.check_slots(desired)
    network = check_network(sc.network)
    _, port = check_endpoint(endpoint)
    profile = robot_profile(sc.robot_profile) if sc.robot_profile else None
    h = period if period is not None else (profile.control_period if profile and profile.control_period else DEFAULT_PERIOD)
    if h >= duration:
        raise click.BadParameter(f"the control period {h:g} s must be shorter than the duration {duration:g} s",
                                 param_hint="--period")  # fmt: skip
    faults = check_faults([parse_fault(t, "kill") for t in kills] + [parse_fault(t, "restart") for t in restarts],
                          sc.topology.n, duration)  # fmt: skip
    if foxglove is not None:
        check_live_port(foxglove, taken=port)
    directory = _out_dir(out, sc)
    run = _run(sc, desired, network, h, duration, endpoint, world, directory, quiet=as_json,
               faults=faults, foxglove=foxglove, ros_domain=ros_domain)  # fmt: skip
    from delayform.report.fleet import fleet_section

    section = fleet_section(run, sc.name, directory)
    _emit(section, directory, as_json=as_json)
    team = run.summary["team"]
    for robot in run.summary["robots"]:
        if robot["error"]:  # a controller that stopped: the run went on without its commands
            click.echo(f"delayform: note: {robot['error']}", err=True)
    for robot in run.summary["robots"]:
        for gap in robot["silent"]:
            click.echo(f"delayform: note: robot {robot['robot']} was silent for {gap['silent_s']:.3f} s "
                       f"(killed at {gap['killed_at_s']:.3f} s)", err=True)  # fmt: skip
    if team["ticks_missed"]:
        click.echo(f"delayform: note: {team['ticks_missed']} control tick(s) missed: the machine was too busy "
                   f"for {sc.topology.n} robots every {h:g} s (summary.txt)", err=True)  # fmt: skip


def _run(sc: Any, desired: Any, network: Any, h: float, duration: float, endpoint: str, world: str,
         directory: Path, *, quiet: bool, faults: Any, foxglove: int | None, ros_domain: int | None) -> Any:  # fmt: skip
    from delayform.fleet import run_fleet
    from delayform.model import Delays, Start, Team

    def say(text: str) -> None:
        if not quiet:
            click.echo(f"fleet: {text}", err=True)

    return run_fleet(Team(sc.topology, sc.P, sc.D), Delays(sc.tau1, sc.tau2), desired, out=directory,
                     duration=duration, period=h, robot=sc.robot,
                     start=Start(sc.initial_positions(), sc.initial_headings(), sc.initial.speed, sc.initial.seed),
                     network=network, endpoint=endpoint, world=world, faults=faults, foxglove=foxglove,
                     ros_domain=ros_domain, progress=say)  # fmt: skip
