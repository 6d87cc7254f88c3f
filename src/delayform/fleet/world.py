"""The world of a fleet run: what moves the robots between their commands (one pluggable model).

A world model holds every robot's true state and has two methods
(:class:`WorldModel`): :meth:`~WorldModel.command` takes a robot's latest
velocity command at the time it arrives, :meth:`~WorldModel.advance`
integrates all robots to a later time at the model's fine step. The world
process (:mod:`delayform.fleet.agents`) calls them in real time and
publishes each robot's odometry; which model it runs is named by
``--world`` (:data:`WORLDS`), so a physics model is one more entry.

The kinematic model
-------------------
The unicycle of the paper (Section "Feedback Linearization")::

    x' = v cos(theta),  y' = v sin(theta),  theta' = omega,  v' = a

A velocity command ``(v_set, omega)`` arriving at ``t_c`` is a set-point for
one control period h later (what a velocity-controlled robot such as the
Create 3 takes): the speed ramps towards ``v_set`` at
``a = (v_set - v(t_c)) / h``, never faster than the robot's largest
acceleration, and stops at ``v_set`` (a command that comes late leaves the
robot at its set-point, not accelerating on). ``omega`` is held until the
next command. With limits, ``|v| <= max_speed`` and
``|omega| <= max_turn_rate``. Each fine step integrates the heading first
and moves along the mean heading of the step (second order in the step).
"""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from delayform.errors import FleetError
from delayform.model.limits import RobotLimits

__all__ = ["WorldModel", "KinematicWorld", "WORLDS", "world_model", "WORLD_STEP", "COMMAND_TIMEOUT"]

_Array = NDArray[np.float64]

#: the kinematic world's fine step (s)
WORLD_STEP = 0.001


class WorldModel(Protocol):
    """What a world model does: take commands, advance in time, show its state."""

    #: ``(n, 4)`` true states ``(x, y, theta, v)``
    state: _Array
    #: ``(n,)`` turn rates being executed
    omega: _Array
    #: the time the state is at (s, on the run's clock)
    time: float

    def command(self, robot: int, speed: float, turn_rate: float) -> None:
        """Take robot ``robot``'s (from 0) velocity command now."""

    def advance(self, t: float) -> None:
        """Integrate every robot to time ``t``."""


class KinematicWorld:
    """The unicycle with the profile's limits, integrated at a fine step (module doc).

    Parameters
    ----------
    state0
        ``(n, 4)`` initial states ``(x, y, theta, v)``.
    period
        The robots' control period h (s): a speed set-point is reached one period after it arrives.
    limits
        The robots' limits, or None for ideal robots.
    step
        The fine step (s).
    """

    def __init__(self, state0: _Array, *, period: float, limits: RobotLimits | None, step: float = WORLD_STEP) -> None:
        self.state = np.array(state0, dtype=np.float64)
        n = self.state.shape[0]
        self.omega = np.zeros(n)
        self.target = self.state[:, 3].copy()
        self.accel = np.zeros(n)
        self.period, self.limits, self.step = float(period), limits, float(step)
        self.time = 0.0

    def command(self, robot: int, speed: float, turn_rate: float) -> None:
        """Take a velocity command (module doc: the set-point and its ramp)."""
        lim = self.limits
        if lim is not None:
            speed = min(max(speed, -lim.max_speed), lim.max_speed)
            turn_rate = min(max(turn_rate, -lim.max_turn_rate), lim.max_turn_rate)
        a = (speed - self.state[robot, 3]) / self.period
        if lim is not None:
            a = min(max(a, -lim.max_acceleration), lim.max_acceleration)
        self.target[robot], self.accel[robot], self.omega[robot] = speed, a, turn_rate

    def advance(self, t: float) -> None:
        """Integrate every robot to ``t`` in fine steps (the last one shorter)."""
        s = self.state
        while self.time < t - 1e-12:
            h = min(self.step, t - self.time)
            v0 = s[:, 3]
            v1 = v0 + self.accel * h
            # stop at the set-point: between v0 and v1 when the ramp crosses it
            crossed = (self.target - v0) * (self.target - v1) <= 0.0
            v1 = np.where(crossed, self.target, v1)
            th0 = s[:, 2]
            th1 = th0 + self.omega * h
            mid, vm = 0.5 * (th0 + th1), 0.5 * (v0 + v1)
            s[:, 0] += vm * np.cos(mid) * h
            s[:, 1] += vm * np.sin(mid) * h
            s[:, 2] = np.remainder(th1 + math.pi, 2 * math.pi) - math.pi
            s[:, 3] = v1
            self.time += h


#: seconds without a command after which the world stops a robot (set-point zero, ramped at its limits): the
#: default ``cmd_vel_timeout`` of ros2_control's diff_drive_controller; a robot whose process died stops
COMMAND_TIMEOUT = 0.5

#: the world models ``--world`` names
WORLDS = ("kinematic",)


def world_model(name: str, state0: _Array, *, period: float, limits: RobotLimits | None) -> WorldModel:
    """The world model called ``name`` (:data:`WORLDS`).

    Parameters
    ----------
    name
        ``"kinematic"``.
    state0
        ``(n, 4)`` initial states.
    period
        The control period (s).
    limits
        The robots' limits or None.

    Raises
    ------
    FleetError
        For a name not in :data:`WORLDS`.
    """
    if name == "kinematic":
        return KinematicWorld(state0, period=period, limits=limits)
    raise FleetError(f"unknown world model {name!r}; known: {', '.join(WORLDS)}")
