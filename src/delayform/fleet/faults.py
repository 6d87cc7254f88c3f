"""Faults of a fleet run: a robot's process killed by signal at a time, and started again later.

``--kill ROBOT@T`` sends SIGKILL to robot ``ROBOT``'s process (numbered from
1) at ``T`` seconds of the run's wall clock (t = 0 is when the controllers
start): nothing in the process runs after it, as when a robot's computer
loses power. Its neighbours' playout buffers hold its last message
(hold-last-value), and the world's command timeout
(:data:`delayform.fleet.world.COMMAND_TIMEOUT`) stops the robot, as a base
whose commands stop coming does. ``--restart ROBOT@T`` starts a new process
for that robot at ``T``: it takes its own position and velocity from the
world's odometry and its neighbours' from their next messages, and ticks
again once it has heard from every neighbour.

:func:`check_faults` refuses, before any process starts, a robot that is
not in the team, a time outside the run, a restart of a robot that is not
dead at that time, a kill of one that is.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

from delayform.errors import FleetError

__all__ = ["Fault", "parse_fault", "check_faults", "ACTIONS"]

#: what a fault does to a robot's process
ACTIONS = ("kill", "restart")


@dataclass(frozen=True, order=True)
class Fault:
    """One fault: at ``at`` seconds of the run, ``action`` ("kill" or "restart") robot ``robot`` (from 1)."""

    at: float
    robot: int
    action: str


def parse_fault(text: str, action: str) -> Fault:
    """``ROBOT@T`` as a :class:`Fault` (not yet checked against the team: :func:`check_faults`).

    Parameters
    ----------
    text
        E.g. ``"3@4.5"``: robot 3 at 4.5 s.
    action
        ``"kill"`` or ``"restart"``.

    Raises
    ------
    FleetError
        For text that is not ``ROBOT@T`` with a whole robot number and a number of seconds.
    """
    if action not in ACTIONS:
        raise FleetError(f"unknown fault {action!r}; known: {', '.join(ACTIONS)}")
    robot_text, sep, at_text = str(text).partition("@")
    try:
        if not sep:
            raise ValueError
        robot, at = int(robot_text), float(at_text)
    except ValueError:
        raise FleetError(f"--{action} takes ROBOT@SECONDS (e.g. 2@5.0), got {text!r}") from None
    return Fault(at, robot, action)


def check_faults(faults: Iterable[Fault], n: int, duration: float) -> tuple[Fault, ...]:
    """The faults in time order, checked against a team of ``n`` robots and a run of ``duration`` s.

    Parameters
    ----------
    faults
        The kills and restarts.
    n
        Number of robots.
    duration
        The run's length (s): every fault lies strictly inside ``(0, duration)``.

    Raises
    ------
    FleetError
        For an unknown robot, a time outside the run, a restart of a robot
        that is running (a restart before its kill), a kill of a robot that
        is already dead, two faults of one robot at the same time.
    """
    ordered = sorted(faults)
    dead: dict[int, float] = {}
    seen: set[tuple[int, float]] = set()
    for f in ordered:
        if not isinstance(f, Fault) or f.action not in ACTIONS:
            raise FleetError(f"a fault must be a Fault with action kill or restart, got {f!r}")
        what = f"--{f.action} {f.robot}@{f.at:g}"
        if isinstance(f.robot, bool) or not 1 <= f.robot <= n:
            raise FleetError(f"{what}: the team has robots 1 to {n}")
        if not math.isfinite(f.at) or not 0.0 < f.at < duration:
            raise FleetError(f"{what}: the time must lie inside the run, between 0 and {duration:g} s")
        if (f.robot, f.at) in seen:
            raise FleetError(f"{what}: robot {f.robot} has two faults at the same time")
        seen.add((f.robot, f.at))
        if f.action == "kill":
            if f.robot in dead:
                raise FleetError(f"{what}: robot {f.robot} is already dead since {dead[f.robot]:g} s")
            dead[f.robot] = f.at
        else:
            if f.robot not in dead:
                raise FleetError(f"{what}: robot {f.robot} is running then; a restart comes after a kill")
            del dead[f.robot]
    return tuple(ordered)
