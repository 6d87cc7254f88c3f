"""Agent models: double integrators, ideal differential-drive robots, robots with actuator limits.

Conventions
-----------
A robot is a unicycle (eq. kinem:uni) with the dynamic extension of Section
"Feedback Linearization": state ``(x, y, theta, v)``, ``x' = v cos(theta)``,
``y' = v sin(theta)``, inputs ``dv/dt`` and ``omega``. ``v`` is signed: a
robot may drive backwards. A differential drive with wheel radius ``r`` and
axle length ``L`` turns ``(v, omega)`` into wheel speeds (rad/s)
``left = (v - omega L / 2) / r`` and ``right = (v + omega L / 2) / r``.

Ideal robots (no limits)
------------------------
Eq. transform2 (``dv/dt = e . u``, ``omega = e_perp . u / v`` with
``e = (cos theta, sin theta)``) makes the position obey ``x'' = u`` exactly
while ``v != 0``. So an ideal robot's position *is* the double integrator's,
and its commands follow from the Cartesian velocity ``V`` and acceleration
``U`` (:func:`ideal_commands`): the heading is the direction of ``V`` up to
a half turn, kept continuous, so ``v = +-|V|`` changes sign where the
velocity passes through zero (the robot reverses instead of spinning
180 degrees), ``omega = (V x U) / |V|^2`` and ``dv/dt = U . e``. A robot whose
speed and commanded acceleration are both below :data:`REST_SPEED` (per
second) has nowhere to go: it holds its heading (``omega = 0``) instead of
following the direction of a vanishing velocity (docs/theory.md).

Robots with limits
------------------
:class:`RobotLimits` describes a differential-drive robot; with limits the
true unicycle state is integrated with saturated inputs
(:class:`LimitedUnicycle`), and the ideal commands that exceeded a limit are
reported by :class:`delayform.simulation.commands.RobotCommands`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any

import numpy as np
from numpy.typing import NDArray

from delayform._validation import check_delay, validated
from delayform.errors import SimulationInputError

__all__ = ["Robot", "RobotLimits", "IROBOT_CREATE", "REST_SPEED", "MODELS", "ideal_commands", "wheel_speeds"]

#: agent models accepted by :func:`delayform.simulation.simulate`; ``"physics"``: robots with mass
#: in a physics engine (:mod:`delayform.simulation.physics`)
MODELS = ("double_integrator", "unicycle", "physics")

_Array = NDArray[np.float64]

#: below this speed (m/s) and acceleration (m/s^2) a robot is at rest and holds
#: its heading: the iRobot Create's drive command has a resolution of 1 mm/s
REST_SPEED = 1e-3


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
        Speed scale (m/s) below which the turn command of eq. transform2 is
        softened (``e_perp . u (v + s slow_speed) / (v^2 + slow_speed^2)``
        instead of ``e_perp . u / v``; s turns the robot's axis towards the
        line of u at rest): the robot turns on the spot when it must, and the
        heading loop stays smooth through v = 0 (docs/theory.md).
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
    slow_speed: float = 0.05
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


def _nonnegative(name: str, value: object, unit: str) -> float:
    """A finite non-negative number of a Robot, or SimulationInputError naming it."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise SimulationInputError(f"{name} must be a number ({unit}), got {value!r}")
    if not (math.isfinite(value) and value >= 0):
        raise SimulationInputError(f"{name} must be finite and non-negative ({unit}), got {value!r}")
    return float(value)


