"""A differential-drive robot's geometry and the limits of its actuators.

Conventions
-----------
Lengths in m, speeds in m/s, turn rates and wheel speeds in rad/s,
accelerations in m/s^2. A differential drive with wheel radius ``r`` and
axle length ``L`` turns ``(v, omega)`` into wheel speeds
``left = (v - omega L / 2) / r`` and ``right = (v + omega L / 2) / r``; the
saturated unicycle that obeys these limits is integrated in
:mod:`delayform.simulation.models.robots`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from delayform._validation import validated
from delayform.errors import SimulationInputError

__all__ = ["RobotLimits", "IROBOT_CREATE", "FORWARD_BIAS"]

#: the softened turn law's preference for driving forward at rest (:meth:`RobotLimits.turn_demand`): where u
#: lies exactly across the heading a robot at rest turns towards u's forward direction at this fraction of
#: its full turn rate, instead of standing still (docs/theory.md)
FORWARD_BIAS = 0.2


@validated(SimulationInputError)
@dataclass(frozen=True)
class RobotLimits:
    """A differential-drive robot: its geometry and the limits of its actuators.

    Attributes
    ----------
    wheel_radius
        Radius of the drive wheels (m).
    axle_length
        Distance between the two drive wheels (m).
    max_wheel_speed
        Largest wheel speed (rad/s) of either wheel.
    max_speed
        Largest linear speed |v| (m/s).
    max_turn_rate
        Largest turn rate |omega| (rad/s).
    max_acceleration
        Largest linear acceleration |dv/dt| (m/s^2).
    slow_speed
        Speed (m/s) the controller treats as standing still: the floor of the
        softening speed of the paper's eq. 19,
        ``v_s = sqrt(slow_speed^2 + (turn_time_constant |u|)^2)``, below which the
        turn command ``e_perp . u / v`` is softened to
        ``e_perp . u (v + s v_s) / (v^2 + v_s^2)`` (:meth:`turn_demand`; s turns
        the robot's axis towards the line of u at rest, preferring forward):
        the robot turns on the spot when it must, and the heading loop stays
        smooth through v = 0 (docs/theory.md). 1 mm/s, the resolution of the
        Create's speed commands: a larger floor slows the heading loop at rest to
        ``|u| / slow_speed`` and leaves a steady formation error of the order of
        ``slow_speed`` times a second.
    turn_time_constant
        Fastest heading response (s) the controller asks for: the softening
        speed grows to ``|u| turn_time_constant`` when the demanded
        acceleration u is large, so the heading loop's rate stays below
        ``1 / turn_time_constant`` (a real robot's heading loop has a finite
        bandwidth; a fixed step must resolve it).
    radius
        Radius (m) of the disc that contains the robot's body, for contacts and
        the safety filter (the Create: 0.34 m across, so 0.17 m).

    See :data:`IROBOT_CREATE` for defaults of the paper's robot.
    """

    wheel_radius: float = 0.036
    axle_length: float = 0.258
    max_wheel_speed: float = 0.5 / 0.036
    max_speed: float = 0.5
    max_turn_rate: float = 2 * 0.5 / 0.258
    max_acceleration: float = 0.5
    slow_speed: float = 0.001
    turn_time_constant: float = 0.05
    radius: float = 0.17

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
                raise SimulationInputError(f"limits.{f.name} must be a number, got {value!r}")
            if not (math.isfinite(value) and value > 0):
                raise SimulationInputError(f"limits.{f.name} must be finite and positive, got {value!r}")
            object.__setattr__(self, f.name, float(value))

    def turn_demand(self, v: Any, along: Any, across: Any, size2: Any) -> Any:
        """The turn rate (rad/s) the controller asks for: the paper's eq. 19, second row, softened near rest.

        ``across (v + s v_s) / (v^2 + v_s^2)`` with
        ``v_s = sqrt(slow_speed^2 + (turn_time_constant |u|)^2)`` and
        ``s = e . u / |u| + FORWARD_BIAS``: for ``|v| >> v_s`` it is
        ``e_perp . u / v`` (the paper's eq. 19); at rest the robot turns its axis
        towards the line of u, forward or backward, and turns towards the forward
        direction of u where u is across its heading (docs/theory.md). Works
        elementwise on floats and on numpy arrays alike (the simulator and the
        deployed controller compute it here, so they agree to the last bit).

        Parameters
        ----------
        v
            Signed speed along the heading (m/s).
        along, across
            ``e . u`` and ``e_perp . u`` (m/s^2), e the heading's unit vector.
        size2
            ``|u|^2``.
        """
        return self._turn_demand(v, along, across, size2)

    def _turn_demand(self, v: Any, along: Any, across: Any, size2: Any) -> Any:
        # the body of turn_demand without the argument check of the public method: the simulator and
        # the controller call it at every stage of every step, where that check cost more than the formula
        vs = np.sqrt(self.slow_speed**2 + self.turn_time_constant**2 * size2)
        toward = along / np.sqrt(size2 + 1e-24) + FORWARD_BIAS
        return across * (v + toward * vs) / (v * v + vs * vs)

    @property
    def speed_cap(self) -> float:
        """Largest speed the robot can drive straight: ``min(max_speed, r max_wheel_speed)``."""
        return min(self.max_speed, self.wheel_radius * self.max_wheel_speed)

    def describe(self) -> str:
        """One line for tables."""
        return (
            f"|v| <= {self.max_speed:g} m/s, |omega| <= {self.max_turn_rate:.3g} rad/s, "
            f"|dv/dt| <= {self.max_acceleration:g} m/s^2, wheels <= {self.max_wheel_speed:.3g} rad/s "
            f"(r = {self.wheel_radius:g} m, L = {self.axle_length:g} m)"
        )


#: iRobot Create-like defaults (the paper's robot). Source: iRobot Create Open
#: Interface (OI) Specification (iRobot, 2006): Drive and Drive Direct take
#: velocities of -500..500 mm/s (both wheels and the robot's centre), and its
#: angle sensor converts wheel travel to heading with the 258 mm wheel base.
#: The wheel radius, 36 mm, is half the 72 mm wheel diameter of the Create 2
#: OI Specification (2015; the Create manual does not state it). Turn rate:
#: both wheels at 500 mm/s in opposite directions, 2 * 0.5 / 0.258 = 3.88 rad/s.
#: The maximum acceleration, 0.5 m/s^2, is NOT documented by iRobot: an
#: assumed value for a small indoor robot.
IROBOT_CREATE = RobotLimits()


