"""Agent models: double integrators, ideal differential-drive robots, robots with actuator limits.

Conventions
-----------
A robot is a unicycle (paper, eq. 14) with the dynamic extension of Section
"Feedback Linearization": state ``(x, y, theta, v)``, ``x' = v cos(theta)``,
``y' = v sin(theta)``, inputs ``dv/dt`` and ``omega``. ``v`` is signed: a
robot may drive backwards. A differential drive with wheel radius ``r`` and
axle length ``L`` turns ``(v, omega)`` into wheel speeds (rad/s)
``left = (v - omega L / 2) / r`` and ``right = (v + omega L / 2) / r``.

Ideal robots (no limits)
------------------------
the paper's eq. 19 (``dv/dt = e . u``, ``omega = e_perp . u / v`` with
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
reported by :class:`delayform.simulation.models.commands.RobotCommands`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from delayform.model.limits import IROBOT_CREATE, RobotLimits
from delayform.model.robot import MODELS, REST_SPEED, Robot

# the robot's description lives with the problem's nouns (delayform.model); its names stay importable here
__all__ = ["Robot", "RobotLimits", "IROBOT_CREATE", "REST_SPEED", "MODELS", "ideal_commands", "wheel_speeds"]

_Array = NDArray[np.float64]


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
    recovers the commands of the paper's eq. 19 that realise it.

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
    """State rows (x, y, theta, v): the paper's eq. 19 with saturated inputs.

    The wanted turn rate is the softened eq. 19 of the paper
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
        limits (``e . u`` and the softened eq. 19 of the paper turn rate); 1.0
        where the speed limit cut the demanded acceleration by more than 1 %.
        """
        return self.apply(state, self.command(state, u))

    def command(self, state: _Array, u: _Array) -> _Array:
        """The demands (dv/dt, omega) of the paper's eq. 19 (softened) on this state, columns of an (n, 2) array.

        With an actuation delay these are what is sent late; the limits act
        when they are executed (:meth:`apply`), on the state then.
        """
        lim = self.limits
        th, v = state[:, 2], state[:, 3]
        c, s = np.cos(th), np.sin(th)
        ux, uy = u[:, 0], u[:, 1]
        along = c * ux + s * uy  # the paper's eq. 19, first row
        across = c * uy - s * ux
        demand = lim._turn_demand(v, along, across, ux * ux + uy * uy)  # the paper's eq. 19, second row, softened
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