@validated(SimulationInputError)
@dataclass(frozen=True)
class Robot:
    """What belongs to the robot in a simulation, gathered as :class:`Network` gathers the network.

    Attributes
    ----------
    model
        ``"unicycle"`` (differential-drive robot, eq. transform2),
        ``"double_integrator"`` (point agents, ``x'' = u``) or ``"physics"``
        (differential-drive bodies with mass, wheel servos and contacts in
        a physics engine: :mod:`delayform.simulation.physics`).
    limits
        Actuator limits (:class:`RobotLimits`); None for ideal robots (for
        ``"physics"``: :data:`IROBOT_CREATE`).
    radius
        Radius (m) of the disc containing the body, for contacts. None
        (default): ``limits.radius``, else the Create's 0.17 m for robots
        and 0 (points, no contacts) for double integrators.
    safety
        A safety filter (:class:`~delayform.simulation.safety.BarrierFilter`,
        or its name ``"barrier"``), or None (default).
    actuation_delay
        tau_a >= 0 (s): each robot applies its command tau_a late,
        ``x'' = u(t - tau_a)`` for double integrators; for robots the demands
        (dv/dt, omega) of eq. transform2, computed on the state when the
        command is made, are executed tau_a later under the limits of that
        time (docs/theory.md, "Actuation delay"). 0 (default): the paper's model.
    chassis
        For ``model="physics"`` only: mass, inertia, tyres and wheel servos
        (:class:`~delayform.simulation.physics.Chassis`); None: the
        Create 3's (:data:`~delayform.simulation.physics.CREATE_CHASSIS`).

    Examples
    --------
    >>> Robot().body_radius, Robot(model="double_integrator").body_radius
    (0.17, 0.0)
    """

    model: str = "unicycle"
    limits: RobotLimits | None = None
    radius: float | None = None
    safety: Any = None
    actuation_delay: float = 0.0
    chassis: Any = None

    def __post_init__(self) -> None:
        from delayform.simulation.safety import check_safety

        object.__setattr__(self, "safety", check_safety(self.safety))
        object.__setattr__(self, "actuation_delay", check_delay("actuation_delay", self.actuation_delay))  # a DelayError, as everywhere
        if self.model not in MODELS:
            raise SimulationInputError(f"unknown model {self.model!r}; choose one of {', '.join(MODELS)}")
        if self.limits is not None and not isinstance(self.limits, RobotLimits):
            raise SimulationInputError(f"limits must be a RobotLimits or None, got {type(self.limits).__name__}")
        if self.limits is not None and self.model == "double_integrator":
            raise SimulationInputError("limits apply to robots: use model='unicycle'")
        if self.model == "physics":
            self._physics_defaults()
        elif self.chassis is not None:
            raise SimulationInputError("a chassis (mass, servos, tyres) applies to model='physics' only")
        if self.radius is not None:
            object.__setattr__(self, "radius", _nonnegative("radius", self.radius, "m"))

    def _physics_defaults(self) -> None:
        """The Create's limits and chassis where none are given; refuse what the engine does not model."""
        from delayform.simulation.physics.chassis import CREATE_CHASSIS, Chassis

        if self.chassis is None:
            object.__setattr__(self, "chassis", CREATE_CHASSIS)
        elif not isinstance(self.chassis, Chassis):
            raise SimulationInputError(f"chassis must be a Chassis, got {type(self.chassis).__name__}")
        if self.limits is None:
            object.__setattr__(self, "limits", IROBOT_CREATE)
        if self.safety is not None:
            raise SimulationInputError("the safety filter is not modelled for model='physics': the bodies "
                                       "push each other instead (use model='unicycle' for the filter)")  # fmt: skip
        if self.actuation_delay > 0.0:
            raise SimulationInputError("model='physics' has its own actuation lag (the wheel servos): give "
                                       "actuation_delay with model='unicycle' or 'double_integrator'")  # fmt: skip

    @property
    def body_radius(self) -> float:
        """The radius (m) used for contacts (see :attr:`radius`)."""
        if self.radius is not None:
            return self.radius
        if self.limits is not None:
            return self.limits.radius
        return IROBOT_CREATE.radius if self.model == "unicycle" else 0.0

    def check_slots(self, desired: _Array) -> None:
        """Refuse a formation whose slots are closer than two body radii, or than the safety filter's distance.

        With a safety filter (:attr:`safety`) the robots are kept at least
        two radii plus its margin apart, so slots closer than that could
        never be reached: the run would end far from the formation and look
        unstable although the delays are stable.

        Parameters
        ----------
        desired
            ``(n, 2)`` desired positions.

        Raises
        ------
        SimulationInputError
            Naming the closest two slots.
        """
        r = self.body_radius
        margin = 0.0 if self.safety is None else self.safety.margin
        n = desired.shape[0]
        if r + margin == 0.0 or n < 2:
            return
        from scipy.spatial import cKDTree

        dist, idx = cKDTree(desired).query(desired, k=2)
        i = int(np.argmin(dist[:, 1]))
        d = float(dist[i, 1])
        if d >= (2.0 * r + margin) * (1.0 - 1e-9):  # touching slots (and slots at the safe distance) are allowed
            return
        # for two slots at the same place the tree may list i itself second: name the other one
        other = int(idx[i, 1]) if int(idx[i, 1]) != i else int(idx[i, 0])
        a, b = sorted((i, other))
        if d < 2.0 * r * (1.0 - 1e-9):
            raise SimulationInputError(
                f"formation slots {a + 1} and {b + 1} are {d:.3g} m apart, closer than two robot "
                f"radii ({2.0 * r:.3g} m): the bodies would overlap in formation; spread the formation "
                f"or give a smaller radius"
            )
        raise SimulationInputError(
            f"formation slots {a + 1} and {b + 1} are {d:.3g} m apart, closer than the safety filter keeps "
            f"the robots (two radii plus its margin: {2.0 * r + margin:.3g} m): the formation could never be "
            f"reached; spread the formation or give a smaller safety margin"
        )


