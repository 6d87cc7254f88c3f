"""The robot's own lag, measured: a servo step response fitted by a first-order-plus-dead-time model.

One robot of the physics model (:mod:`delayform.simulation.physics.engine`)
stands still; both wheel servos are stepped to the same speed and the
chassis speed v(t) is recorded at every engine step. The response is fitted
(least squares, :func:`scipy.optimize.least_squares`) by

    v(t) = K v_step (1 - exp(-(t - L) / T))   for t > L,  0 before,

the first-order-plus-dead-time (FOPDT) model: gain K, time constant T (the
bandwidth is 1/T rad/s, the -3 dB frequency of the lag), dead time L.

The bridge to the analysis
--------------------------
The analysis models a late actuator as ``x'' = u(t - tau_a)`` (paper, eq. 1
with an actuation delay, :func:`~delayform.analysis.roots.dominant.dominant_root`).
The robot's speed follows its set-point through the dead time and the lag,
``e^{-s L} / (1 + s T)``, to first order in s ``e^{-s (L + T)}``, so the
equivalent actuation delay is

    tau_a = L + T.

The zero-order hold adds nothing to it: the controller integrates dv/dt
over the coming period into the speed set-point at the tick (the end value
of the period's ramp, sent at its start), half a period early, which
cancels the hold's half period late. Measured: with a control period of
50 ms the formation error of the Create 3 hexagon decays as the dominant
root at ``L + T`` says, not at ``L + T + h / 2`` (tests/test_physics.py).
The equivalent delay matches the phase of the true actuator at low
frequency and over-states it at high frequency (a lag's phase saturates at
90 degrees, a delay's does not): at the formation's crossing frequencies
(about 1 rad/s) with T of tens of ms the two differ by well under a degree.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

from delayform._validation import validated
from delayform.errors import SimulationInputError
from delayform.model.chassis import Chassis
from delayform.model import RobotLimits

__all__ = ["ServoIdentification", "identify_actuation"]

_Array = NDArray[np.float64]


@validated(SimulationInputError)
@dataclass(frozen=True, eq=False)
class ServoIdentification:
    """A fitted first-order-plus-dead-time servo response (module doc).

    Attributes
    ----------
    times, speeds
        The step response: engine step times (s) and chassis speed (m/s).
    step_speed
        The commanded speed step (m/s).
    gain
        K: final speed over the step.
    time_constant
        T (s).
    dead_time
        L (s).
    control_period
        h (s), the controller's period (zero-order hold; it does not enter
        :attr:`effective_delay`, module doc).
    rms_error
        Root-mean-square residual of the fit (m/s).
    """

    times: _Array
    speeds: _Array
    step_speed: float
    gain: float
    time_constant: float
    dead_time: float
    control_period: float
    rms_error: float

    @property
    def bandwidth(self) -> float:
        """1 / T (rad/s): where the servo's lag is 3 dB down."""
        return 1.0 / self.time_constant

    @property
    def effective_delay(self) -> float:
        """tau_a = L + T (s): the actuation delay for the analysis (module doc; the hold adds nothing)."""
        return self.dead_time + self.time_constant

    def fitted(self, times: _Array | None = None) -> _Array:
        """The FOPDT model at ``times`` (default: :attr:`times`)."""
        t = self.times if times is None else np.asarray(times, dtype=np.float64)
        return _fopdt(t, self.gain * self.step_speed, self.time_constant, self.dead_time)

    def describe(self) -> str:
        """One line for reports."""
        return (f"servo step {self.step_speed:g} m/s: gain {self.gain:.3f}, time constant {1e3 * self.time_constant:.1f} ms, "
                f"dead time {1e3 * self.dead_time:.1f} ms, bandwidth {self.bandwidth:.3g} rad/s; equivalent actuation "
                f"delay {1e3 * self.effective_delay:.1f} ms")  # fmt: skip

    def plot(self, ax: Any = None) -> Any:
        """The measured response and the fit; returns the axes.

        Parameters
        ----------
        ax
            Matplotlib axes, or None for a new figure.
        """
        import matplotlib.pyplot as plt

        if ax is None:
            _, ax = plt.subplots(figsize=(6, 3.5))
        ax.plot(self.times, self.speeds, label="physics model", lw=1.5)
        ax.plot(self.times, self.fitted(), "--", label=f"FOPDT: T = {1e3 * self.time_constant:.1f} ms, "
                f"L = {1e3 * self.dead_time:.1f} ms")  # fmt: skip
        ax.set_xlabel("t (s)")
        ax.set_ylabel("speed v (m/s)")
        ax.legend(loc="lower right")
        return ax


def _fopdt(t: _Array, final: float, T: float, L: float) -> _Array:
    return np.where(t > L, final * (1.0 - np.exp(-np.maximum(t - L, 0.0) / T)), 0.0)


@validated(SimulationInputError)
def identify_actuation(chassis: Chassis, limits: RobotLimits, *, step_speed: float | None = None) -> ServoIdentification:
    """Step one robot's wheel servos in the physics model and fit a first-order-plus-dead-time model.

    Parameters
    ----------
    chassis, limits
        The robot (a profile's ``chassis`` and ``limits``).
    step_speed
        The speed step (m/s); default: the largest the servos follow
        without reaching their torque limit (the linear response), at most
        half the speed cap.

    Returns
    -------
    ServoIdentification
        With :attr:`~ServoIdentification.effective_delay` for
        ``dominant_root(..., actuation_delay=)``.

    Raises
    ------
    SimulationInputError
        For a step beyond the speed cap.
    """
    from delayform.simulation.physics.engine import PhysicsTeam

    r = limits.wheel_radius
    linear = 0.9 * chassis.max_torque / chassis.servo_gain * r  # the first instant's torque within the limit
    if step_speed is None:
        step_speed = min(0.5 * limits.speed_cap, linear)
    elif not (isinstance(step_speed, (int, float)) and math.isfinite(step_speed) and 0 < step_speed <= limits.speed_cap):
        raise SimulationInputError(f"step_speed must be in (0, {limits.speed_cap:g}] m/s, got {step_speed!r}")
    tau = chassis.servo_time_constant(r)
    dt, _ = chassis.engine_grid()
    steps = max(50, math.ceil(10.0 * tau / dt))
    team = PhysicsTeam(chassis, limits, np.zeros((1, 2)), np.zeros(1), np.zeros(1))
    team.step(max(1, round(0.2 / dt)))  # settle on the floor first
    team.command(np.array([step_speed / r]), np.array([step_speed / r]))
    speeds = np.empty(steps + 1)
    speeds[0] = team.measure()[3][0]
    for k in range(1, steps + 1):
        team.step(1)
        speeds[k] = team.measure()[3][0]
    times = np.arange(steps + 1) * dt
    final = float(speeds[-max(1, steps // 10):].mean())
    guess_T = float(times[np.argmax(speeds >= 0.632 * final)]) or dt

    def residual(p: _Array) -> _Array:
        return _fopdt(times, p[0], p[1], p[2]) - speeds

    fit = least_squares(residual, x0=[final, guess_T, 0.0], bounds=([0.0, 1e-6, 0.0], [np.inf, 10 * times[-1], times[-1]]))
    K, T, L = (float(v) for v in fit.x)
    return ServoIdentification(
        times=times, speeds=speeds, step_speed=float(step_speed), gain=K / step_speed, time_constant=T,
        dead_time=L, control_period=chassis.control_period,
        rms_error=float(np.sqrt(np.mean(fit.fun**2))),
    )  # fmt: skip
