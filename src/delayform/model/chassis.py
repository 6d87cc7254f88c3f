"""The physical numbers of a differential-drive robot: chassis, wheels, caster, tyres and wheel servos.

A :class:`Chassis` completes a :class:`~delayform.model.RobotLimits`
(wheel radius, track, speed limits, body radius) with what a physics engine
needs: mass and yaw inertia, body height, wheel mass and width, where the
caster sits, the tyres' friction, the wheel servo's gain and torque limit,
and the period of the loop that sends the wheel commands. Robot profiles
(:mod:`delayform.model.profiles`) give each number its source, or mark it
as an assumption where the maker documents none. A
:class:`~delayform.model.Robot` with ``model="physics"`` carries one; the
engine that steps it is :mod:`delayform.simulation.physics`.

Conventions
-----------
SI units: kg, m, kg m^2, N m, N m s/rad (a velocity servo's torque per
rad/s of speed error), s. The robot's frame has x forward and z up; its
origin is the middle of the axle.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace

import numpy as np

from delayform._validation import validated
from delayform.errors import SimulationInputError

__all__ = ["Chassis", "CREATE_CHASSIS", "TIMESTEP"]

#: the engine's step (s): docs/theory.md, "Robots with mass", says why 2 ms
TIMESTEP = 0.002


@validated(SimulationInputError)
@dataclass(frozen=True)
class Chassis:
    """The mass, inertia, tyres and wheel servos of a differential-drive robot (module doc for units).

    Attributes
    ----------
    mass
        Mass of the body without its two drive wheels (kg).
    height
        Height of the body's cylinder (m); its radius is the robot's
        :attr:`~delayform.model.RobotLimits.radius`.
    wheel_mass
        Mass of one drive wheel (kg).
    wheel_width
        Width of one drive wheel's tyre (m).
    caster_offset
        Where the caster touches the floor along the robot's axis (m):
        positive ahead of the axle, negative behind it (the TurtleBot3's).
        The body's centre of mass lies a third of the way from the axle to
        the caster, inside the triangle of the three contacts.
    tyre_friction
        Sliding friction coefficient of the tyres on the floor.
    servo_gain
        Gain of each wheel's velocity servo: torque (N m) per rad/s of
        wheel-speed error.
    max_torque
        Largest torque (N m) a wheel's motor gives.
    control_period
        Period (s) at which the robot's controller sends wheel speeds (held
        between ticks).
    yaw_inertia
        The body's moment of inertia about the vertical (kg m^2); None
        (default): a uniform cylinder, ``mass radius^2 / 2``.
    """

    mass: float
    height: float
    wheel_mass: float
    wheel_width: float
    caster_offset: float
    tyre_friction: float
    servo_gain: float
    max_torque: float
    control_period: float = 0.01
    yaw_inertia: float | None = None

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if value is None and f.name == "yaw_inertia":
                continue
            if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
                raise SimulationInputError(f"chassis.{f.name} must be a number, got {value!r}")
            if f.name == "caster_offset":
                if not (math.isfinite(value) and value != 0.0):
                    raise SimulationInputError(f"chassis.caster_offset must be finite and non-zero (m), got {value!r}")
            elif not (math.isfinite(value) and value > 0):
                raise SimulationInputError(f"chassis.{f.name} must be finite and positive, got {value!r}")
            object.__setattr__(self, f.name, float(value))

    def with_changes(self, **changes: float) -> Chassis:
        """A copy with some numbers changed (``chassis.with_changes(servo_gain=1.0)``)."""
        return replace(self, **changes)

    def engine_grid(self) -> tuple[float, int]:
        """The engine's step (s) and the steps per control tick: the longest step up to :data:`TIMESTEP` that divides the period.

        >>> CREATE_CHASSIS.engine_grid(), CREATE_CHASSIS.with_changes(control_period=0.015).engine_grid()
        ((0.002, 5), (0.001875, 8))
        """
        substeps = max(1, math.ceil(self.control_period / TIMESTEP - 1e-9))
        return self.control_period / substeps, substeps

    def wheel_inertia(self, wheel_radius: float) -> float:
        """A drive wheel's inertia about its axle (kg m^2): a disc, ``wheel_mass r^2 / 2``."""
        return 0.5 * self.wheel_mass * wheel_radius * wheel_radius

    def rotor_inertia(self, wheel_radius: float) -> float:
        """Inertia (kg m^2) the motor adds at the wheel's axle: ``max(0, servo_gain TIMESTEP - I_wheel)``.

        The engine integrates the servo's torque explicitly (semi-implicit
        Euler, accurate for the servo-chassis coupling, docs/theory.md), which
        is stable for a wheel off the floor while ``servo_gain TIMESTEP /
        inertia <= 1``: the wheel's joint carries at least that inertia, as a
        geared motor's rotor does (a few per cent of what the servo drives on
        the floor for every profile).
        """
        return max(0.0, self.servo_gain * TIMESTEP - self.wheel_inertia(wheel_radius))

    def servo_time_constant(self, wheel_radius: float) -> float:
        """Time constant (s) of a straight-line speed step while no limit is reached.

        Each wheel's servo drives its own and its rotor's inertia and half
        the robot's mass at the rim:
        ``(I_wheel + I_rotor + (mass / 2 + wheel_mass) r^2) / servo_gain``.

        Parameters
        ----------
        wheel_radius
            Radius r of the drive wheels (m).
        """
        r = wheel_radius
        inertia = self.wheel_inertia(r) + self.rotor_inertia(r) + (0.5 * self.mass + self.wheel_mass) * r * r
        return inertia / self.servo_gain


#: The iRobot Create's (the paper's robot, :data:`~delayform.model.IROBOT_CREATE`),
#: used by ``simulate(..., model="physics")`` when no chassis is given. iRobot's Open Interface
#: specification documents none of these numbers: every one is an ASSUMPTION (the robot
#: profile ``create`` names each): 3.6 kg, a Roomba-class body 7 cm high, 0.1 kg wheels 2 cm wide,
#: the caster 13 cm ahead, rubber on a hard floor (0.8), a servo of 25 ms time constant
#: (:meth:`Chassis.servo_time_constant`), torque for three times the 0.5 m/s^2 limit, 10 ms ticks.
CREATE_CHASSIS = Chassis(
    mass=3.6, height=0.07, wheel_mass=0.1, wheel_width=0.02, caster_offset=0.13,
    tyre_friction=0.8, servo_gain=0.1, max_torque=0.15, control_period=0.01,
)  # fmt: skip