def wheel_speeds(v: _Array, omega: _Array, robot: RobotLimits) -> tuple[_Array, _Array]:
    """Left and right wheel speeds (rad/s) of a differential drive at speed v and turn rate omega.

    Parameters
    ----------
    v, omega
        Linear speed (m/s) and turn rate (rad/s), arrays of one shape.
    robot
        Wheel radius and axle length.

    >>> wheel_speeds(np.array([0.5]), np.array([0.0]), IROBOT_CREATE)[0].round(2)
    array([13.89])
    """
    half = 0.5 * robot.axle_length * omega
    return (v - half) / robot.wheel_radius, (v + half) / robot.wheel_radius


def ideal_commands(
    velocities: _Array, accelerations: _Array, headings0: _Array, *, rest_speed: float = REST_SPEED
) -> tuple[_Array, _Array, _Array, _Array]:
    """Heading, signed speed, turn rate and acceleration of ideal robots from their motion.

    The ideal robot's position is the double integrator's (module doc); this
    recovers the commands of eq. transform2 that realise it.

    Parameters
    ----------
    velocities, accelerations
        ``(T, n, 2)`` Cartesian velocity V and acceleration U at the samples.
    headings0
        ``(n,)`` initial headings; the first sample's heading is this one.
    rest_speed
        A robot whose |V| and |U| (per second) are both below this holds its
        heading; so does one whose |V| is zero to rounding.

    Returns
    -------
    (headings, speeds, turn_rates, accelerations)
        ``(T, n)`` each: theta continuous in time (not wrapped), signed v,
        omega and dv/dt.
    """
    V, U = velocities, accelerations
    speed = np.hypot(V[..., 0], V[..., 1])
    scale = float(speed.max(initial=0.0)) + 1e-300
    hold = ((speed < rest_speed) & (np.hypot(U[..., 0], U[..., 1]) < rest_speed)) | (speed <= 1e-12 * scale)
    # The axis of motion is the direction of V modulo a half turn: unwrap twice the
    # angle, so the heading stays continuous and v changes sign where V reverses.
    doubled = 2.0 * np.arctan2(V[..., 1], V[..., 0])
    doubled[0] = 2.0 * headings0  # the first heading is the given one
    T = V.shape[0]
    # held samples repeat the last moving sample's axis (forward fill)
    idx = np.where(hold, 0, np.arange(T)[:, None])
    idx[0] = 0
    np.maximum.accumulate(idx, axis=0, out=idx)
    filled = np.take_along_axis(doubled, idx, axis=0)
    theta = 0.5 * np.unwrap(filled, axis=0)
    theta += headings0 - theta[0]
    c, s = np.cos(theta), np.sin(theta)
    v = V[..., 0] * c + V[..., 1] * s
    vdot = U[..., 0] * c + U[..., 1] * s
    cross = V[..., 0] * U[..., 1] - V[..., 1] * U[..., 0]
    omega = np.where(hold, 0.0, cross / np.where(hold, 1.0, speed**2))
    return theta, v, omega, vdot


# ----------------------------------------------------------- agent models
class DoubleIntegrator:
    """State rows (x, y, xdot, ydot): ``x'' = u`` (Section "Consensus Protocol")."""

    name = "double_integrator"
    extras: tuple[str, ...] = ()

    def __init__(self, x0: _Array, v0: _Array) -> None:
        self.state0 = np.column_stack([x0, v0])

    @staticmethod
    def velocity(state: _Array) -> _Array:
        return state[:, 2:]

    @staticmethod
    def rhs(state: _Array, u: _Array) -> tuple[_Array, _Array, tuple[_Array, ...]]:
        """(state derivative, Cartesian acceleration, extras)."""
        return np.concatenate([state[:, 2:], u], axis=1), u, ()

    @staticmethod
    def command(state: _Array, u: _Array) -> _Array:
        """What the actuators receive, to be applied late (actuation delay): the acceleration u itself."""
        return u

    apply = rhs  # applying a (late) command: x'' = the command


class LimitedUnicycle:
    """State rows (x, y, theta, v): eq. transform2 with saturated inputs.

    The wanted turn rate is the softened eq. transform2
    (:attr:`RobotLimits.slow_speed`, :attr:`RobotLimits.turn_time_constant`)
    clipped to ``max_turn_rate``. The
    commanded acceleration is ``clip(e . u, +-max_acceleration)``, faded to
    zero as |v| approaches the speed cap while it would push |v| beyond it
    (factor ``1 - (|v| / cap)^8``); turning has priority over speed: where
    the wheels cannot give the wanted turn at speed v
    (``|v| + |omega| L / 2 > r max_wheel_speed``) the robot brakes at full
    deceleration (ramped in over 0.1 s of excess). The executed turn rate
    is the wanted one clipped to what the wheels leave,
    ``2 (r max_wheel_speed - |v|) / L``. Every function is continuous, so
    RK4 stays second order across the switches of the limits.
    """

    name = "unicycle"
    extras = ("dv_dt", "omega", "ideal_dv_dt", "ideal_omega", "speed_held")

    def __init__(self, x0: _Array, theta0: _Array, speed0: _Array, limits: RobotLimits) -> None:
        self.state0 = np.column_stack([x0, theta0, speed0])
        self.limits = limits

    @staticmethod
    def velocity(state: _Array) -> _Array:
        th, v = state[:, 2], state[:, 3]
        out = np.empty((state.shape[0], 2))
        np.multiply(v, np.cos(th), out=out[:, 0])
        np.multiply(v, np.sin(th), out=out[:, 1])
        return out

    def rhs(self, state: _Array, u: _Array) -> tuple[_Array, _Array, tuple[_Array, ...]]:
        """(state derivative, Cartesian acceleration, extras).

        Extras: executed dv/dt and omega; the controller's demands before the
        limits (``e . u`` and the softened eq. transform2 turn rate); 1.0
        where the speed limit cut the demanded acceleration by more than 1 %.
        """
        return self.apply(state, self.command(state, u))

    def command(self, state: _Array, u: _Array) -> _Array:
        """The demands (dv/dt, omega) of eq. transform2 (softened) on this state, columns of an (n, 2) array.

        With an actuation delay these are what is sent late; the limits act
        when they are executed (:meth:`apply`), on the state then.
        """
        lim = self.limits
        th, v = state[:, 2], state[:, 3]
        c, s = np.cos(th), np.sin(th)
        ux, uy = u[:, 0], u[:, 1]
        along = c * ux + s * uy  # eq. transform2, first row
        across = c * uy - s * ux
        size2 = ux * ux + uy * uy
        vs = np.sqrt(lim.slow_speed**2 + lim.turn_time_constant**2 * size2)
        # towards the line of u at rest: +1 when u is ahead, -1 when behind (then reverse)
        toward = along / np.sqrt(size2 + 1e-24)
        demand = across * (v + toward * vs) / (v * v + vs * vs)  # eq. transform2, second row, softened
        return np.column_stack([along, demand])

    def apply(self, state: _Array, command: _Array) -> tuple[_Array, _Array, tuple[_Array, ...]]:
        """Execute demands (dv/dt, omega) under the limits at this state: as :meth:`rhs` returns."""
        # np.minimum / np.maximum instead of np.clip: for a handful of robots the
        # call overhead, not the arithmetic, is the cost of a step.
        lo, hi = np.maximum, np.minimum
        lim = self.limits
        th, v = state[:, 2], state[:, 3]
        c, s = np.cos(th), np.sin(th)
        along, demand = command[:, 0], command[:, 1]
        speed = np.abs(v)
        amax = lim.max_acceleration
        accel = hi(lo(along, -amax), amax)
        fade = np.where(accel * v > 0.0, lo(1.0 - (speed / lim.speed_cap) ** 8, 0.0), 1.0)
        accel = accel * fade
        wanted = hi(lo(demand, -lim.max_turn_rate), lim.max_turn_rate)
        # Both wheels at full speed leave no room to turn: the turn comes first, so a
        # robot faster than the wheels allow for the wanted turn brakes (ramp over 0.1 s).
        rim = lim.wheel_radius * lim.max_wheel_speed
        allowed = lo(rim - 0.5 * lim.axle_length * np.abs(wanted), 0.0)
        brake = hi(lo((speed - allowed) / (0.1 * amax), 0.0), 1.0)
        accel = (1.0 - brake) * accel - brake * np.sign(v) * amax
        turn_cap = hi(lo(2.0 * (rim - speed) / lim.axle_length, 0.0), lim.max_turn_rate)
        omega = hi(lo(wanted, -turn_cap), turn_cap)
        n = v.shape[0]
        deriv = np.empty((n, 4))
        deriv[:, 0] = v * c
        deriv[:, 1] = v * s
        deriv[:, 2] = omega
        deriv[:, 3] = accel
        vw = v * omega
        cart = np.empty((n, 2))
        cart[:, 0] = accel * c - vw * s
        cart[:, 1] = accel * s + vw * c
        return deriv, cart, (accel, omega, along, demand, (fade < 0.99).astype(float))
